"""A metric map from an RGB-D walk-through: keyframes, odometry between them, a pose graph with
loop closures, TSDF fusion (docs/mapping.md).

The stages follow Open3D's reconstruction system and call its pipelines rather than re-derive
them: ``open3d.pipelines.registration`` (``PoseGraph``, ``global_optimization`` with its line
process) and Open3D's TSDF integration (``open3d.t.geometry.VoxelBlockGrid``). Pairwise
registration is point-to-plane ICP over the base's x, y and yaw with the odometry as a prior,
built from the pieces of hearth/perception/registration.py, because Open3D's ICP has no prior term
(see ``RegistrationOptions``). Each stage is a function with one options dataclass, arrays in
and out, no hidden state and no files (hearth/mapping/ reads the recording and writes each
stage's output).

Frames: ``T_world_camera`` maps camera points (OpenCV axes: x right, y down, z forward) into
the map frame (z up, floor at z = 0, metres; the recording's world frame, in which the robot's
start pose is known). Keyframe poses are (K, 4, 4) arrays; the pose graph is over base poses
``T_world_base`` (on the floor), cameras follow as ``T_world_base @ T_base_camera``. An edge
``(i, j, T_j_i)`` maps points of keyframe i's base frame into keyframe j's (Open3D's source ->
target).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from hearth.perception.camera import Intrinsics


# -- keyframes ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class KeyframeOptions:
    """A frame becomes a keyframe when the believed camera moved this far from the last one
    (metres), or its optical axis turned this far (degrees)."""
    min_translation: float = 0.30
    min_rotation_deg: float = 15.0


def _axis_angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(c, -1.0, 1.0))))


def select_keyframes(T_world_camera: np.ndarray, options: KeyframeOptions = KeyframeOptions()
                     ) -> list[int]:
    """Indices of the keyframes among (N, 4, 4) believed camera poses (the first is one)."""
    T = np.asarray(T_world_camera, dtype=float)
    if len(T) == 0:
        return []
    keep = [0]
    for i in range(1, len(T)):
        last = T[keep[-1]]
        moved = np.linalg.norm(T[i][:3, 3] - last[:3, 3])
        turned = _axis_angle_deg(last[:3, :3], T[i][:3, :3])
        if moved >= options.min_translation or turned >= options.min_rotation_deg:
            keep.append(i)
    return keep


# -- clouds ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CloudOptions:
    """How a keyframe's depth becomes the points registration works on: back-projected,
    put in the robot's base frame, downsampled, and only the points of upright surfaces (walls,
    furniture faces) kept, since a planar robot's motion (x, y, yaw) is constrained by them
    and not by the floor or the ceiling."""
    voxel: float = 0.04           #: metres, downsampling
    depth_min: float = 0.3        #: metres
    depth_max: float = 3.5        #: metres; Kinect-class noise grows with the square of depth
    stride: int = 2               #: pixel step when back-projecting
    normal_radius: float = 0.12   #: metres
    max_normal_z: float = 0.5     #: keep points whose unit normal's |z| is below this


@dataclass
class KeyframeCloud:
    """A keyframe's upright-surface points and unit normals (N, 3), base frame."""
    points: np.ndarray
    normals: np.ndarray
    _tree: object = None

    def tree(self):
        from scipy.spatial import cKDTree
        if self._tree is None:
            self._tree = cKDTree(self.points)
        return self._tree


