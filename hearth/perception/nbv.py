"""Next best view for small objects: where to stand to see a hypothesised object best.

Given one or more object hypotheses (object id, ``T_world_object``, weight) and the current
RGB-D view, ``plan_next_best_view``:

1. puts candidate base poses on two rings around the hypotheses (the base faces them; the
   head camera looks at them from about 1.3 m) and at the parking positions of the furniture
   they stand on (the map's free floor from which that furniture is seen);
2. drops those that collide with the map's large objects (their footprints, oriented boxes in
   each object's frame, in the current articulation state), leave the room, or come within the
   robot's radius of an obstacle observed in the current view;
3. builds a voxel occupancy from the current view (observed surfaces, extruded a little away
   from the camera because the space right behind a seen surface is unknown and usually solid;
   the hypotheses' own volumes are left free, and so are the points the map's furniture
   explains: that furniture is ray cast as it is) and ray casts (open3d ``RaycastingScene``, Embree)
   from each candidate camera to points sampled on each hypothesised model surface: a point is
   visible when neither the occupancy, nor the map's furniture near it (a cupboard's sides and
   the shelf above, in their current articulation state), nor the model itself is hit first;
4. with several hypotheses, measures how well the view separates them: the fraction of rays
   on which two hypotheses would show a different depth or colour;
5. scores and sorts: best view first.

Only what the current view saw and the map's furniture are known to be occupied; elsewhere
space counts as free (the map's large objects also block the base). Pure: map, arrays and hypotheses in, candidates out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import open3d as o3d

from hearth.perception.camera import Intrinsics, depth_to_points, look_at, project
from hearth.perception.errors import PerceptionError
from hearth.perception.objects import color_agreement, model_library
from hearth.worldmodel.frames import room_at, to_room


@dataclass(frozen=True)
class NBVConfig:
    """Parameters of ``plan_next_best_view`` (metres, radians)."""
    radii: tuple[float, ...] = (0.7, 0.95, 1.25, 1.6)  #: ring radii around the hypotheses' centre
    n_angles: int = 24                     #: candidates per ring
    robot_radius: float = 0.30
    camera_height: float = 1.30
    camera_forward: float = 0.10           #: camera ahead of the base centre
    voxel: float = 0.025
    shadow_depth: float = 0.10             #: observed surfaces extruded this far behind
    stride: int = 3                        #: depth pixels used for the occupancy
    obstacle_z: tuple[float, float] = (0.05, 1.8)
    samples_per_model: int = 250
    separation_weight: float = 1.0
    travel_weight: float = 0.05            #: score lost per metre from the current base
    max_range: float = 3.5
    furniture_radius: float = 1.5          #: furniture this near the hypotheses can occlude them
    furniture_explained: float = 0.02      #: seen points this near the map's furniture are its own
    parking_candidates: bool = True        #: also try the supporting furniture's parking positions


@dataclass
class ViewCandidate:
    """One candidate view. ``base_pose`` is (x, y, yaw) in the world; ``visible_fraction`` the
    weighted mean over hypotheses of model surface facing the camera that is not occluded;
    ``visible_surface`` the same as a fraction of the whole model surface; ``separation`` the
    fraction of rays on which hypotheses would look different (0 with one hypothesis)."""
    base_pose: tuple[float, float, float]
    T_world_camera: np.ndarray
    visible_fraction: float
    visible_surface: float
    separation: float
    score: float
    ring: int


@dataclass(frozen=True)
class ObjectHypothesis:
    """Where an object might be: ``T_world_object`` (its model frame) with a weight."""
    object_id: str
    T_world_object: np.ndarray
    weight: float = 1.0


def from_detection(hypotheses, min_confidence: float = 0.05, limit: int = 4):
    """``ObjectHypothesis`` list from hearth.perception.objects hypotheses (best ``limit``)."""
    out = [ObjectHypothesis(h.object_id, h.T_world_object, max(h.confidence, 1e-3))
           for h in hypotheses if h.confidence >= min_confidence]
    return out[:limit]


def from_map(world, object_id: str, yaws: Sequence[float] = (0.0,)) -> list[ObjectHypothesis]:
    """Hypotheses at the map's believed pose of an object (optionally several yaws)."""
    T = world.T_world(object_id)
    out = []
    for a in yaws:
        R = np.eye(4)
        c, s = math.cos(a), math.sin(a)
        R[:2, :2] = [[c, -s], [s, c]]
        out.append(ObjectHypothesis(object_id, T @ R, 1.0 / len(yaws)))
    return out


# -- collision ----------------------------------------------------------------------------------

