"""`hearth home make|describe|import-model`: generated homes (hearth/worldmodel/homegen.py), what is
in a home, and a kitchen made around a public articulated model (MJCF, hearth/worldmodel/mjcf.py;
docs/renderers-and-assets.md).

Generate valid homes that differ the way real homes do (turned rooms, furniture and knob
designs, off states with other names, objects on low shelves and in closed cupboards); see
docs/world-format.md, 'Generated homes'.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from hearth.cli.util import add_command


def register(sub) -> None:
    p = add_command(sub, "home", __doc__, help="generate homes, or describe what a home holds")
    hs = p.add_subparsers(dest="home_command", metavar="ACTION", required=True)
    m = hs.add_parser("make", help="write generated homes",
                      description="Write the home of each seed: DIR/world.xml (and "
                                  "DIR/meshes/) for one seed, DIR/home-SEED/world.xml for "
                                  "--count K seeds N..N+K-1. One line per home.")
    m.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    m.add_argument("--count", type=int, default=None, metavar="K",
                   help="make K homes, seeds N..N+K-1, in DIR/home-SEED/")
    m.add_argument("--out", required=True, metavar="DIR", help="directory to write")
    m.add_argument("--rooms", default=None, metavar="MIN-MAX",
                   help="number of rooms (default 2-5)")
    m.set_defaults(func=_make)
    d = hs.add_parser("describe", help="list a home's rooms, appliances, containers and small "
                                       "objects (ids to pass to missions)")
    d.add_argument("world", metavar="WORLD")
    d.set_defaults(func=_describe)
    i = hs.add_parser("import-model", help="write a kitchen world around an MJCF appliance "
                                           "(knobs, doors, drawers, handles from its joints)",
                      description="Read an MJCF model with MuJoCo (the mujoco extra) and write "
                                  "DIR/world.xml and DIR/meshes/: a kitchen holding the model "
                                  "as an articulated appliance (docs/renderers-and-assets.md).")
    i.add_argument("model", metavar="FILE.xml", help="the MJCF file")
    i.add_argument("--out", required=True, metavar="DIR", help="directory to write")
    i.add_argument("--body", default="", metavar="NAME",
                   help="import only this body's subtree (an appliance out of a larger scene)")
    i.add_argument("--id", default="", help="the appliance's id (default: from the file name)")
    i.add_argument("--type", default="", help="its type (default: from the name: oven, stove, ...)")
    i.add_argument("--front", default="auto", choices=("auto", "+x", "-x", "+y", "-y"),
                   help="the model's axis that faces the room (default: from its knobs)")
    i.set_defaults(func=_import_model)


def _make(args) -> int:
    from hearth.worldmodel.homegen import HomeConfig, HomeGenError, make_home, summary
    from hearth.worldmodel.io import load_world
    if args.seed < 0:
        print(f"hearth home make: --seed must be >= 0, not {args.seed}", file=sys.stderr)
        return 2
    if args.count is not None and not 1 <= args.count <= 10_000:
        print(f"hearth home make: --count must be 1..10000, not {args.count}", file=sys.stderr)
        return 2
    config = HomeConfig()
    if args.rooms:
        lo, sep, hi = args.rooms.partition("-")
        try:
            config = HomeConfig(rooms=(int(lo), int(hi or lo)))
        except ValueError:
            print(f"hearth home make: --rooms must be N or MIN-MAX, not {args.rooms!r}",
                  file=sys.stderr)
            return 2
    out = Path(args.out)
    seeds = [args.seed] if args.count is None else range(args.seed, args.seed + args.count)
    for seed in seeds:
        target = out if args.count is None else out / f"home-{seed}"
        try:
            path = make_home(seed, target, config)
        except HomeGenError as err:
            print(str(err), file=sys.stderr)
            return 2
        except OSError as err:
            print(f"{target}: cannot write the home: {err.strerror or err}", file=sys.stderr)
            return 2
        print(f"{path}: {_line(summary(load_world(path)))}")
    return 0


def _line(s: dict) -> str:
    rooms = ", ".join(s["rooms"])
    turned = f"; turned: {', '.join(s['turned'])}" if s["turned"] else ""
    return (f"{len(s['rooms'])} rooms ({rooms}{turned}), {s['large']} large objects, "
            f"{s['small']} small objects, {s['knobs']} knobs")


def _import_model(args) -> int:
    from hearth.worldmodel.mjcf import import_model
    from hearth.worldmodel.io import load_world
    from hearth.worldmodel.homegen import summary
    try:
        path = import_model(args.model, args.out, object_id=args.id, object_type=args.type,
                            front=args.front, body=args.body)
    except OSError as err:
        print(f"{args.out}: cannot write the world: {err.strerror or err}", file=sys.stderr)
        return 2
    world = load_world(path)
    print(f"{path}: {_line(summary(world))}")
    for k in world.knobs():
        print(f"  knob {k.id}: off is {k.off!r}; states " + ", ".join(s.name for s in k.states))
    return 0


def _describe(args) -> int:
    from hearth.worldmodel.homegen import summary
    from hearth.worldmodel.io import load_world
    from hearth.worldmodel.nodes import LargeArticulatedObject
    world = load_world(args.world)
    ap = world.apartment
    print(f"{ap.id} ({ap.name or 'no name'}): {_line(summary(world))}")
    for room in world.rooms:
        p = room.pose
        print(f"{room.name} ({room.id}): at x={p.x:.2f} y={p.y:.2f} turned "
              f"{math.degrees(p.yaw):.0f} deg, bounds {room.bounds}")
        for o in room.objects:
            print(f"  {o.id} ({o.name or o.type}): {o.description or o.type}")
            if isinstance(o, LargeArticulatedObject) and o.parts:
                print("    parts: " + ", ".join(f"{q.id} ({q.type})" for q in o.parts))
            for k in world.knobs(o.id):
                names = ", ".join(s.name for s in k.states)
                print(f"    knob {k.id}: {k.state} now, off is {k.off!r}; states {names}")
            for c in o.children:
                print(f"    holds {world.label(c.id)} ({c.id}) {c.relation} it")
    return 0
