"""`hearth run MISSION [--param k=v]`: run a mission against a simulated or replayed robot."""
from __future__ import annotations

import sys

from executive.cliutil import add_run_arguments, make_executive, run_to_end


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
    mission, params, ex = make_executive(args)
    result = run_to_end(ex, mission, params, quiet=args.quiet)
    print(f"{mission.name}: {result.outcome} ({result.reason}) in {result.ticks} ticks, "
          f"{result.duration:.2f} s; log {result.log_path}", file=sys.stderr if args.quiet else sys.stdout)
    return 0 if result.outcome == "succeeded" else 1
