"""`hearth show MISSION [--format ascii|dot]`: draw a mission's tree."""
from __future__ import annotations


def register(sub) -> None:
    from hearth.cli.util import mission_file

    p = sub.add_parser("show", help="draw a mission's behaviour tree",
                       description="Load and check a mission, then draw its tree: ASCII "
                                   "(default) or Graphviz dot.")
    p.add_argument("mission", type=mission_file,
                   help="mission file, or the name of a shipped mission (go_to_rest)")
    p.add_argument("--format", choices=("ascii", "dot"), default="ascii")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.executive.missionfile import load_mission
    from hearth.executive.render import ascii_tree, dot_tree

    mission = load_mission(args.mission)
    if args.format == "dot":
        print(dot_tree(mission.root, mission.name))
    else:
        print(f"{mission.name}: {mission.description}".rstrip(": "))
        for p in mission.parameters.values():
            flags = " runtime" if p.runtime else ""
            default = f" = {p.default!r}" if p.default is not None else " (required)"
            print(f"  ${p.name}: {p.type}{flags}{default}")
        print(ascii_tree(mission.root))
    return 0