def footprints(world, room_id: Optional[str] = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """(T_world_object, (xmin, ymin, xmax, ymax) in the object's frame) for each large object
    (of ``room_id``), from its meshes in their current articulation state."""
    from hearth.worldmodel.geometry import object_meshes
    out = []
    for obj in world.large_objects():
        if room_id is not None and world.room_of(obj.id).id != room_id:
            continue
        T = world.T_world(obj.id)
        verts = [np.asarray(lm.mesh.vertices) for lm in object_meshes(world, obj, children=False)]
        if not verts:
            continue
        local = (np.vstack(verts) - T[:3, 3]) @ T[:3, :3]
        local = local[local[:, 2] < 1.9]  # what is above the robot's head does not block it
        if len(local):
            out.append((T, np.r_[local[:, :2].min(0), local[:, :2].max(0)]))
    return out


def _box_distance(p_xy: np.ndarray, T: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Distance (m) from world xy points to an oriented rectangle (0 inside)."""
    local = (np.c_[p_xy, np.zeros(len(p_xy))] - T[:3, 3]) @ T[:3, :3]
    dx = np.maximum(np.maximum(box[0] - local[:, 0], local[:, 0] - box[2]), 0)
    dy = np.maximum(np.maximum(box[1] - local[:, 1], local[:, 1] - box[3]), 0)
    return np.hypot(dx, dy)


# -- occupancy ----------------------------------------------------------------------------------

def occupancy_voxels(points_world: np.ndarray, camera_world: np.ndarray, voxel: float,
                     shadow_depth: float) -> np.ndarray:
    """(M, 3) integer voxel indices occupied by observed points, each extruded up to
    ``shadow_depth`` away from the camera. numpy ``unique`` on floored coordinates is the
    whole of building a sparse voxel set; open3d's VoxelGrid would hand the voxels back one
    Python object at a time."""
    if len(points_world) == 0:
        return np.zeros((0, 3), int)
    ray = points_world - camera_world
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    steps = np.arange(0.0, shadow_depth + 1e-9, voxel * 0.8)
    p = (points_world[None] + steps[:, None, None] * ray[None]).reshape(-1, 3)
    return np.unique(np.floor(p / voxel).astype(np.int64), axis=0)


_BOX_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1],
                   [0, 1, 1]], dtype=np.float32)
_BOX_T = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [2, 3, 7],
                   [2, 7, 6], [1, 2, 6], [1, 6, 5], [0, 4, 7], [0, 7, 3]], dtype=np.int32)


def voxel_scene(voxels: np.ndarray, voxel: float) -> o3d.t.geometry.RaycastingScene:
    """A ray-casting scene of the occupied voxels as boxes (one mesh, built with numpy)."""
    scene = o3d.t.geometry.RaycastingScene()
    if len(voxels):
        v = (voxels[:, None, :].astype(np.float32) + _BOX_V[None]) * np.float32(voxel)
        t = (_BOX_T[None] + (np.arange(len(voxels), dtype=np.int32) * 8)[:, None, None]).astype(np.uint32)
        scene.add_triangles(o3d.core.Tensor(v.reshape(-1, 3)), o3d.core.Tensor(t.reshape(-1, 3)))
    return scene


def _model_scene(world, object_id: str, T: np.ndarray) -> o3d.t.geometry.RaycastingScene:
    from hearth.worldmodel.geometry import small_object_meshes
    scene = o3d.t.geometry.RaycastingScene()
    for lm in small_object_meshes(world, world.get(object_id), T_world_object=T):
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
    return scene


def furniture_scene(world, centre, radius: float) -> o3d.t.geometry.RaycastingScene:
    """A ray-casting scene of the map's large objects (without their small objects) whose
    origin lies within ``radius`` (m) of the world point ``centre``, in their current
    articulation state: what the map knows can hide a small object (shelves, sides, doors)."""
    from hearth.worldmodel.geometry import object_meshes
    scene = o3d.t.geometry.RaycastingScene()
    c = np.asarray(centre, float)[:2]
    for obj in world.large_objects():
        if np.hypot(*(world.T_world(obj.id)[:2, 3] - c)) > radius:
            continue
        for lm in object_meshes(world, obj, children=False):
            if len(lm.mesh.triangles):
                scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
    return scene


def parking_candidates(world, centre) -> list[tuple[float, float, float]]:
    """World base poses (x, y, yaw) of the parking positions of the large object the world
    point ``centre`` stands on or in (``World.support_at``), turned to face it."""
    found = world.support_at(centre)
    if found is None:
        return []
    out = []
    for _, pose in world.parking_positions(found[0].id):
        out.append((pose.x, pose.y, math.atan2(centre[1] - pose.y, centre[0] - pose.x)))
    return out


def candidate_bases(world, centre, config: NBVConfig = NBVConfig(), room=None
                    ) -> list[tuple[float, float, float, int]]:
    """Base poses (x, y, yaw, ring) the planner considers around the world point ``centre``:
    on the rings, facing it, and (``config.parking_candidates``) the parking positions of
    the furniture it stands on (ring ``len(config.radii)``); those that leave ``room``
    (default: the room at ``centre``) or come within the robot's radius of a large object's
    footprint (current articulation state) dropped. Obstacles seen in a view are not known
    here: the planner drops those near them."""
    room = room or room_at(world, float(centre[0]), float(centre[1]))
    cands = []
    for ri, r in enumerate(config.radii):
        for k in range(config.n_angles):
            a = 2 * math.pi * (k + 0.5 * ri) / config.n_angles
            cands.append((centre[0] + r * math.cos(a), centre[1] + r * math.sin(a),
                          math.atan2(-math.sin(a), -math.cos(a)), ri))
    if config.parking_candidates:
        cands += [(x, y, yaw, len(config.radii)) for x, y, yaw in parking_candidates(world, centre)]
    xy = np.array([c[:2] for c in cands])
    ok = np.ones(len(cands), bool)
    for T, box in footprints(world, room.id if room is not None else None):
        ok &= _box_distance(xy, T, box) > config.robot_radius
    if room is not None and room.bounds is not None:
        x0, y0, x1, y1 = room.bounds
        local = to_room(room, xy)
        rr = config.robot_radius
        ok &= (local[:, 0] > x0 + rr) & (local[:, 0] < x1 - rr) & \
              (local[:, 1] > y0 + rr) & (local[:, 1] < y1 - rr)
    return [c for c, good in zip(cands, ok) if good]


def _cast(scene, origin: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Distance to the first hit along rays from ``origin`` towards ``targets`` (inf: none)."""
    d = targets - origin
    rays = np.c_[np.tile(origin, (len(d), 1)), d / np.linalg.norm(d, axis=1, keepdims=True)]
    return scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()


# -- the planner ----------------------------------------------------------------------------------

def plan_next_best_view(world, hypotheses: Sequence[ObjectHypothesis], depth: np.ndarray,
                        K: Intrinsics, T_world_camera: np.ndarray,
                        current_base: Optional[Sequence[float]] = None,
                        config: NBVConfig = NBVConfig()) -> list[ViewCandidate]:
    """Candidate views of the hypothesised objects, best first (see the module docstring).

    ``depth`` (metres) and ``T_world_camera`` are the current view; ``current_base`` (x, y,
    yaw) adds a small travel cost. Raises PerceptionError when there is no hypothesis or no
    collision-free candidate.
    """
    if not hypotheses:
        raise PerceptionError("no object hypothesis to plan a view for")
    T_world_camera = np.asarray(T_world_camera, dtype=float)
    models = model_library(world, sorted({h.object_id for h in hypotheses}))
    w = np.array([h.weight for h in hypotheses], float)
    w = w / w.sum()
    centre = np.average([h.T_world_object[:3, 3] for h in hypotheses], axis=0, weights=w)
    look = centre + (0, 0, np.average([models[h.object_id].height for h in hypotheses],
                                      weights=w) / 2)

    # The current view in the world frame, without the hypotheses' own volumes.
    s = config.stride
    P = depth_to_points(np.asarray(depth, float), K, stride=s) @ T_world_camera[:3, :3].T \
        + T_world_camera[:3, 3]
    free = np.zeros(len(P), bool)
    for h in hypotheses:
        m = models[h.object_id]
        local = P - h.T_world_object[:3, 3]
        free |= (np.hypot(local[:, 0], local[:, 1]) < m.radius + 0.02) & \
                (local[:, 2] > -0.02) & (local[:, 2] < m.height + 0.03)
    obstacles = P[~free & (P[:, 2] > config.obstacle_z[0]) & (P[:, 2] < config.obstacle_z[1])]

    # Candidates on the rings, filtered by collision.
    # The room where the hypotheses stand (an object the map keeps in another room still
    # stands where it was seen).
    room = room_at(world, float(centre[0]), float(centre[1])) or world.room_of(hypotheses[0].object_id)
    cands = candidate_bases(world, centre, config, room)
    if len(obstacles) and cands:
        from scipy.spatial import cKDTree
        d, _ = cKDTree(obstacles[:, :2]).query(np.array([c[:2] for c in cands]))
        cands = [c for c, dist in zip(cands, d) if dist > config.robot_radius]
    if not cands:
        raise PerceptionError("no collision-free view around the object")

    # Occupancy near the object: rays from the rings to it stay within the outer ring.
    near = np.hypot(*(P[:, :2] - centre[:2]).T) < max(config.radii) + 0.2
    above = P[:, 2] > centre[2] + 0.015  # the supporting surface itself hides nothing above it
    seen = P[near & above & ~free]
    # What the map's furniture explains is in its own scene, exactly: extruded, a shelf board's
    # front edge would become a slab hiding what stands below it.
    furn_scene = furniture_scene(world, centre, config.furniture_radius)
    if len(seen):
        d = furn_scene.compute_distance(o3d.core.Tensor(seen.astype(np.float32))).numpy()
        seen = seen[d > config.furniture_explained]
    occ = occupancy_voxels(seen, T_world_camera[:3, 3], config.voxel, config.shadow_depth)
    # Extruded shadows must not fill the hypotheses' volumes either.
    if len(occ):
        c = (occ + 0.5) * config.voxel
        keep = np.ones(len(occ), bool)
        for h in hypotheses:
            m = models[h.object_id]
            local = c - h.T_world_object[:3, 3]
            keep &= ~((np.hypot(local[:, 0], local[:, 1]) < m.radius + 0.01 + config.voxel)
                      & (local[:, 2] < m.height + config.voxel))
        occ = occ[keep]
    occ_scene = voxel_scene(occ, config.voxel)

    rng = np.random.default_rng(0)
    samples = []
    for h in hypotheses:
        m = models[h.object_id]
        idx = rng.choice(len(m.points), min(config.samples_per_model, len(m.points)),
                         replace=False)
        R, t = h.T_world_object[:3, :3], h.T_world_object[:3, 3]
        samples.append((m.points[idx] @ R.T + t, m.normals[idx] @ R.T, m.hsv[idx], m))
    own = [_model_scene(world, h.object_id, h.T_world_object) for h in hypotheses]

    out = []
    for (x, y, yaw, ri) in cands:
        eye = np.array([x + config.camera_forward * math.cos(yaw),
                        y + config.camera_forward * math.sin(yaw), config.camera_height])
        T_wc = look_at(eye, look)
        T_cw = np.linalg.inv(T_wc)
        vis_frac, vis_surf, seps = [], [], []
        rays_vis = []
        for (pw, nw, hsv, m), scene in zip(samples, own):
            dist = np.linalg.norm(pw - eye, axis=1)
            facing = np.einsum("ij,ij->i", nw, pw - eye) < 0
            uv, front = project(pw @ T_cw[:3, :3].T + T_cw[:3, 3], K)
            inimg = front & (uv[:, 0] >= 0) & (uv[:, 0] < K.width) & (uv[:, 1] >= 0) & \
                (uv[:, 1] < K.height) & (dist < config.max_range)
            cand = facing & inimg
            t_self = _cast(scene, eye, pw)
            t_occ = _cast(occ_scene, eye, pw)
            t_furn = _cast(furn_scene, eye, pw)
            unblocked = (t_self > dist - 0.004) & (t_occ > dist - 0.01) & (t_furn > dist - 0.01)
            vis = cand & unblocked
            vis_frac.append(vis.sum() / cand.sum() if cand.sum() else 0.0)
            vis_surf.append(vis.sum() / len(pw))
            rays_vis.append(vis)
        if len(hypotheses) > 1:
            for i, (pw, _, hsv, _) in enumerate(samples):
                pts_i = pw[rays_vis[i]]
                if not len(pts_i):
                    continue
                d_i = np.linalg.norm(pts_i - eye, axis=1)
                for j, (pwj, _, hsvj, mj) in enumerate(samples):
                    if j == i:
                        continue
                    t_j = _cast(own[j], eye, pts_i)
                    differ = np.abs(np.where(np.isfinite(t_j), t_j, 10.0) - d_i) > 0.01
                    hit = ~differ
                    if hit.any():
                        # Same depth: different colour still tells them apart.
                        from scipy.spatial import cKDTree
                        _, jj = cKDTree(pwj).query(pts_i[hit])
                        differ[hit] = color_agreement(hsv[rays_vis[i]][hit], hsvj[jj]) < 0.5
                    seps.append(w[i] * differ.sum() / len(pw))
        vf = float(np.dot(w, vis_frac))
        vs = float(np.dot(w, vis_surf))
        sep = float(np.sum(seps)) if seps else 0.0
        score = vf * (0.5 + vs) + config.separation_weight * sep
        if current_base is not None:
            score -= config.travel_weight * math.hypot(x - current_base[0], y - current_base[1])
        out.append(ViewCandidate((float(x), float(y), float(yaw)), T_wc, vf, vs, sep,
                                 float(score), ri))
    out.sort(key=lambda c: c.score, reverse=True)
    return out
