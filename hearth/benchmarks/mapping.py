"""Mapping a home from a tour (docs/mapping.md), stage 1: the tour and the fused metric map.

Per world: `hearth tour` (the simulated robot, odometry drifting 1.5 % of distance and of
rotation by default), then `hearth map build`'s metric stages, scored against the truth the
recording carries and the true home:

- trajectory: ``ate_*_m`` (RMSE of keyframe camera centres against the truth, map frame =
  world frame, no alignment fitted) for the believed poses (odometry as recorded), after ICP
  odometry and after the pose graph; ``rot_err_posegraph_deg``; ``ate_in_parts_*_m``: the
  same with each part of the map that views link (a room: generated homes have no doorways,
  so nothing observes where one room sits against the next) aligned to the truth on its own;
- map: ``map_err_mm_median`` (median distance of the fused points to the true scene's
  surfaces), ``map_err_mm_p90``; ``completeness`` (share of points sampled every 5 cm on the
  true floor and the inner faces of the walls up to 2.2 m with a fused point within 5 cm:
  floor and walls behind furniture count as missing, so 1.0 is out of reach);
  ``floor_z_mm`` (median height of the fused floor);
- cost: ``build_s`` (the build's wall time; target 300 s a home on a 2-core machine),
  ``tour_s``, ``tour_frames``, ``tour_path_m``;
- the draft (the build's ``draft`` stage: the semantic draft of the TOUR's map, odometry and
  pose graph, no true pose) scored as ``hearth bench mapping_draft`` scores a true-pose
  draft (hearth/benchmarks/mapping_draft.py ``score_draft``): ``large_object_macro_f1``,
  ``appliance_f1``, ``hinge_side_accuracy``, ``centre_err_cm_median``, ... pooled over the
  worlds, with ``per_type``; each world's in ``per_world[...]["draft"]``;
- ``drift_2pct`` (first world only): the same tour with 2 % drift of distance and of rotation,
  its ATE before and after the pose graph.

Pooled figures are medians over worlds (``*_median``); ``per_world`` holds each world's. The
tour records at ``--width`` pixels (default 320: the build integrates at 320 x 240 anyway).
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from hearth.benchmarks import _worlds


def add_arguments(parser) -> None:
    _worlds.add_arguments(parser, homes=2)
    parser.add_argument("--width", type=int, default=320, help="tour image width (default 320)")
    parser.add_argument("--no-drift-check", action="store_true",
                        help="skip the 2 %% drift tour")
    parser.add_argument("--verbose", action="store_true", help="one line per world on stderr")


def true_surface_samples(world, step: float = 0.05, height: float = 2.2) -> np.ndarray:
    """Points every ``step`` m on each room's floor and the inner faces of its walls (up to
    ``height``), world frame."""
    out = []
    for room in world.rooms:
        if room.bounds is None:
            continue
        x0, y0, x1, y1 = room.bounds
        xs, ys = np.arange(x0, x1, step) + step / 2, np.arange(y0, y1, step) + step / 2
        zs = np.arange(0.0, height, step) + step / 2
        X, Y = np.meshgrid(xs, ys)
        pts = [np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]]
        for x in (x0, x1):
            Yw, Z = np.meshgrid(ys, zs)
            pts.append(np.c_[np.full(Yw.size, x), Yw.ravel(), Z.ravel()])
        for y in (y0, y1):
            Xw, Z = np.meshgrid(xs, zs)
            pts.append(np.c_[Xw.ravel(), np.full(Xw.size, y), Z.ravel()])
        P = np.vstack(pts)
        T = room.pose.matrix()
        out.append(P @ T[:3, :3].T + T[:3, 3])
    return np.vstack(out) if out else np.zeros((0, 3))


def map_accuracy(world, points: np.ndarray) -> dict:
    import open3d as o3d
    from scipy.spatial import cKDTree
    from hearth.worldmodel.geometry import merge, scene_meshes
    mesh = merge(scene_meshes(world))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    rng = np.random.default_rng(0)
    sample = points[rng.choice(len(points), min(len(points), 200_000), replace=False)]
    d = scene.compute_distance(o3d.core.Tensor(sample.astype(np.float32))).numpy()
    truth = true_surface_samples(world)
    near, _ = cKDTree(points).query(truth, distance_upper_bound=0.05)
    floor = points[np.abs(points[:, 2]) < 0.1, 2]
    return dict(map_err_mm_median=round(float(np.median(d)) * 1000, 1),
                map_err_mm_p90=round(float(np.percentile(d, 90)) * 1000, 1),
                completeness=round(float(np.mean(np.isfinite(near))), 3),
                floor_z_mm=round(float(np.median(floor)) * 1000, 1) if len(floor) else None)


def tour_and_build(world, work: Path, width: int, seed: int, drift) -> dict:
    import open3d as o3d
    from hearth.mapping.build import build
    from hearth.robot.tour import TourOptions, record_tour
    from hearth.perception.camera import Intrinsics
    t0 = time.perf_counter()
    summary = record_tour(world, work / "rec", TourOptions(), drift, seed=seed,
                          intrinsics=Intrinsics.kinect(width, width * 3 // 4))
    tour_s = time.perf_counter() - t0
    result = build(work / "rec", work / "map")
    st = result.stages
    out = dict(tour_s=round(tour_s, 1), tour_frames=summary.frames,
               tour_path_m=round(summary.path_m, 1), build_s=round(result.seconds, 1),
               failed=result.failed,
               stage_s={k: v.get("seconds") for k, v in st.items()},
               keyframes=st.get("odometry", {}).get("keyframes"),
               loop_closures_kept=st.get("posegraph", {}).get("loop_closures_kept"))
    for key in ("ate_believed_m", "ate_odometry_m", "rot_err_believed_deg"):
        out[key] = st.get("odometry", {}).get(key)
    for key in ("ate_posegraph_m", "rot_err_posegraph_deg", "ate_in_parts_odometry_m",
                "ate_in_parts_posegraph_m", "parts"):
        out[key] = st.get("posegraph", {}).get(key)
    ply = work / "map/fused/map.ply"
    if ply.is_file():
        out |= map_accuracy(world, np.asarray(o3d.io.read_point_cloud(str(ply)).points))
    drafted = work / "map/draft/world.xml"
    if drafted.is_file():
        from hearth.benchmarks.mapping_draft import score_draft
        from hearth.worldmodel.io import load_world
        out["draft_scores"] = score_draft(load_world(drafted), world)
        out["draft_s"] = st.get("draft", {}).get("seconds")
    return out


def _median(rows, key):
    xs = [r[key] for r in rows if r.get(key) is not None]
    return round(statistics.median(xs), 4) if xs else None


def _world(spec: str):
    """A generated home made in memory by this checkout's generator (the shared file cache of
    generated homes can hold a file another version of the generator wrote), else the file."""
    if _worlds.is_generated(spec):
        from hearth.worldmodel.homegen import generate_home
        return generate_home(int(spec.split(":", 1)[1]))
    return _worlds.load(spec)


def run(args) -> dict:
    import sys
    from hearth.benchmarks.mapping_draft import summarise
    from hearth.mapping.classify import classifier
    from hearth.robot.tour import OdometryDrift
    specs = _worlds.world_specs(args, homes=2)
    classifier(retrain=True)          # the draft stage's; trained once when missing or stale
    per_world, drift_check = {}, None
    for i, spec in enumerate(specs):
        world = _world(spec)
        with tempfile.TemporaryDirectory(prefix="hearth-mapping-") as tmp:
            r = tour_and_build(world, Path(tmp), args.width, args.seed + i, OdometryDrift())
        per_world[spec] = r
        if getattr(args, "verbose", False):
            print(f"mapping: {spec}: {r['tour_frames']} frames, build {r['build_s']} s, ATE "
                  f"{r['ate_believed_m']} -> {r['ate_odometry_m']} -> {r['ate_posegraph_m']} m, "
                  f"map err {r.get('map_err_mm_median')} mm", file=sys.stderr, flush=True)
        if i == 0 and not args.no_drift_check:
            with tempfile.TemporaryDirectory(prefix="hearth-mapping-") as tmp:
                d = tour_and_build(world, Path(tmp), args.width, args.seed + 1000,
                                   OdometryDrift(distance=0.02, rotation=0.02))
            drift_check = dict(world=spec, drift_distance=0.02, drift_rotation=0.02) | {
                k: d.get(k) for k in ("ate_believed_m", "ate_odometry_m", "ate_posegraph_m",
                                      "ate_in_parts_odometry_m", "ate_in_parts_posegraph_m",
                                      "rot_err_posegraph_deg", "map_err_mm_median",
                                      "loop_closures_kept")}
    rows = list(per_world.values())
    drafts = []
    for r in rows:
        if "draft_scores" in r:
            drafts.append(r.pop("draft_scores"))
            r["draft"] = {k: v for k, v in summarise(drafts[-1:]).items() if k != "per_type"}
    out = {k if k.endswith("_median") else f"{k}_median": _median(rows, k) for k in (
        "ate_believed_m", "ate_odometry_m", "ate_posegraph_m", "rot_err_posegraph_deg",
        "ate_in_parts_odometry_m", "ate_in_parts_posegraph_m",
        "map_err_mm_median", "completeness", "floor_z_mm", "tour_frames", "tour_s",
        "tour_path_m")}
    out["build_s_median"] = _median(rows, "build_s")
    if drafts:      # the draft of the tour's map against the true home, pooled over worlds
        out |= {"draft_poses": "tour"} | summarise(drafts)
        out["draft_s_median"] = _median(rows, "draft_s")
    out["targets"] = {"build_s_median": 300}
    out["worlds"] = specs
    out["per_world"] = per_world
    out["drift_2pct"] = drift_check
    try:
        import os
        out["load_average_1min"] = round(os.getloadavg()[0], 2)
    except OSError:  # pragma: no cover
        pass
    return out
