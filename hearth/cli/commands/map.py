"""`hearth map show|find|draw|draft|rename`: look at a world file; `hearth map build`: a map
from a tour; draft a world from a fused map."""
from __future__ import annotations

import json
import sys


def register(sub) -> None:
    p = sub.add_parser("map", help="show a world file's hierarchy or find nodes by words; "
                                   "build a map from a tour and draft a world from it",
                       description="Inspect the hierarchical semantic map of a world file, "
                                   "build a map from a tour recording, or draft a world from a "
                                   "fused map (docs/mapping.md).")
    msub = p.add_subparsers(dest="map_command", metavar="ACTION", required=True)
    show = msub.add_parser("show", help="print the hierarchy with states")
    show.add_argument("world", metavar="WORLD")
    show.add_argument("--node", help="print only this node and what it holds")
    show.set_defaults(func=_show)
    find = msub.add_parser("find", help="find a node by words, e.g. 'blue cup'")
    find.add_argument("world", metavar="WORLD")
    find.add_argument("words", nargs="+", metavar="WORD")
    find.add_argument("--json", action="store_true", help="print JSON")
    find.set_defaults(func=_find)
    draw = msub.add_parser("draw", help="draw the map top-down to a PNG",
                           description="Draw any world top-down (rooms where their poses put "
                                       "them, large objects, parking positions, small objects).")
    draw.add_argument("world", metavar="WORLD")
    draw.add_argument("-o", "--out", required=True, metavar="PNG", help="the PNG file to write")
    draw.add_argument("--px-per-m", type=int, default=90, help="pixels per metre (default 90)")
    draw.set_defaults(func=_draw)
    build = msub.add_parser(
        "build", help="build a map from a tour recording (docs/mapping.md)",
        description="Build a map from a tour recording (a Hearth recording or a ROS 2 bag, "
                    "e.g. from `hearth tour`) in named stages, each writing under DIR so one "
                    "can be rerun alone (--stages): odometry (keyframes, ICP on the odometry), "
                    "posegraph (loop closures, global optimisation), fuse (TSDF: "
                    "fused/map.ply, fused/mesh.ply), picture (map.png), draft (the semantic "
                    "draft: draft/world.xml, draft.png; docs/mapping.md); DIR/build.json holds "
                    "each stage's timing, counts and warnings. Exit 0 when every stage "
                    "succeeded, 1 when one failed (the others still wrote what they found), "
                    "2 for a recording a map cannot be built from.")
    build.add_argument("recording", metavar="REC", help="tour recording directory or bag")
    build.add_argument("--out", required=True, metavar="DIR", help="build directory")
    build.add_argument("--stages", default=None, metavar="NAME,...",
                       help="run only these stages (their inputs from DIR)")
    build.add_argument("--topics", default=None, metavar="MAP",
                       help="a bag's topic and frame mapping (docs/ros2-foxglove.md)")
    build.add_argument("--quiet", action="store_true", help="print only the outcome")
    build.set_defaults(func=_build)
    dr = msub.add_parser(
        "draft", help="draft a world from a fused map (DIR/fused/map.ply)",
        description="The semantic-draft stages of `hearth map build` (docs/mapping.md, "
                    "'Semantic draft'): rooms, large objects by type, doors, drawers, handles, "
                    "knobs and parking positions from DIR/fused/map.ply; writes OUT/world.xml "
                    "(validated), OUT/draft.png (the draft over the map) and OUT/unlabelled.txt "
                    "(what it could not label). Ids are drafts: rename them with `hearth map "
                    "rename`.")
    dr.add_argument("map_dir", metavar="DIR", help="a map directory (DIR/fused/map.ply) or a .ply")
    dr.add_argument("--out", required=True, metavar="OUT", help="directory to write")
    dr.set_defaults(func=_draft)
    rn = msub.add_parser("rename", help="rename a node and every reference to it",
                         description="Rename node OLD to NEW in WORLD (in place, atomically, "
                                     "checked before it is written): its id, every reference to "
                                     "it, and the ids that start with OLD_ (a draft's parts, "
                                     "handles, knobs, parking positions).")
    rn.add_argument("world", metavar="WORLD")
    rn.add_argument("old", metavar="OLD")
    rn.add_argument("new", metavar="NEW")
    rn.set_defaults(func=_rename)


