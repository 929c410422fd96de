"""`hearth learn --object NAME [--on SURFACE] [--world W] [--scenario S]`: learn a new object.

Run the learn_object mission (missions/learn_object.yaml): the robot finds the object its
map does not know on the surface it looks at (or on SURFACE), drives round it taking views,
builds a coloured model and mesh from them and adds the object to the map under NAME (the
mesh files go to learned/ beside the world file; the map is saved as `hearth run` saves it).
From then on "bring me my NAME" works. In simulation the object must be in the truth and not
in the map: give a scenario (`hearth scenario`) or a recording whose truth holds it. Progress
is printed as the robot goes round. Exit 0 when the object was learned, 1 when it could not
be (nothing there, too few views, too small), 2 for bad input (a name already taken).
"""
from __future__ import annotations

from hearth.cli.util import DEFAULT_WORLD, add_command


def register(sub) -> None:
    p = add_command(sub, "learn", __doc__, help="learn a new object from views around it")
    p.add_argument("--object", required=True, metavar="NAME",
                   help="what to call it (\"pill organiser\")")
    p.add_argument("--on", default="", metavar="SURFACE",
                   help="the furniture it stands on (default: the one the robot looks at)")
    p.add_argument("--words", default="", help="more words for it: colour, material")
    p.add_argument("--kind", default="", help="what kind of thing it is")
    p.add_argument("--views", default="6", help="views to take around it (2-12; default 6)")
    p.add_argument("--world", default=str(DEFAULT_WORLD), help="world file: the belief map")
    p.add_argument("--scenario", default=None, metavar="DIR", help="simulation scenario")
    p.add_argument("--recording", default=None, metavar="PATH", help="recording to replay")
    p.add_argument("--map-out", default=None, metavar="PATH",
                   help="keep the learned map in PATH instead of the world file")
    p.add_argument("--quiet", action="store_true", help="print only the outcome line")
    p.set_defaults(func=_run)


def _run(args) -> int:
    import os
    import sys

    from hearth.cli.main import main
    from hearth.util.errors import HearthError
    from hearth.worldmodel import load_world
    from hearth.worldmodel.learned import check_name
    kept = args.map_out if args.map_out and os.path.exists(args.map_out) else args.world
    try:      # a name already taken is bad input: said before the robot moves
        check_name(load_world(kept), args.object)
    except HearthError as err:
        print(f"hearth learn: {err}", file=sys.stderr)
        return 2
    argv = ["run", "learn_object", "--world", args.world,
            "--param", f"name={args.object}", "--param", f"views={args.views}"]
    for key, value in (("surface", args.on), ("words", args.words), ("kind", args.kind)):
        if value:
            argv += ["--param", f"{key}={value}"]
    for flag, value in (("--scenario", args.scenario), ("--recording", args.recording),
                        ("--map-out", args.map_out)):
        if value:
            argv += [flag, value]
    if args.quiet:
        argv.append("--quiet")
    return main(argv)
