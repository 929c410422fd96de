"""`hearth run MISSION [--param k=v]`: run a mission against a simulated or replayed robot."""
from __future__ import annotations

import sys

from executive.cliutil import (add_run_arguments, make_clock, make_world_and_robot, parse_params,
                               run_to_end)
from executive.executive import Executive
from executive.missionfile import load_mission


def register(sub) -> None:
    p = sub.add_parser("run", help="run a mission",
                       description="Run a mission on the robot adapter made by "
                                   "robot.create_adapter (simulated home, scenario or "
                                   "recording), printing the mission's progress. Exit 0 when "
                                   "it succeeds, 1 when it fails or is cancelled.")
    add_run_arguments(p)
    p.add_argument("--quiet", action="store_true", help="print only the outcome")
    p.set_defaults(func=_run)


def _run(args) -> int:
    mission = load_mission(args.mission)
    params = parse_params(mission, args.param)
    clock = make_clock(args)
    world, robot = make_world_and_robot(args, clock)
    ex = Executive(world=world, robot=robot, clock=clock, tick_hz=args.tick_hz,
                   runs_dir=args.runs_dir, background=False)
    result = run_to_end(ex, mission, params, quiet=args.quiet)
    print(f"{mission.name}: {result.outcome} ({result.reason}) in {result.ticks} ticks, "
          f"{result.duration:.2f} s; log {result.log_path}", file=sys.stderr if args.quiet else sys.stdout)
    return 0 if result.outcome == "succeeded" else 1