def _show(args) -> int:
    from hearth.worldmodel.describe import hierarchy_lines
    from hearth.worldmodel.io import load_world

    world = load_world(args.world)
    print("\n".join(hierarchy_lines(world, args.node)))
    return 0


def _find(args) -> int:
    from hearth.worldmodel.describe import find_report
    from hearth.worldmodel.io import load_world

    world = load_world(args.world)
    report = find_report(world, " ".join(args.words))
    if args.json:
        print(json.dumps(report, indent=2))
        return 0 if report["match"] else 1
    if report.get("ambiguous"):
        which = " or ".join(f"the {a['label']} ({a['id']}) {a['location']}" for a in report["ambiguous"])
        print(f"which {report['query']} do you mean: {which}?")
        return 1
    if not report["match"]:
        print(f"nothing in the map matches {report['query']!r}")
        return 1
    m = report["match"]
    print(f"{m['label']} ({m['id']}) is {report['location']} in the {report['room']['name']}")
    print(f"  chain: {' -> '.join(report['chain'])}")
    for p in report["parking_positions"]:
        print(f"  parking {p['id']}: x={p['x']:.2f} y={p['y']:.2f} yaw={p['yaw']:.2f}")
    if report["candidates"]:
        print("  also matching: " + ", ".join(c["id"] for c in report["candidates"]))
    return 0


def _draw(args) -> int:
    from hearth.worldmodel.io import load_world
    from hearth.worldmodel.topdown import Overlay, draw, save_png
    world = load_world(args.world)
    if not 10 <= args.px_per_m <= 1000:
        print(f"hearth map draw: --px-per-m must be 10..1000, not {args.px_per_m}", file=sys.stderr)
        return 2
    img = draw(world, Overlay(title=world.apartment.name or world.apartment.id),
               px_per_m=args.px_per_m)
    try:
        out = save_png(args.out, img)
    except OSError as err:
        print(f"{args.out}: {err}", file=sys.stderr)
        return 2
    print(f"wrote {out} ({img.shape[1]}x{img.shape[0]} px)")
    return 0


def _build(args) -> int:
    from hearth.mapping.build import build
    only = [x.strip() for x in args.stages.split(",") if x.strip()] if args.stages else None
    progress = (lambda text: None) if args.quiet else (lambda text: print(text, flush=True))
    topics = None
    if args.topics:
        from hearth.robot.rosbag import load_topic_map
        topics = load_topic_map(args.topics)
    result = build(args.recording, args.out, only=only, topics=topics, progress=progress)
    state = (f"failed in {', '.join(result.failed)} (the other stages wrote what they found)"
             if result.failed else "built")
    print(f"{args.out}: {state} in {result.seconds:.1f} s; {len(result.warnings)} warning"
          f"{'' if len(result.warnings) == 1 else 's'}; see {args.out}/build.json")
    return 1 if result.failed else 0
def _draft(args) -> int:
    from hearth.mapping.draft import draft_from_fused
    draft_from_fused(args.map_dir, args.out, progress=lambda m: print(m, flush=True))
    return 0


def _rename(args) -> int:
    from pathlib import Path
    from hearth.worldmodel.draft import rename
    from hearth.worldmodel.io import atomic_write, parse_world
    from hearth.util.files import read_limited
    from hearth.worldmodel.io import _TOO_LARGE, MAX_FILE_BYTES
    from hearth.worldmodel.errors import WorldError
    path = Path(args.world)
    data = read_limited(path, MAX_FILE_BYTES, WorldError, _TOO_LARGE)
    parse_world(data, str(path), base_dir=path.parent.resolve())     # a bad file: one line
    new, changed = rename(data, args.old, args.new, str(path))
    parse_world(new, str(path), base_dir=path.parent.resolve())
    atomic_write(path, new)
    print(f"{path}: {args.old} -> {args.new} ({changed} ids and references)")
    return 0
