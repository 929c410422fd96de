"""The semantic-draft stages of `hearth map build` (issue 47): from a fused map on disk to a
draft world file, its picture and the list of what could not be labelled.

``draft_from_fused(map_dir, out_dir)`` reads ``MAP_DIR/fused/map.ply`` (an open3d coloured
point cloud with normals in the map frame: z up, floor at z = 0, metres), runs the draft
(hearth/perception/semantic_map.py, the classifier from the model store), writes the world
(hearth/worldmodel/draft.py) as ``OUT_DIR/world.xml`` (validated before it is written),
``OUT_DIR/draft.png`` (the draft over the fused map) and ``OUT_DIR/unlabelled.txt``. A
draft that fails part way (no classifier, an object it cannot type) still writes what it
found: rooms and untyped boxes are kept, and the list says what is missing.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Optional

from hearth.util.errors import HearthError


class DraftError(HearthError):
    """A fused map the draft cannot read (one line naming the file)."""


def read_fused(map_dir) -> tuple:
    """(points, normals, colours) of ``map_dir/fused/map.ply`` (or a .ply path itself)."""
    import numpy as np
    import open3d as o3d
    p = Path(map_dir)
    path = p if p.suffix == ".ply" else p / "fused" / "map.ply"
    if not path.is_file():
        raise DraftError(f"{path}: no fused map (run the metric-map stages of `hearth map "
                         "build` first)")
    pcd = o3d.io.read_point_cloud(str(path))
    if len(pcd.points) == 0:
        raise DraftError(f"{path}: not a point cloud, or an empty one")
    if not pcd.has_normals():
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=0.04, max_nn=30))
        pcd.orient_normals_towards_camera_location(np.asarray(pcd.points).mean(0) + (0, 0, 1.3))
    colors = np.asarray(pcd.colors) if pcd.has_colors() else np.full((len(pcd.points), 3), 0.5)
    return np.asarray(pcd.points), np.asarray(pcd.normals), colors


def draft_from_fused(map_dir, out_dir, classifier=None,
                     progress: Optional[Callable[[str], None]] = None) -> dict:
    """Run the draft on ``map_dir``'s fused map and write it to ``out_dir`` (see the module
    docstring); a summary dict (paths, counts, seconds, unlabelled lines)."""
    from hearth.perception.errors import PerceptionError
    from hearth.mapping.classify import classifier as get, label
    from hearth.perception.semantic_map import articulate, draft_geometry
    from hearth.worldmodel.draft import draft_world, draw_draft
    from hearth.worldmodel.io import atomic_write, checked_xml
    from hearth.worldmodel.topdown import save_png
    from hearth.worldmodel.world import World
    say = progress or (lambda m: None)
    t0 = time.perf_counter()
    P, N, C = read_fused(map_dir)
    say(f"read the fused map: {len(P)} points")
    d = draft_geometry(P, N)
    say(f"rooms: {len(d.rooms)}; large objects: {len(d.objects)}; "
        f"fixtures: {sum(len(o.fixtures) for o in d.objects)}")
    failed = []
    if classifier is None:
        try:
            classifier = get(retrain=False)
        except PerceptionError as err:
            failed.append(f"no object types: {err}")
    if classifier is not None:
        label(d, P, N, C, classifier)
        say("labelled: " + ", ".join(sorted(o.type for o in d.objects)))
    else:
        for o in d.objects:
            o.type, o.confidence = "cupboard" if o.fixtures else "table", 0.0
            o.parts = articulate(o)
            d.unlabelled.append((o, "type unknown (no classifier): drafted as " + o.type))
    result = draft_world(d, home_id="draft_home")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    world_path = out / "world.xml"
    data = checked_xml(result.apartment, str(world_path), out.resolve())
    atomic_write(world_path, data)
    unlabelled = failed + result.unlabelled
    atomic_write(out / "unlabelled.txt", "".join(f"{u}\n" for u in unlabelled).encode())
    img = draw_draft(World(result.apartment), P, C)
    png = save_png(out / "draft.png", img)
    seconds = time.perf_counter() - t0
    say(f"wrote {world_path}, {png}; {len(unlabelled)} things to check in "
        f"{out / 'unlabelled.txt'} ({seconds:.1f} s)")
    return dict(world=str(world_path), picture=str(png), unlabelled=unlabelled,
                rooms=len(result.apartment.rooms),
                objects=sum(len(r.objects) for r in result.apartment.rooms), seconds=seconds)


# -- the hook of `hearth map build` (hearth/mapping/build.py, the metric-map stages) -------------

def _stage_run(ctx) -> dict:
    """The ``draft`` stage: ``ctx.out/fused/map.ply`` -> ``ctx.out/draft/``."""
    from hearth.perception.errors import PerceptionError
    try:
        done = draft_from_fused(ctx.out, ctx.out / "draft", progress=ctx.progress)
    except DraftError as err:
        raise PerceptionError(str(err)) from None
    for line in done["unlabelled"]:
        ctx.warnings.append(f"draft: {line}")
    return {k: done[k] for k in ("world", "picture", "rooms", "objects", "seconds")} | \
        {"unlabelled": len(done["unlabelled"])}


def register_build_stage() -> bool:
    """Register the ``draft`` stage after the metric map's last stage (``picture``) in
    ``hearth map build``; False where that command is not there. Adding this module to
    ``hearth.mapping.build.STAGE_MODULES`` joins the two."""
    try:
        from hearth.mapping.build import STAGES, Stage, register_stage
        # the metric stages first, whichever module is imported first (a draft stage
        # registered before them would run before the map it drafts from exists)
        import hearth.mapping.metric  # noqa: F401
    except ImportError:
        return False
    after = "picture" if any(s.name == "picture" for s in STAGES) else None
    register_stage(Stage("draft", _stage_run, "the semantic draft: rooms, large objects, parts, "
                                              "parking -> draft/world.xml, draft/draft.png",
                         needs=("fuse",)), after=after)
    return True


register_build_stage()