def keyframe_cloud(depth: np.ndarray, K: Intrinsics, T_base_camera: np.ndarray,
                   options: CloudOptions = CloudOptions()) -> KeyframeCloud:
    """The registration cloud of one depth image (float metres, 0 = no reading) taken by a
    camera at ``T_base_camera`` on the base."""
    import open3d as o3d
    s = max(1, int(options.stride))
    z = np.asarray(depth, dtype=np.float32)[::s, ::s]
    v, u = np.nonzero((z > options.depth_min) & (z < options.depth_max))
    zz = z[v, u].astype(np.float64)
    x = (u * s - K.cx) / K.fx * zz
    y = (v * s - K.cy) / K.fy * zz
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.c_[x, y, zz]))
    pcd = pcd.voxel_down_sample(options.voxel)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=options.normal_radius,
                                                              max_nn=30))
    # Normals face the camera: the two sides of a wall then disagree, and a view through a
    # wall into the next room cannot match (registration pairs only agreeing normals).
    pcd.orient_normals_towards_camera_location(np.zeros(3))
    pcd.transform(np.asarray(T_base_camera, float))
    P, N = np.asarray(pcd.points), np.asarray(pcd.normals)
    keep = np.abs(N[:, 2]) < options.max_normal_z if len(N) else np.zeros(0, bool)
    return KeyframeCloud(P[keep], N[keep])


# -- pairwise registration ---------------------------------------------------------------------

@dataclass(frozen=True)
class RegistrationOptions:
    """Point-to-plane ICP in x, y and yaw with a motion prior (odometry, or the current
    estimate), coarse then fine. Open3D's ICP has no prior term, and on a view of one wall it
    slides along the wall (measured on tours: 0.9 m off a prior good to a millimetre); the
    prior holds what the points leave free. A result is kept only when enough of the source
    overlaps and the correction of the prior is plausible."""
    gates: tuple[float, ...] = (0.15, 0.08, 0.04)  #: max correspondence distance per level, m
    iterations: tuple[int, ...] = (10, 10, 10)
    sigma_point: float = 0.02          #: metres, point-to-plane residual scale
    robust_scale: float = 0.05         #: metres, Tukey kernel at the finest level
    min_fitness: float = 0.30          #: share of source points with a correspondence
    max_rmse: float = 0.025            #: metres, point-to-plane RMSE at the finest level
    max_correction_m: float = 0.30     #: change of the prior's translation, metres
    max_correction_deg: float = 10.0   #: change of the prior's yaw
    min_points: int = 50
    min_normal_dot: float = 0.7        #: a correspondence's normals agree at least this much


@dataclass(frozen=True)
class MotionPrior:
    """Standard deviations of a prior relative motion: translation (each axis) and yaw, as
    a floor plus a fraction of the distance and the angle moved."""
    sigma_m: float = 0.01
    sigma_deg: float = 0.3
    per_m: float = 0.02
    per_rad: float = 0.02

    def information(self, T: np.ndarray) -> np.ndarray:
        d = math.hypot(T[0, 3], T[1, 3])
        a = abs(math.atan2(T[1, 0], T[0, 0]))
        st = self.sigma_m + self.per_m * d
        sa = math.radians(self.sigma_deg) + self.per_rad * a
        return np.diag([1 / st ** 2, 1 / st ** 2, 1 / sa ** 2])


@dataclass
class PairResult:
    """A registered pair: ``T_target_source`` (planar, base frames), the 6 x 6 information
    matrix over Open3D's (rx, ry, rz, tx, ty, tz), fitness, RMSE (m), whether it passed the
    checks (else ``T_target_source`` is the prior) and how far it moved the prior."""
    source: int
    target: int
    T_target_source: np.ndarray
    information: np.ndarray
    fitness: float
    rmse: float
    ok: bool
    correction_m: float = 0.0
    correction_deg: float = 0.0


