"""The metric map's stages of `hearth map build` (docs/mapping.md), each over the pure
functions of hearth/perception/mapping.py, each writing under the build directory:

- ``odometry``: keyframes of the tour (by the believed motion), each keyframe's cloud of
  upright surfaces, and ICP between consecutive keyframes with the robot's odometry as the
  prior -> ``odometry/keyframes.json`` (capture indices, believed and registered base poses,
  the camera on the base, the edges with their information) and ``odometry/clouds.npz``.
- ``posegraph``: loop closures where the tour comes back to a place (near cameras looking the
  same way, registered from the current estimate) and Open3D's global optimisation ->
  ``posegraph/pose_graph.json`` (Open3D's format), ``posegraph/poses.json`` (optimised base and
  camera poses per keyframe), ``posegraph/summary.json``.
- ``fuse``: Open3D's scalable TSDF volume over every keyframe at the optimised poses ->
  ``fused/map.ply`` (coloured points with normals) and ``fused/mesh.ply``.
- ``picture``: the fused map from above with the trajectory -> ``map.png``.

The map frame is the recording's world frame (z up, floor at z = 0, metres): the robot's
start pose is known in it, so keyframe poses compare with the truth without an alignment.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hearth.mapping import MappingError
from hearth.mapping.build import BuildContext, Stage, StageFailed, register_stage
from hearth.perception import mapping as pm


@dataclass(frozen=True)
class MetricConfig:
    """One configuration for the metric stages (``ctx.config["metric"]``)."""
    keyframes: pm.KeyframeOptions = pm.KeyframeOptions()
    cloud: pm.CloudOptions = pm.CloudOptions()
    registration: pm.RegistrationOptions = pm.RegistrationOptions()
    prior: pm.MotionPrior = pm.MotionPrior()
    posegraph: pm.PoseGraphOptions = pm.PoseGraphOptions()
    fusion: pm.FusionOptions = pm.FusionOptions()
    px_per_m: int = 40


def config(ctx: BuildContext) -> MetricConfig:
    return ctx.config.get("metric") or MetricConfig()


def _stack(x) -> np.ndarray:
    return np.asarray(x, dtype=float).reshape(-1, 4, 4)


def _truth_figures(ctx: BuildContext, keyframes, T_world_camera, key: str) -> dict:
    from hearth.mapping.inputs import true_cameras
    T_true = true_cameras(ctx.recording)
    if T_true is None:
        return {}
    return {f"ate_{key}_m": round(pm.ate_rmse(T_world_camera, T_true[keyframes]), 4),
            f"rot_err_{key}_deg": round(pm.yaw_rmse_deg(T_world_camera, T_true[keyframes]), 3)}


# -- odometry ------------------------------------------------------------------------------------

def run_odometry(ctx: BuildContext) -> dict:
    from hearth.mapping.inputs import BlindFrame, base_camera, read_frame
    cfg = config(ctx)
    rec = ctx.recording
    B, C = base_camera(rec)
    kf = pm.select_keyframes(B @ C, cfg.keyframes)
    clouds, kept, blind = [], [], []
    for n, i in enumerate(kf):
        try:
            f = read_frame(rec, i)
        except BlindFrame as err:       # nothing to register or fuse: the next one is used
            ctx.warn(f"{err}; skipped")
            blind.append(i)
            continue
        kept.append(i)
        clouds.append(pm.keyframe_cloud(f.depth, rec.intrinsics, C[i], cfg.cloud))
        if (n + 1) % 100 == 0:
            ctx.progress(f"  {n + 1}/{len(kf)} keyframes read")
    if not kept:
        raise MappingError(f"every keyframe ({len(kf)}) is blind: the depth camera saw "
                           "nothing in the whole tour",
                           file=str(getattr(rec, "dir", None) or getattr(rec, "path", "")))
    kf = kept
    edges = pm.odometry(clouds, B[kf], cfg.registration, cfg.prior)
    T_odo = np.stack([pm.floor_pose(T) for T in pm.chain(B[kf[0]], edges)])
    registered = sum(e.ok for e in edges)
    if edges and registered < 0.5 * len(edges):
        ctx.warn(f"only {registered} of {len(edges)} consecutive keyframes registered; the "
                 "rest keep the odometry (views too far apart, or too little in them)")
    ctx.write_json("odometry/keyframes.json", dict(
        keyframes=kf, T_base_camera=C[kf], T_world_base_believed=B[kf], T_world_base=T_odo,
        T_world_camera=T_odo @ C[kf],
        edges=[dict(source=e.source, target=e.target, ok=e.ok, fitness=round(e.fitness, 4),
                    rmse=e.rmse if math.isfinite(e.rmse) else None,
                    correction_m=round(e.correction_m, 4),
                    correction_deg=round(e.correction_deg, 3), T=e.T_target_source,
                    information=e.information) for e in edges]))
    sizes = np.array([len(c.points) for c in clouds])
    np.savez_compressed(ctx.path("odometry/clouds.npz"),
                        points=np.concatenate([c.points for c in clouds]).astype(np.float32),
                        normals=np.concatenate([c.normals for c in clouds]).astype(np.float32),
                        sizes=sizes)
    return dict(captures=len(rec.captures), keyframes=len(kf), blind_skipped=blind,
                pairs=len(edges),
                registered=int(registered), points_per_keyframe=int(np.median(sizes))) \
        | _truth_figures(ctx, kf, B[kf] @ C[kf], "believed") \
        | _truth_figures(ctx, kf, T_odo @ C[kf], "odometry")


def _load_odometry(ctx: BuildContext):
    data = ctx.read_json("odometry/keyframes.json", "odometry")
    p = ctx.out / "odometry/clouds.npz"
    if not p.is_file():
        raise StageFailed(f"{p}: missing (run the odometry stage first)")
    z = np.load(p)
    cuts = np.cumsum(z["sizes"])[:-1]
    clouds = [pm.KeyframeCloud(P.astype(float), N.astype(float))
              for P, N in zip(np.split(z["points"], cuts), np.split(z["normals"], cuts))]
    edges = [pm.PairResult(e["source"], e["target"], np.asarray(e["T"]),
                           np.asarray(e["information"]), e["fitness"],
                           e["rmse"] if e["rmse"] is not None else math.inf, e["ok"],
                           e["correction_m"], e["correction_deg"]) for e in data["edges"]]
    return data, clouds, edges


# -- pose graph ----------------------------------------------------------------------------------

def run_posegraph(ctx: BuildContext) -> dict:
    import open3d as o3d
    cfg = config(ctx)
    data, clouds, edges = _load_odometry(ctx)
    kf, C = data["keyframes"], _stack(data["T_base_camera"])
    T_odo = _stack(data["T_world_base"])
    loops, tried = pm.find_loop_closures(clouds, T_odo, C, cfg.posegraph)
    T_opt, summary, graph = pm.optimise_pose_graph(T_odo, edges, loops, cfg.posegraph)
    summary["loop_closures_tried"] = tried
    if not loops:
        ctx.warn("no loop closure found: the map is the odometry chain (a tour that never "
                 "comes back to a place cannot be corrected)")
    o3d.io.write_pose_graph(str(ctx.path("posegraph/pose_graph.json")), graph)
    ctx.write_json("posegraph/poses.json", dict(keyframes=kf, T_world_base=T_opt,
                                                T_world_camera=T_opt @ C))
    ctx.write_json("posegraph/summary.json", summary)
    out = dict(loop_closures_tried=tried, loop_closures=len(loops),
               loop_closures_kept=summary["loop_closures_kept"],
               parts=len(summary["parts"])) | _truth_figures(ctx, kf, T_opt @ C, "posegraph")
    from hearth.mapping.inputs import true_cameras
    T_true = true_cameras(ctx.recording)
    if T_true is not None:
        # each part (a room, in a home without doorways) aligned on its own
        parts = summary["parts"]
        for key, T in (("odometry", _stack(data["T_world_camera"])), ("posegraph", T_opt @ C)):
            out[f"ate_in_parts_{key}_m"] = round(pm.ate_rmse_parts(T, T_true[kf], parts), 4)
    return out


# -- fusion --------------------------------------------------------------------------------------

def _poses(ctx: BuildContext):
    """The best keyframe camera poses there are: the pose graph's, else the odometry's."""
    p = ctx.out / "posegraph/poses.json"
    if p.is_file() and ctx.results.get("posegraph", {}).get("status") != "failed":
        data = ctx.read_json("posegraph/poses.json", "posegraph")
        return data["keyframes"], _stack(data["T_world_camera"]), "posegraph"
    data = ctx.read_json("odometry/keyframes.json", "odometry")
    ctx.warn("fusing at the odometry's poses (no pose graph)")
    return data["keyframes"], _stack(data["T_world_camera"]), "odometry"


def run_fuse(ctx: BuildContext) -> dict:
    import open3d as o3d
    from hearth.mapping.inputs import read_frame
    cfg = config(ctx)
    rec = ctx.recording
    kf, T, source = _poses(ctx)

    def frames():
        for n, i in enumerate(kf):
            f = read_frame(rec, i)
            if (n + 1) % 100 == 0:
                ctx.progress(f"  {n + 1}/{len(kf)} keyframes fused")
            yield f.color, f.depth

    fused = pm.fuse(frames(), T, rec.intrinsics, cfg.fusion)
    if len(fused.points) == 0:
        raise StageFailed("the TSDF volume is empty: no depth reading within "
                          f"{cfg.fusion.depth_max} m in any keyframe")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(fused.points))
    pcd.colors = o3d.utility.Vector3dVector(fused.colors)
    pcd.normals = o3d.utility.Vector3dVector(fused.normals)
    o3d.io.write_point_cloud(str(ctx.path("fused/map.ply")), pcd)
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(fused.vertices),
                                     o3d.utility.Vector3iVector(fused.triangles))
    mesh.vertex_colors = o3d.utility.Vector3dVector(fused.vertex_colors)
    mesh.compute_vertex_normals()
    o3d.io.write_triangle_mesh(str(ctx.path("fused/mesh.ply")), mesh)
    lo, hi = fused.points.min(axis=0), fused.points.max(axis=0)
    floor = fused.points[:, 2][np.abs(fused.points[:, 2]) < 0.15]
    return dict(frames=fused.frames, poses=source, points=len(fused.points),
                triangles=len(fused.triangles),
                floor_z_m=round(float(np.median(floor)), 4) if len(floor) else None,
                extent_m=np.round(hi - lo, 2).tolist())


# -- picture -------------------------------------------------------------------------------------

def run_picture(ctx: BuildContext) -> dict:
    import cv2
    import open3d as o3d
    cfg = config(ctx)
    p = ctx.out / "fused/map.ply"
    if not p.is_file():
        raise StageFailed(f"{p}: missing (run the fuse stage first)")
    pcd = o3d.io.read_point_cloud(str(p))
    kf, T, _ = _poses(ctx)
    img = draw_map(np.asarray(pcd.points), np.asarray(pcd.colors), T[:, :2, 3], cfg.px_per_m,
                   title=f"{ctx.source.name}: {len(kf)} keyframes, {len(pcd.points)} points")
    out = ctx.path("map.png")
    if not cv2.imwrite(str(out), img[..., ::-1]):
        raise StageFailed(f"{out}: cannot write the picture")
    return dict(width=img.shape[1], height=img.shape[0])


def draw_map(points: np.ndarray, colors: np.ndarray, trajectory_xy: np.ndarray, px_per_m: int,
             title: str = "", margin_m: float = 0.5) -> np.ndarray:
    """A top-down RGB picture: the points (below 2.2 m, higher ones drawn over lower) in their
    colours, the keyframe trajectory in red from a green start, a 1 m scale bar."""
    import cv2
    keep = points[:, 2] < 2.2
    P, Cc = points[keep], colors[keep]
    xy = np.vstack([P[:, :2], trajectory_xy]) if len(P) else trajectory_xy
    lo, hi = xy.min(axis=0) - margin_m, xy.max(axis=0) + margin_m
    W = int(math.ceil((hi[0] - lo[0]) * px_per_m))
    H = int(math.ceil((hi[1] - lo[1]) * px_per_m)) + 30
    img = np.full((H, W, 3), 255, np.uint8)

    def px(q):
        q = np.atleast_2d(q)
        return np.c_[(q[:, 0] - lo[0]) * px_per_m, H - 1 - (q[:, 1] - lo[1]) * px_per_m] \
            .round().astype(int)

    order = np.argsort(P[:, 2])
    uv = px(P[order, :2])
    ok = (uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)
    shade = np.clip(Cc[order] * 255, 0, 255).astype(np.uint8)
    floor = P[order, 2] < 0.05
    shade[floor] = (0.55 * shade[floor] + 0.45 * 255).astype(np.uint8)   # floor lighter
    img[uv[ok, 1], uv[ok, 0]] = shade[ok]
    t = px(trajectory_xy)
    cv2.polylines(img, [t.reshape(-1, 1, 2)], False, (220, 30, 30), 1, cv2.LINE_AA)
    if len(t):
        cv2.circle(img, tuple(int(v) for v in t[0]), 5, (30, 160, 30), -1)
    cv2.line(img, (10, H - 12), (10 + px_per_m, H - 12), (0, 0, 0), 2)
    cv2.putText(img, "1 m", (14 + px_per_m, H - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    cv2.putText(img, title[:120], (10, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
    return img


register_stage(Stage("odometry", run_odometry, "keyframes, ICP between them on the odometry"))
register_stage(Stage("posegraph", run_posegraph, "loop closures and the pose graph",
                     needs=("odometry",)))
register_stage(Stage("fuse", run_fuse, "TSDF fusion into a point cloud and a mesh",
                     needs=("posegraph",)))
register_stage(Stage("picture", run_picture, "the map from above with the trajectory",
                     needs=("fuse",)))
