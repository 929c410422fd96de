"""`hearth scenario make --world W --seed N --out DIR`: a simulation scenario (robot/scenario.py).

Perturb a world's truth from a seed (moved objects, ajar doors, knobs on, clutter, occluders,
localisation error) and write belief.xml, truth.xml and scenario.json, with copies of the
meshes the world refers to.
"""
from __future__ import annotations

import math
import sys

from hearth.cli.util import DEFAULT_WORLD, add_command, output_dir, seed


def register(sub) -> None:
    p = add_command(sub, "scenario", __doc__,
                    help="make a simulation scenario (belief, truth, start pose)")
    s = p.add_subparsers(dest="scenario_command", required=True)
    m = s.add_parser("make", help="write a scenario directory")
    m.add_argument("--world", default=str(DEFAULT_WORLD), help="world file")
    m.add_argument("--seed", type=seed, default=0, help="random seed (0 to 2^32 - 1)")
    m.add_argument("--out", type=output_dir, required=True, metavar="DIR",
                   help="directory to write (made if missing; not a file)")
    m.set_defaults(func=_make)


def _make(args) -> int:
    from hearth.robot.scenario import make_scenario, save_scenario
    from hearth.worldmodel.io import load_world
    sc = make_scenario(load_world(args.world), args.seed)
    try:
        save_scenario(sc, args.out)
    except OSError as err:
        print(f"{args.out}: cannot write the scenario: {err.strerror or err}", file=sys.stderr)
        return 2
    e = sc.localisation_error
    print(f"scenario {args.seed} in {args.out}: {len(sc.perturbations)} changes to the truth, "
          f"localisation error {math.hypot(e.x, e.y) * 100:.1f} cm / {math.degrees(e.yaw):.1f} deg")
    for p in sc.perturbations:
        what = ", ".join(f"{k}={v}" for k, v in p.items() if k not in ("kind", "pose"))
        print(f"  {p['kind']}: {what}")
    for k in sc.stuck_knobs:
        print(f"  stuck knob: {k}")
    for d in sc.locked:
        print(f"  locked: {d}")
    for n in sc.notes:
        print(f"  note: {n}")
    return 0