def _planar(x: float, y: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = (x, y)
    return T


def _about(D: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Parameters x of a planar move D as ``hearth.perception.registration.planar_delta(x, c)``."""
    a = math.atan2(D[1, 0], D[0, 0])
    return np.r_[D[:2, 3] - c[:2] + D[:2, :2] @ c[:2], a]


def information_6dof(info_c: np.ndarray, c: np.ndarray, count: float = 1.0,
                     stiff: float = 1e6) -> np.ndarray:
    """A 3x3 information over (x, y, yaw about the point c) as Open3D's 6x6 over (rx, ry, rz,
    tx, ty, tz) about the origin, in Open3D's units (unit residual scale: one point adds its
    Jacobian's outer product); roll and pitch (a base on the floor) held by ``stiff``. Open3D
    reads the tz entry as the edge's number of correspondences when it weighs loop closures
    against their residual (the line process), so that entry is ``count``: every edge is
    planar, so height has nothing to hold."""
    A = np.array([[1.0, 0.0, c[1]], [0.0, 1.0, -c[0]], [0.0, 0.0, 1.0]])   # origin <- about c
    Ai = np.linalg.inv(A)
    L = Ai.T @ info_c @ Ai                                              # (x, y, yaw) at origin
    out = np.diag([stiff, stiff, 0.0, 0.0, 0.0, max(float(count), 1.0)])
    idx = [3, 4, 2]
    for a in range(3):
        for b in range(3):
            out[idx[a], idx[b]] = L[a, b]
    return out


def _agreeing(T, source: KeyframeCloud, target: KeyframeCloud, moved: np.ndarray, gate: float,
              min_dot: float) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-neighbour correspondences within ``gate`` whose normals agree."""
    from hearth.perception.registration import associate
    i_s, i_t, _ = associate(target.tree(), moved, gate)
    dots = np.einsum("ij,ij->i", source.normals[i_s] @ T[:3, :3].T, target.normals[i_t])
    keep = dots >= min_dot
    return i_s[keep], i_t[keep]


def register_pair(source: KeyframeCloud, target: KeyframeCloud, T_prior: np.ndarray,
                  prior_information: np.ndarray, options: RegistrationOptions
                  = RegistrationOptions(), ids: tuple[int, int] = (0, 1)) -> PairResult:
    """Register ``source`` onto ``target`` (both base frames) from ``T_prior``
    (``T_target_source``, planar) held by ``prior_information`` (3x3 over x, y, yaw)."""
    from hearth.perception.registration import (kernel_weights, normal_equations, planar_delta,
                                         planar_plane_jacobian, point_to_plane, transform)
    T_prior = np.asarray(T_prior, dtype=float)
    # Open3D's pose graph takes information at a unit residual scale: everything here is
    # divided by the point weight (so an odometry prior keeps its weight against the points).
    w_data = 1.0 / options.sigma_point ** 2
    fail = PairResult(ids[0], ids[1], T_prior,
                      information_6dof(prior_information / w_data, np.zeros(3)),
                      0.0, math.inf, False)
    if len(source.points) < options.min_points or len(target.points) < options.min_points:
        return fail
    q_all, n_all = target.points, target.normals
    c = target.points.mean(axis=0)
    c[2] = 0.0
    T = T_prior.copy()
    H_data = np.zeros((3, 3))
    last = len(options.gates) - 1
    for level, (gate, iterations) in enumerate(zip(options.gates, options.iterations)):
        for _ in range(iterations):
            p = transform(T, source.points)
            i_s, i_t = _agreeing(T, source, target, p, gate, options.min_normal_dot)
            if len(i_s) < 6:
                break
            ps, q, n = p[i_s], q_all[i_t], n_all[i_t]
            r = point_to_plane(ps, q, n)
            w = kernel_weights(r, level == last, options.robust_scale) * w_data
            J = planar_plane_jacobian(n, ps - c)
            H_data, g = normal_equations(J, r, w)
            x_dev = _about(T @ np.linalg.inv(T_prior), c)
            H = H_data + prior_information
            g = g + prior_information @ x_dev
            x = -np.linalg.solve(H + 1e-9 * np.eye(3), g)
            T = planar_delta(x, c) @ T
            if abs(x[0]) + abs(x[1]) + abs(x[2]) < 1e-5:
                break
    p = transform(T, source.points)
    i_s, i_t = _agreeing(T, source, target, p, options.gates[-1], options.min_normal_dot)
    fitness = len(i_s) / max(len(source.points), 1)
    r = point_to_plane(p[i_s], q_all[i_t], n_all[i_t])
    rmse = float(np.sqrt(np.mean(r ** 2))) if len(r) else math.inf
    delta = T @ np.linalg.inv(T_prior)
    corr_m = float(np.hypot(*_about(delta, c)[:2]))
    corr_deg = abs(math.degrees(math.atan2(delta[1, 0], delta[0, 0])))
    ok = (fitness >= options.min_fitness and rmse <= options.max_rmse
          and corr_m <= options.max_correction_m and corr_deg <= options.max_correction_deg)
    if not ok:
        fail.fitness, fail.rmse, fail.correction_m, fail.correction_deg = (fitness, rmse, corr_m,
                                                                           corr_deg)
        return fail
    return PairResult(ids[0], ids[1], T,
                      information_6dof((H_data + prior_information) / w_data, c, len(i_s)),
                      fitness, rmse, True, corr_m, corr_deg)


def relative(T_world_a: np.ndarray, T_world_b: np.ndarray) -> np.ndarray:
    """``T_b_a``: maps points of frame a into frame b."""
    return np.linalg.inv(T_world_b) @ T_world_a


def odometry(clouds: list[KeyframeCloud], T_world_base: np.ndarray,
             options: RegistrationOptions = RegistrationOptions(),
             prior: MotionPrior = MotionPrior()) -> list[PairResult]:
    """Register each keyframe onto the one before it, from the believed base poses' relative
    motion (the robot's odometry) held by ``prior``. Returns K - 1 results (edge i: keyframe
    i+1 -> keyframe i); a failed registration keeps the odometry with its prior information."""
    T = np.asarray(T_world_base, dtype=float)
    out = []
    for i in range(1, len(clouds)):
        T0 = relative(T[i], T[i - 1])
        out.append(register_pair(clouds[i], clouds[i - 1], T0, prior.information(T0), options,
                                 ids=(i, i - 1)))
    return out


def chain(T_first: np.ndarray, edges: list[PairResult]) -> np.ndarray:
    """Poses from the first and consecutive edges (edge i maps keyframe i+1 into keyframe i)."""
    poses = [np.asarray(T_first, float)]
    for e in edges:
        poses.append(poses[-1] @ e.T_target_source)
    return np.stack(poses)


# -- pose graph ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class PoseGraphOptions:
    """Loop closures and the global optimisation."""
    loop_radius: float = 1.6           #: camera centres at most this far apart, metres
    loop_angle_deg: float = 35.0       #: optical axes at most this far apart
    min_separation: int = 6            #: keyframes apart in the sequence
    max_candidates: int = 2            #: loop closures tried per keyframe (nearest first)
    loop_prior: MotionPrior = MotionPrior(sigma_m=0.15, sigma_deg=3.0, per_m=0.0, per_rad=0.0)
    registration: RegistrationOptions = RegistrationOptions(
        gates=(0.15, 0.08, 0.04), iterations=(10, 10, 10), min_fitness=0.35,
        max_rmse=0.02, max_correction_m=0.4, max_correction_deg=8.0)
    max_correspondence: float = 0.03   #: global optimisation (line process), metres
    edge_prune_threshold: float = 0.25
    #: 0.1: as Open3D's reconstruction system for a sequence of odometry (loop closures weigh
    #: less than the odometry; on development tours, seeds 3 and 5, 1.0 left the rooms 2.9 and
    #: 2.9 cm off, 0.1 1.5 and 2.1 cm, odometry alone 2.8 and 2.5 cm)
    preference_loop_closure: float = 0.1


def loop_candidates(T_world_camera: np.ndarray, options: PoseGraphOptions = PoseGraphOptions()
                    ) -> list[tuple[int, int]]:
    """Pairs (i, j), i > j + min_separation, whose cameras are near and look the same way."""
    T = np.asarray(T_world_camera, dtype=float)
    c = T[:, :3, 3]
    z = T[:, :3, 2]
    cos_max = math.cos(math.radians(options.loop_angle_deg))
    pairs = []
    for i in range(len(T)):
        j = np.arange(0, max(0, i - options.min_separation))
        if not len(j):
            continue
        d = np.linalg.norm(c[j] - c[i], axis=1)
        good = (d <= options.loop_radius) & (z[j] @ z[i] >= cos_max)
        js = j[good][np.argsort(d[good])][: options.max_candidates]
        pairs += [(i, int(k)) for k in js]
    return pairs


def find_loop_closures(clouds: list[KeyframeCloud], T_world_base: np.ndarray,
                       T_base_camera: np.ndarray, options: PoseGraphOptions = PoseGraphOptions()
                       ) -> tuple[list[PairResult], int]:
    """Loop closures among the candidates of the current estimate: registered pairs that
    passed the checks, and how many were tried."""
    T = np.asarray(T_world_base, float)
    pairs = loop_candidates(T @ np.asarray(T_base_camera, float), options)
    found = []
    for i, j in pairs:
        T0 = relative(T[i], T[j])
        r = register_pair(clouds[i], clouds[j], T0, options.loop_prior.information(T0),
                          options.registration, ids=(i, j))
        if r.ok:
            found.append(r)
    return found, len(pairs)


def _components(n: int, links: list[tuple[int, int]]) -> list[list[int]]:
    parent = list(range(n))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a
    for a, b in links:
        parent[root(a)] = root(b)
    groups: dict[int, list[int]] = {}
    for k in range(n):
        groups.setdefault(root(k), []).append(k)
    return sorted(groups.values(), key=lambda g: g[0])


def optimise_pose_graph(T_odometry: np.ndarray, odometry_edges: list[PairResult],
                        loops: list[PairResult], options: PoseGraphOptions = PoseGraphOptions()
                        ) -> tuple[np.ndarray, dict, object]:
    """Open3D's global optimisation (Levenberg-Marquardt, line process on the loop closures)
    over the base poses of the odometry chain ``T_odometry`` (node 0 fixed). Returns the
    optimised base poses (put back on the floor), a summary, and the whole ``PoseGraph``.

    The keyframes fall into parts that views link (registered odometry edges and loop
    closures); parts are linked only by odometry edges whose registration failed (a drive into
    another room: no view spans it), whose relative placement nothing observes. Each part is
    optimised on its own, its first keyframe placed by the odometry from the part before:
    optimised together, the weak links (1e-5 of a registered edge's information) leave the
    problem so ill-conditioned that Levenberg-Marquardt moved whole rooms by 15 cm on tours.
    """
    import open3d as o3d
    reg = o3d.pipelines.registration
    T = np.asarray(T_odometry, float).copy()
    n = len(T)
    edges = list(odometry_edges) + list(loops)
    loop_ids = {id(e) for e in loops}
    parts = _components(n, [(e.source, e.target) for e in edges if e.ok])
    by_source = {e.source: e for e in odometry_edges}
    kept = 0
    for part in parts:
        first = part[0]
        if first > 0 and first in by_source:       # placed by the odometry from before
            delta = (T[first - 1] @ by_source[first].T_target_source) @ np.linalg.inv(T[first])
            T[part] = delta @ T[part]
        index = {k: i for i, k in enumerate(part)}
        inside = [e for e in edges if e.source in index and e.target in index]
        part_loops = [e for e in inside if id(e) in loop_ids]
        if not part_loops:
            continue
        graph = reg.PoseGraph()
        for k in part:
            graph.nodes.append(reg.PoseGraphNode(T[k]))
        for e in inside:
            graph.edges.append(reg.PoseGraphEdge(index[e.source], index[e.target],
                                                 e.T_target_source, e.information,
                                                 uncertain=id(e) in loop_ids))
        with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            reg.global_optimization(
                graph, reg.GlobalOptimizationLevenbergMarquardt(),
                reg.GlobalOptimizationConvergenceCriteria(),
                reg.GlobalOptimizationOption(
                    max_correspondence_distance=options.max_correspondence,
                    edge_prune_threshold=options.edge_prune_threshold,
                    preference_loop_closure=options.preference_loop_closure,
                    reference_node=0))
        kept += sum(1 for e in graph.edges if e.uncertain)
        for k, node in zip(part, graph.nodes):
            T[k] = np.asarray(node.pose)
    T_opt = np.stack([floor_pose(t) for t in T])
    whole = reg.PoseGraph()
    for t in T_opt:
        whole.nodes.append(reg.PoseGraphNode(t))
    for e in edges:
        whole.edges.append(reg.PoseGraphEdge(e.source, e.target, e.T_target_source,
                                             e.information, uncertain=id(e) in loop_ids))
    summary = dict(nodes=n, parts=parts, odometry_edges=len(odometry_edges),
                   odometry_edges_registered=sum(1 for e in odometry_edges if e.ok),
                   loop_closures_tried=None, loop_closures=len(loops), loop_closures_kept=kept)
    return T_opt, summary, whole


def floor_pose(T_world_base: np.ndarray) -> np.ndarray:
    """A base pose put back on the floor: x, y and yaw kept; z, roll and pitch zero."""
    T = np.asarray(T_world_base, float)
    return _planar(T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0]))


