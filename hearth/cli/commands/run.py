"""`hearth run MISSION [--param k=v]`: run a mission against a simulated or replayed robot.

Run a mission on the robot adapter made by robot.create_adapter (simulated home, scenario or
recording), printing the mission's progress. The belief map is kept on disk: what the mission
learns is saved after every change (--map-out, --no-save). Exit 0 when it succeeds, 1 when it
fails or is cancelled, 2 for bad input (a parameter the map refutes included).
"""
from __future__ import annotations

import sys
import time

from hearth.cli.util import (add_command, add_run_arguments, add_topics_argument, close_map,
                               close_robot, link_lost, make_executive, outcome_line,
                               run_to_end)


def register(sub) -> None:
    p = add_command(sub, "run", __doc__, help="run a mission")
    add_run_arguments(p)
    add_topics_argument(p)
    out = p.add_mutually_exclusive_group()
    out.add_argument("--quiet", action="store_true",
                     help="print only the outcome line (on stdout)")
    out.add_argument("--verbose", action="store_true",
                     help="print every event (status changes, feedback, blackboard writes, map "
                          "changes) in the order it happened within its tick; by default: the "
                          "mission's events and each skill's outcome")
    add_groot2_arguments(p)
    p.add_argument("--groot2-linger", type=float, default=0.0, metavar="SECONDS",
                   help="with --groot2: keep publishing the ended mission this long (a "
                        "simulated run may end before a viewer attaches)")
    from hearth.cli.util import add_foxglove_arguments
    add_foxglove_arguments(p)
    p.set_defaults(func=_run)


def add_groot2_arguments(p) -> None:
    p.add_argument("--groot2", nargs="?", type=int, const=1667, default=None, metavar="PORT",
                   help="publish the running tree and its statuses over the Groot2 protocol "
                        "(Groot2, btview) on PORT and PORT+1 (default 1667)")
    p.add_argument("--groot2-host", default="127.0.0.1", metavar="HOST",
                   help="address the Groot2 publisher binds (default 127.0.0.1; the protocol "
                        "has no authentication)")


def start_groot2(args, executive, mission=None):
    """The Groot2 publisher asked for by --groot2 (None when not asked), showing
    ``mission``'s tree until its run starts."""
    if args.groot2 is None:
        return None
    from hearth.executive.groot2 import Groot2Publisher
    pub = Groot2Publisher(executive, port=args.groot2, host=args.groot2_host)
    if mission is not None:
        pub.show(mission)
    print(f"groot2: publishing on tcp://{args.groot2_host}:{pub.port} (and {pub.port + 1})",
          file=sys.stderr, flush=True)
    return pub


def _run(args) -> int:
    from hearth.executive.foxglove import sink_from_args
    mission, params, ex, keeper = make_executive(args)
    sink = sink_from_args(args, world=ex.world, clock=ex.clock)
    simulated = bool(getattr(ex.clock, "simulated", False))
    if sink is not None:
        sink.attach(ex)
        if simulated:                      # a simulated run is over in seconds: wait for a viewer
            sink.wait_for_viewer(args.foxglove_wait)
    pub = start_groot2(args, ex, mission)
    try:
        result = run_to_end(ex, mission, params, quiet=args.quiet, verbose=args.verbose)
        if pub is not None and args.groot2_linger > 0:
            time.sleep(args.groot2_linger)
    finally:
        if pub is not None:
            pub.close()
        if sink is not None:
            sink.wait_for_viewers_to_leave(args.foxglove_wait)
            sink.close()
        close_robot(ex.robot)
        close_map(keeper, quiet=args.quiet)
    print(outcome_line(mission, result), flush=True)
    lost = link_lost(ex.robot)
    if lost and result.outcome != "succeeded":     # not the mission's failure: the robot's
        print(lost, file=sys.stderr, flush=True)
        return 2
    return 0 if result.outcome == "succeeded" else 1
