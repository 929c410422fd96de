"""`hearth demo`: the main job on the bundled demo home (what `make demo` runs)."""
from __future__ import annotations

from pathlib import Path

from worldmodel.describe import find_report, hierarchy_lines
from worldmodel.io import load_world

DEMO_WORLD = Path(__file__).resolve().parents[2] / "data" / "demo_home" / "world.xml"


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the demo on the bundled demo home",
                       description="Load the bundled demo home and show what Hearth knows of it.")
    p.add_argument("--world", default=str(DEMO_WORLD), help="world file (default: the demo home)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    world = load_world(args.world)
    print(f"Loaded {args.world}: {len(world.ids())} nodes in {len(world.rooms)} rooms\n")
    print("\n".join(hierarchy_lines(world)))
    report = find_report(world, "blue cup")
    if report["match"]:
        print(f"\nWhere is the blue cup? {report['match']['label']} is {report['location']} in the "
              f"{report['room']['name']}; parking positions: "
              + ", ".join(p["id"] for p in report["parking_positions"]))
    return 0