# -- fusion ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FusionOptions:
    """Open3D's TSDF voxel block grid, integrated at ``width`` pixels across."""
    voxel: float = 0.02           #: metres
    block_resolution: int = 16    #: voxels per block side
    block_count: int = 40000      #: blocks reserved (the grid grows past it)
    depth_max: float = 3.5        #: metres
    width: int = 320              #: integration resolution (the camera scaled to it)
    weight_threshold: float = 2.0  #: a surface must be seen by this many frames' worth
    trunc_voxels: float = 8.0     #: the TSDF's truncation in voxels (Open3D's default)
    min_valid_pixels: int = 0     #: a frame with fewer depth readings in range is skipped
    mesh: bool = True             #: also extract the triangle mesh


@dataclass
class FusedMap:
    """The fused map (map frame): points (N, 3) with colours (N, 3, 0..1) and normals, and the
    mesh's vertices, triangles and vertex colours."""
    points: np.ndarray
    colors: np.ndarray
    normals: np.ndarray
    vertices: np.ndarray
    triangles: np.ndarray
    vertex_colors: np.ndarray
    frames: int


def fuse(frames: Iterable[tuple[np.ndarray, np.ndarray]], T_world_camera: np.ndarray,
         K: Intrinsics, options: FusionOptions = FusionOptions()) -> FusedMap:
    """Integrate ``frames`` (colour uint8 RGB (H, W, 3), depth float metres, 0 = none), seen
    from the matching ``T_world_camera``, into a TSDF (``open3d.t.geometry.VoxelBlockGrid``,
    the successor of the legacy ``ScalableTSDFVolume``, which in Open3D 0.20 extracts nothing
    from these frames); its point cloud and mesh."""
    import cv2
    import open3d as o3d
    import open3d.core as o3c
    vbg = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight", "color"), attr_dtypes=(o3c.float32,) * 3,
        attr_channels=((1), (1), (3)), voxel_size=options.voxel,
        block_resolution=options.block_resolution, block_count=options.block_count,
        device=o3c.Device("CPU:0"))
    factor = min(1.0, options.width / K.width)
    Ks = K.scaled(factor) if factor < 1.0 else K
    intr = o3c.Tensor(Ks.matrix(), o3c.float64)
    n = 0
    for (color, depth), T in zip(frames, np.asarray(T_world_camera, float)):
        if factor < 1.0:
            color = cv2.resize(color, (Ks.width, Ks.height), interpolation=cv2.INTER_AREA)
            depth = cv2.resize(depth, (Ks.width, Ks.height), interpolation=cv2.INTER_NEAREST)
        if options.min_valid_pixels and np.count_nonzero(
                (depth > 0) & (depth < options.depth_max)) < options.min_valid_pixels:
            continue
        d = o3d.t.geometry.Image(np.ascontiguousarray(depth, dtype=np.float32))
        c = o3d.t.geometry.Image(np.ascontiguousarray(color, dtype=np.float32) / 255.0)
        extr = o3c.Tensor(np.linalg.inv(T), o3c.float64)
        blocks = vbg.compute_unique_block_coordinates(d, intr, extr, 1.0, options.depth_max,
                                                      options.trunc_voxels)
        vbg.integrate(blocks, d, c, intr, intr, extr, 1.0, options.depth_max,
                      options.trunc_voxels)
        n += 1
    if n == 0:
        z = np.zeros((0, 3))
        return FusedMap(z, z, z, z, np.zeros((0, 3), int), z, 0)
    pcd = vbg.extract_point_cloud(weight_threshold=options.weight_threshold)
    mesh = vbg.extract_triangle_mesh(weight_threshold=options.weight_threshold) \
        if options.mesh else None

    def arr(tmap, key, shape):
        return tmap[key].numpy().astype(float) if key in tmap else np.zeros(shape)

    P = arr(pcd.point, "positions", (0, 3))
    if mesh is None:
        V, F, VC = np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3))
    else:
        V = arr(mesh.vertex, "positions", (0, 3))
        F = mesh.triangle["indices"].numpy().astype(np.int64) if "indices" in mesh.triangle \
            else np.zeros((0, 3), np.int64)
        VC = np.clip(arr(mesh.vertex, "colors", V.shape), 0, 1)
    return FusedMap(P, np.clip(arr(pcd.point, "colors", P.shape), 0, 1),
                    arr(pcd.point, "normals", P.shape), V, F, VC, n)


