"""A fused map of a generated home FROM TRUE POSES: the stand-in for the tour's metric map,
on which the large-object classifier is trained (hearth/mapping/classify.py) and the draft
benchmark runs (``hearth bench mapping_draft``).

``fused_from_true_poses(world)`` renders RGB-D views of the truth with the simulated camera
(hearth/robot/sim.py, Kinect-class noise) at *true* camera poses and fuses them with the
metric map's own TSDF fusion (``hearth.perception.mapping.fuse``: open3d's VoxelBlockGrid) at
1 cm into a coloured point cloud with normals in the map frame (z up, floor at z = 0,
metres): the same thing ``hearth map build`` writes as DIR/fused/map.ply from a tour.
No odometry, no pose graph: figures drafted from it say ``"poses": "true"``; swap in the
tour's map to measure the whole chain.

The views: from every parking position of the home the robot looks at its object (its face,
its top, and a little lower and higher), and from a few places in each room it turns round at
two head tilts (the walls and the floor).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TruePoseMapConfig:
    voxel: float = 0.01            #: TSDF voxel (m)
    sdf_trunc: float = 0.03        #: TSDF truncation (m)
    depth_trunc: float = 3.5       #: depth used up to (m)
    scale: float = 0.5             #: image scale of the rendered views (0.5: 320 x 240)
    pans: int = 8                  #: views per turn round
    tilts: tuple = (math.radians(10), math.radians(45))
    noise: bool = True             #: the simulated Kinect noise
    seed: int = 0


def _view_poses(world, cfg: TruePoseMapConfig, few: bool = False) -> list[np.ndarray]:
    """True ``T_world_camera`` of every view (see the module docstring)."""
    from hearth.robot.sim import camera_pose, pan_tilt_to
    from hearth.worldmodel.frames import T_world_room
    from hearth.worldmodel.geometry import object_meshes
    out = []
    for room in world.rooms:
        T_wr = T_world_room(room)
        x0, y0, x1, y1 = room.bounds
        spots = [((x0 + x1) / 2, (y0 + y1) / 2)]
        spots += [(x0 + (x1 - x0) * fx, y0 + (y1 - y0) * fy) for fx, fy in
                  ((0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75))]
        free = []
        for o in room.objects:
            T_wo = T_wr @ o.pose.matrix()
            meshes = object_meshes(world, o, T_world_object=T_wo, children=True)
            pts = np.vstack([np.asarray(m.mesh.vertices) for m in meshes])
            lo, hi = pts.min(0), pts.max(0)
            free.append((lo, hi))
            centre = (lo + hi) / 2
            for pk in (o.parking[:1] if few else o.parking):
                T_wb = T_wo @ pk.pose.matrix()
                for z in sorted({min(hi[2], 1.0) * 0.5, hi[2] - 0.05, 0.15}):
                    target = np.array([centre[0], centre[1], z])
                    pan, tilt = pan_tilt_to(T_wb, target)
                    out.append(camera_pose(T_wb, pan, tilt))
        for sx, sy in (spots[:1] if few else spots):
            p = T_wr @ np.array([sx, sy, 0.0, 1.0])
            if any(np.all(p[:2] > lo[:2] - 0.35) and np.all(p[:2] < hi[:2] + 0.35)
                   for lo, hi in free):
                continue
            for k in range(cfg.pans):
                yaw = 2 * math.pi * k / cfg.pans
                c, s = math.cos(yaw), math.sin(yaw)
                T_wb = np.array([[c, -s, 0, p[0]], [s, c, 0, p[1]], [0, 0, 1, 0], [0, 0, 0, 1.0]])
                for tilt in cfg.tilts:
                    out.append(camera_pose(T_wb, 0.0, tilt))
    return out


def fused_from_true_poses(world, cfg: TruePoseMapConfig = TruePoseMapConfig(), progress=None,
                          few: bool = False):
    """(open3d PointCloud with colours and normals, number of views) of ``world`` rendered at
    true poses and fused by the metric map's TSDF fusion (``hearth.perception.mapping.fuse``,
    open3d's VoxelBlockGrid) at 1 cm; ``few``: from each object's first parking position only
    and one place per room (a quick map for tests)."""
    import open3d as o3d
    from hearth.robot.noise import KinectNoise
    from hearth.robot.sim import render_view, world_scene
    from hearth.perception.camera import Intrinsics
    from hearth.perception.mapping import FusionOptions, fuse
    K = Intrinsics.kinect().scaled(cfg.scale)
    scene = world_scene(world)
    rng = np.random.default_rng(cfg.seed)
    poses = _view_poses(world, cfg, few)

    def frames():
        for i, T in enumerate(poses):
            f = render_view(world, K, T, rng=rng, noise=KinectNoise() if cfg.noise else None,
                            scene=scene)
            if progress:
                progress(i + 1, len(poses))
            yield f.color, f.depth

    options = FusionOptions(voxel=cfg.voxel, block_count=60000, depth_max=cfg.depth_trunc,
                            width=K.width, weight_threshold=1.0,
                            trunc_voxels=cfg.sdf_trunc / cfg.voxel,
                            min_valid_pixels=100,      # a view of nothing in range: skipped
                            mesh=False)
    fused = fuse(frames(), np.array(poses), K, options)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(fused.points))
    pcd.colors = o3d.utility.Vector3dVector(fused.colors)
    pcd.normals = o3d.utility.Vector3dVector(fused.normals)
    return pcd, len(poses)


def cached_fused(seed: int, config=None, cache_dir=None, cfg: TruePoseMapConfig = TruePoseMapConfig()):
    """(world, fused PointCloud) of generated home ``seed``, the cloud cached as
    ``true-pose-<seed>-<key>.ply`` in ``cache_dir`` (default ~/.cache/hearth/mapdraft)."""
    import hashlib
    import json
    import os
    from pathlib import Path
    import open3d as o3d
    from hearth.worldmodel.homegen import GENERATOR_VERSION, HomeConfig, generate_home
    config = config or HomeConfig()
    world = generate_home(seed, config)
    key = hashlib.sha1(json.dumps([repr(config), repr(cfg), GENERATOR_VERSION]).encode()).hexdigest()[:10]
    d = Path(cache_dir or os.environ.get("HEARTH_MAPDRAFT_DIR", Path.home() / ".cache" / "hearth" / "mapdraft"))
    path = d / f"true-pose-{seed}-{key}.ply"
    if path.exists():
        return world, o3d.io.read_point_cloud(str(path))
    pcd, _ = fused_from_true_poses(world, cfg)
    d.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.ply")
    o3d.io.write_point_cloud(str(tmp), pcd)
    os.replace(tmp, path)
    return world, pcd