# -- scoring -------------------------------------------------------------------------------------

def ate_rmse(T_est: np.ndarray, T_true: np.ndarray) -> float:
    """Absolute trajectory error (metres): RMSE of camera centres, in the map frame as it is
    (the map frame is the recording's world frame, so no alignment is fitted)."""
    d = np.asarray(T_est)[:, :3, 3] - np.asarray(T_true)[:, :3, 3]
    return float(np.sqrt(np.mean(np.sum(d ** 2, axis=1)))) if len(d) else math.nan


def yaw_rmse_deg(T_est: np.ndarray, T_true: np.ndarray) -> float:
    """RMSE of the rotation between estimated and true camera orientations (degrees)."""
    a = [_axis_angle_deg(a[:3, :3], b[:3, :3]) for a, b in zip(T_est, T_true)]
    return float(np.sqrt(np.mean(np.square(a)))) if a else math.nan


def ate_rmse_parts(T_est: np.ndarray, T_true: np.ndarray, parts: list[list[int]]) -> float:
    """ATE (metres) with each part (keyframes views link, e.g. one room) aligned to the truth
    on its own by the best planar rigid motion of its camera centres (2-D Kabsch): how well
    the map holds together where it could be observed, apart from where the parts sit."""
    sq, n = 0.0, 0
    for part in parts:
        a = np.asarray(T_est)[part][:, :2, 3]
        b = np.asarray(T_true)[part][:, :2, 3]
        ca, cb = a.mean(axis=0), b.mean(axis=0)
        H = (a - ca).T @ (b - cb)
        t = math.atan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
        R = np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
        d = (a - ca) @ R.T + cb - b
        sq += float(np.sum(d ** 2))
        n += len(part)
    return math.sqrt(sq / n) if n else math.nan
