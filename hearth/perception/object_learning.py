"""Learn a small object's model from RGB-D views around it (HOBBIT section 4, RAMCIP 3.3.3).

The shape of Open3D's reconstruction system, for one object: a few named stages, one
configuration, arrays in and out.

1. ``segment_view``: the object's points in one view. Points within ``support_window`` of
   the surface height the map gives, a seeded RANSAC plane among them (the support), the
   points standing over it within ``region_radius`` of where the object is believed to
   stand, their Euclidean cluster nearest that place (hearth.perception.objects' pieces). A ring
   of the support around the object is kept apart: it is static, and pins height, roll and
   pitch when the views are registered.
2. ``register_views``: each view's points are in the world frame through the robot's
   believed camera pose, which is off by the localisation error of wherever the robot stood.
   The error is planar (x, y, yaw: the camera's height, roll and pitch come from the robot's
   joints), so consecutive views are registered pairwise with Hearth's x-y-yaw ICP
   (hearth.perception.registration.register_planar) on the object's points, a correction larger
   than a localisation error could be refused, every pair that overlaps enough is an edge of
   open3d's pose graph, and ``global_optimization`` (Levenberg-Marquardt, line-process
   pruning of wrong edges) gives every view's correction; the first view anchors it.
3. ``fuse``: the corrected views merged on a voxel grid; a voxel is kept when at least
   ``min_views`` views saw it (view consistency: a speckle of one frame's noise is not the
   object) or, for surfaces only one view faces, it survives open3d's statistical outlier
   filter; normals are oriented towards the cameras that saw them.
4. ``build_model``: the object frame (origin on the support under the footprint's centre,
   z up, x along the footprint's long axis), size, the dominant colours (scikit-learn's
   k-means in RGB, as few as explain the points), and a closed mesh (open3d's Poisson
   reconstruction over the fused points and a disc of the support under them, trimmed by
   density and to the points' hull) split by nearest dominant colour, one mesh per colour:
   the world format's mesh visuals have one colour each, and the object detector's colour
   test (``ObjectModel.colour_part``) judges each colour on its own.

Everything is a pure function; writing the model into the map (mesh files, the
SmallObject) is worldmodel's (``hearth.worldmodel.learned``) and moving the robot is the mission's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np
import open3d as o3d

from hearth.perception.camera import Intrinsics, depth_to_points
from hearth.perception.errors import PerceptionError


@dataclass(frozen=True)
class LearnConfig:
    """Settings of every stage (metres unless said)."""
    support_window: float = 0.05     #: points this near the surface height the map gives
    plane_distance: float = 0.006    #: RANSAC inlier distance of the support
    min_height: float = 0.006        #: object points start this far above the support
    max_height: float = 0.45
    region_radius: float = 0.18      #: around the believed place of the object
    ring_radius: float = 0.30        #: support points this near are the static ring
    cluster_radius: float = 0.012
    min_points: int = 150            #: fewer object points in a view: the view is not used
    max_range: float = 2.0           #: depth readings beyond this are too noisy to model
    voxel: float = 0.003             #: fused grid
    icp_distances: tuple = (0.02, 0.01, 0.005)   #: coarse to fine, planar ICP gates
    icp_iterations: int = 30
    min_fitness: float = 0.3         #: a pair registered with less overlap is no edge
    #: A pairwise correction moving the object by more than this, or turning it by more than
    #: ``max_turn_deg``, is refused: the views differ by the robot's localisation error (a
    #: few centimetres and a degree or two); a larger "correction" is a box's flat face slid
    #: along itself or a symmetric object turned by ICP.
    max_correction: float = 0.04
    max_turn_deg: float = 3.0
    min_views: int = 2               #: a voxel seen by fewer views is kept only if not an outlier
    poisson_depth: int = 7
    density_quantile: float = 0.04   #: Poisson vertices of the lowest density are cut
    max_colours: int = 3
    colour_tolerance: float = 0.12   #: RGB distance one more colour must explain away
    min_object_size: float = 0.02    #: smaller than this across: too small to model
    face_band: float = 0.01          #: measure_size: a face's points lie this near the outermost
    face_angle: float = 20.0         #: ... and face its way within this (degrees)
    face_normal_radius: float = 0.01  #: ... normals from neighbours this near
    known_margin: float = 0.025      #: around the boxes of objects the map knows


@dataclass
class ObjectView:
    """One view's segmented object. ``points_world`` and ``colors`` (N, 3, RGB in [0, 1])
    are the object's; ``ring_world`` the support around it; ``T_world_camera`` the believed
    camera pose the points were put in the world with."""
    points_world: np.ndarray
    colors: np.ndarray
    ring_world: np.ndarray
    ring_colors: np.ndarray
    T_world_camera: np.ndarray
    support_height: float


@dataclass
class LearnedModel:
    """A learned object. ``T_world_object``: where it stands (origin on the support under the
    footprint's centre, z up); ``points``, ``normals``, ``colors``: the fused surface in the
    object frame; ``size``: (long side, short side, height) of its footprint box (m);
    ``colours``: dominant RGB colours in [0, 1] with the share of the surface each covers,
    largest first; ``meshes``: one (vertices object frame, triangles, RGB) per colour;
    ``views_used`` / ``views_given``; ``notes``: what a person should know (views dropped)."""
    T_world_object: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    size: tuple
    colours: list
    meshes: list
    views_used: int
    views_given: int
    corrections: list = field(default_factory=list)
    notes: list = field(default_factory=list)


# -- 1. segmentation ---------------------------------------------------------------------------

def segment_view(depth: np.ndarray, color: Optional[np.ndarray], K: Intrinsics,
                 T_world_camera: np.ndarray, support_height: float, centre_xy,
                 config: LearnConfig = LearnConfig(),
                 known: Sequence[tuple[np.ndarray, np.ndarray]] = ()) -> Optional[ObjectView]:
    """The object standing near ``centre_xy`` (world, m) on the support the map puts at
    ``support_height`` (world z), as one view shows it; None when the view shows too little
    of it (fewer than ``min_points`` points) or no support. ``known``: world boxes (lo, hi
    corners) of the objects the map already has there: their points are not the new
    object's, even where they touch it."""
    from hearth.perception.objects import euclidean_clusters, ransac_plane
    depth = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(depth) & (depth > 0) & (depth < config.max_range)
    pc = depth_to_points(depth, K, mask=valid)
    if len(pc) == 0:
        return None
    rgb = (np.asarray(color, dtype=np.float64)[valid] / 255.0 if color is not None
           else np.full((len(pc), 3), 0.5))
    T = np.asarray(T_world_camera, dtype=float)
    pw = pc @ T[:3, :3].T + T[:3, 3]
    c = np.asarray(centre_xy, dtype=float)[:2]
    r = np.hypot(pw[:, 0] - c[0], pw[:, 1] - c[1])
    near = (r < config.ring_radius) & (np.abs(pw[:, 2] - support_height) < config.support_window)
    if near.sum() < 50:
        return None
    plane, inl = ransac_plane(pw[near], config.plane_distance, 200, 0)
    if plane is None or plane[2] < math.cos(math.radians(6)):
        return None
    z0 = float(np.median(pw[near][inl, 2]))
    height = pw[:, 2] - z0
    above = (height > config.min_height) & (height < config.max_height) & (r < config.region_radius)
    for lo, hi in known:      # grown by the localisation error and the sensor's edge noise
        lo, hi = np.asarray(lo) - config.known_margin, np.asarray(hi) + config.known_margin
        above &= ~np.all((pw > lo) & (pw < hi), axis=1)
    idx = np.flatnonzero(above)
    if len(idx) < config.min_points:
        return None
    clusters = euclidean_clusters(pw[idx], config.cluster_radius, config.min_points // 3)
    if not clusters:
        return None
    # the cluster nearest the believed place, then every other cluster touching its footprint
    # (a handle seen apart from its mug's body across a gap of missing depth)
    dist = [np.hypot(*(pw[idx[k], :2].mean(axis=0) - c)) for k in clusters]
    main = clusters[int(np.argmin(dist))]
    keep = [main]
    lo, hi = pw[idx[main], :2].min(axis=0) - 0.02, pw[idx[main], :2].max(axis=0) + 0.02
    for k in clusters:
        if k is not main:
            m = pw[idx[k], :2].mean(axis=0)
            if np.all(m > lo) and np.all(m < hi):
                keep.append(k)
    sel = idx[np.concatenate(keep)]
    if len(sel) < config.min_points:
        return None
    ring = np.flatnonzero(near)[inl]
    return ObjectView(pw[sel], rgb[sel], pw[ring], rgb[ring], T, z0)


# -- 2. registration ---------------------------------------------------------------------------

def _cloud(points: np.ndarray, colors: np.ndarray, voxel: float,
           camera: Optional[np.ndarray] = None) -> o3d.geometry.PointCloud:
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pc.colors = o3d.utility.Vector3dVector(np.clip(colors, 0, 1))
    pc = pc.voxel_down_sample(voxel)
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=voxel * 4, max_nn=30))
    if camera is not None:
        pc.orient_normals_towards_camera_location(camera)
    return pc


def _object_cloud(v: ObjectView, voxel: float, centre: np.ndarray) -> o3d.geometry.PointCloud:
    """The view's object points about ``centre`` (a correction's translation is then its
    displacement at the object, not a lever arm from the world's origin), normals towards
    its camera."""
    return _cloud(v.points_world - centre, v.colors, voxel, v.T_world_camera[:3, 3] - centre)


def _pairwise(source: o3d.geometry.PointCloud, target: o3d.geometry.PointCloud,
              config: LearnConfig) -> tuple[np.ndarray, np.ndarray, float]:
    """(T_target_source, 6x6 information in open3d's (rx, ry, rz, tx, ty, tz) order,
    fitness): Hearth's x-y-yaw ICP (hearth.perception.registration.register_planar) between the
    object points of two views. The views differ by the robot's localisation error, which
    is planar (the camera's height, roll and pitch come from the robot's own joints): a
    six-degree ICP, or one that lets the support ring in, slides along the table top, whose
    flat, even-coloured points pin nothing in x, y and yaw. Height, roll and pitch are held
    fixed by a stiff information.

    A body of revolution (a bottle, a cup seen without its handle) leaves the yaw free: the
    ICP finds the shift to a few millimetres but turns by tens of degrees, a correction no
    localisation error makes. Then the pair is registered again with the yaw held (a shift
    only), and the edge holds the yaw stiffly too: the robot's yaw error (a degree or so)
    turns the object about itself by that much, under a millimetre at its rim, while it
    moves it by centimetres about the robot, which the shift takes. The identity with
    fitness 0 when both fail."""
    from hearth.perception.registration import ICPConfig, RegistrationFailed, register_planar
    cfg = ICPConfig(voxel=config.voxel, gates=config.icp_distances, iterations=(12, 10, 8),
                    robust_scale=config.icp_distances[-1] / 2, min_fitness=config.min_fitness,
                    min_points=30, point_weight=0.3)
    P, Q = np.asarray(source.points), np.asarray(target.points)
    res = None
    for turn in (True, False):
        try:
            res = register_planar(P, Q, np.asarray(target.normals), cfg=cfg, turn=turn)
        except (RegistrationFailed, PerceptionError):
            res = None
            continue
        if _plausible(res.T, config):
            break
    if res is None:
        return np.eye(4), np.zeros((6, 6)), 0.0
    c = Q.mean(axis=0)
    radius = float(np.sqrt(np.mean(np.sum((Q[:, :2] - c[:2]) ** 2, axis=1)))) or 0.05
    S = np.diag([1.0, 1.0, radius])
    info3 = S.T @ np.asarray(res.information) @ S * max(len(res.inliers), 1)
    info = np.zeros((6, 6))
    idx = [3, 4, 2]                                    # x, y, yaw in open3d's order
    info[np.ix_(idx, idx)] = info3
    stiff = 1e3 * max(float(np.trace(info3)), 1.0)
    held = (0, 1, 5) if turn else (0, 1, 2, 5)         # roll, pitch, z: known; yaw: held
    for k in held:
        if not turn and k == 2:
            info[2, :], info[:, 2] = 0.0, 0.0
        info[k, k] = stiff
    return res.T, info, float(res.fitness)


def _plausible(T: np.ndarray, config: LearnConfig) -> bool:
    """A correction the robot's localisation error could make (object-centred ``T``)."""
    turn = math.degrees(abs(math.atan2(T[1, 0], T[0, 0])))
    return np.linalg.norm(T[:3, 3]) <= config.max_correction and turn <= config.max_turn_deg


def register_views(views: Sequence[ObjectView],
                   config: LearnConfig = LearnConfig()) -> list[np.ndarray]:
    """Per view, the correction ``C`` (world -> world) that moves its points onto the
    others (``C @ p``); the first view's is the identity. Pairwise planar ICP between
    every two views whose cameras stand within 90 degrees of each other around the object,
    then open3d's pose graph optimisation over those edges (consecutive views as the
    odometry chain, the rest as loop closures that may be pruned)."""
    reg = o3d.pipelines.registration
    n = len(views)
    if n == 0:
        return []
    centre = np.vstack([v.points_world for v in views]).mean(axis=0)
    clouds = [_object_cloud(v, config.voxel, centre) for v in views]
    bearings = [math.atan2(*(v.T_world_camera[[1, 0], 3] - centre[[1, 0]])) for v in views]
    graph = reg.PoseGraph()
    graph.nodes.append(reg.PoseGraphNode(np.eye(4)))
    chain = np.eye(4)     # the world-to-world correction of view i (node pose) so far
    for i in range(1, n):
        T, info, fit = _pairwise(clouds[i], clouds[i - 1], config)
        if fit < config.min_fitness or not _plausible(T, config):
            T, info = np.eye(4), np.eye(6) * 1e-3     # keep the chain, trust it little
        chain = chain @ T
        graph.nodes.append(reg.PoseGraphNode(chain.copy()))
        graph.edges.append(reg.PoseGraphEdge(i, i - 1, T, info, uncertain=False))
    for i in range(n):
        for j in range(i + 2, n):
            if abs(math.remainder(bearings[i] - bearings[j], 2 * math.pi)) > math.pi / 2:
                continue
            T, info, fit = _pairwise(clouds[j], clouds[i], config)
            if fit >= config.min_fitness and _plausible(T, config):
                graph.edges.append(reg.PoseGraphEdge(j, i, T, info, uncertain=True))
    if n > 1:
        option = reg.GlobalOptimizationOption(
            max_correspondence_distance=config.icp_distances[-1],
            edge_prune_threshold=0.25, reference_node=0)
        with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            reg.global_optimization(graph, reg.GlobalOptimizationLevenbergMarquardt(),
                                    reg.GlobalOptimizationConvergenceCriteria(), option)
    to, back = np.eye(4), np.eye(4)
    to[:3, 3], back[:3, 3] = -centre, centre
    return [back @ np.asarray(node.pose) @ to for node in graph.nodes]


# -- 3. fusion ---------------------------------------------------------------------------------

def fuse(views: Sequence[ObjectView], corrections: Sequence[np.ndarray],
         config: LearnConfig = LearnConfig()) -> o3d.geometry.PointCloud:
    """The views' object points, corrected, on one voxel grid with normals towards the
    cameras that saw them; voxels seen by one view only are kept when open3d's statistical
    filter does not call them outliers."""
    pts, cols, nrm, vid = [], [], [], []
    for k, (v, C) in enumerate(zip(views, corrections)):
        p = v.points_world @ C[:3, :3].T + C[:3, 3]
        cam = C[:3, :3] @ v.T_world_camera[:3, 3] + C[:3, 3]
        pc = _cloud(p, v.colors, config.voxel / 2, cam)
        pts.append(np.asarray(pc.points))
        cols.append(np.asarray(pc.colors))
        nrm.append(np.asarray(pc.normals))
        vid.append(np.full(len(pc.points), k))
    P, Cc, N, V = np.vstack(pts), np.vstack(cols), np.vstack(nrm), np.concatenate(vid)
    key = np.floor(P / config.voxel).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    nvox = inv.max() + 1
    seen = np.zeros((nvox, len(views)), bool)
    seen[inv, V] = True
    views_per_voxel = seen.sum(axis=1)
    count = np.bincount(inv, minlength=nvox)[:, None]
    mean = lambda a: np.stack([np.bincount(inv, a[:, j], nvox) for j in range(3)], 1) / count  # noqa: E731
    P, Cc, N = mean(P), mean(Cc), mean(N)
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-9)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
    pc.colors = o3d.utility.Vector3dVector(np.clip(Cc, 0, 1))
    pc.normals = o3d.utility.Vector3dVector(N)
    multi = views_per_voxel >= min(config.min_views, len(views))
    _, inlier = pc.remove_statistical_outlier(nb_neighbors=16, std_ratio=2.0)
    keep = multi.copy()
    keep[np.asarray(inlier, dtype=int)] = True
    return pc.select_by_index(np.flatnonzero(keep).tolist())


# -- 4. the model ------------------------------------------------------------------------------

def dominant_colours(colors: np.ndarray, config: LearnConfig = LearnConfig()
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) RGB centres, largest share first, and each point's centre: k-means with the
    fewest centres (1 .. ``max_colours``) after which one more lowers the mean distance to
    the centres by less than ``colour_tolerance`` / 4."""
    from sklearn.cluster import KMeans
    best = None
    prev = None
    for k in range(1, config.max_colours + 1):
        if len(colors) < 10 * k:
            break
        km = KMeans(n_clusters=k, n_init=4, random_state=0).fit(colors)
        spread = float(np.linalg.norm(colors - km.cluster_centers_[km.labels_], axis=1).mean())
        gap = min((np.linalg.norm(a - b) for i, a in enumerate(km.cluster_centers_)
                   for b in km.cluster_centers_[i + 1:]), default=1.0)
        if prev is not None and (prev - spread < config.colour_tolerance / 4
                                 or gap < config.colour_tolerance):
            break
        best, prev = km, spread
    if best is None:
        return colors.mean(axis=0, keepdims=True), np.zeros(len(colors), int)
    order = np.argsort(-np.bincount(best.labels_, minlength=len(best.cluster_centers_)))
    remap = np.empty_like(order)
    remap[order] = np.arange(len(order))
    return best.cluster_centers_[order], remap[best.labels_]


def object_frame(points_world: np.ndarray, support_height: float) -> np.ndarray:
    """``T_world_object``: origin on the support under the footprint's centre (the middle of
    its minimum-area box), z up, x along the box's long side."""
    import cv2
    xy = points_world[:, :2].astype(np.float32)
    (cx, cy), (w, h), ang = cv2.minAreaRect(xy)
    yaw = math.radians(ang) if w >= h else math.radians(ang + 90)
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = (cx, cy, support_height)
    return T


def measure_size(points: np.ndarray, config: LearnConfig = LearnConfig()) -> tuple:
    """(long side, short side, height) of object-frame points (x along the footprint's
    long side, the support at z = 0): each face of the box from the points that face it.

    Extents of the points themselves overstate the size: the sensor's noise scatters a
    face's points a few millimetres either side of it, and the outermost of them, or even
    the 99.5th percentile (a few mixed pixels at depth edges stand centimetres off), lies
    2-3 mm out on every side (a 92 mm box measured 97.7). The face is where the middle of
    its points lies: the points within ``face_band`` of the outermost (99.5th percentile)
    along a direction, whose normal is within ``face_angle`` of it, their median. On a
    curved side (a bottle) those points lie on the stretch of the curve facing that way,
    under a millimetre inside its extreme. Too few such points: the percentile."""
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=config.face_normal_radius,
                                                              max_nn=60))
    N = np.asarray(pc.normals)
    cos = math.cos(math.radians(config.face_angle))

    def face(d) -> float:
        s = points @ d
        out = float(np.percentile(s, 99.5))
        on = (s > out - config.face_band) & (np.abs(N @ d) > cos)
        return float(np.median(s[on])) if on.sum() >= 10 else out
    e = [face(np.eye(3)[k]) + face(-np.eye(3)[k]) for k in (0, 1)]
    return float(max(e)), float(min(e)), face(np.eye(3)[2])


def poisson_mesh(points: np.ndarray, normals: np.ndarray,
                 config: LearnConfig = LearnConfig()) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, triangles) of a closed surface through object-frame points (z up, the
    support at z = 0): open3d's Poisson reconstruction over the points and a disc of the
    support under their footprint (the base no camera sees), its lowest-density vertices
    cut (Poisson's balloon where no point was), clipped to z >= 0 and to the points' box."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    step = config.voxel
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + step, step), np.arange(lo[1], hi[1] + step, step))
    base = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    # the base under the footprint only: the disc's points near the object's lowest ring
    from scipy.spatial import cKDTree
    low = points[points[:, 2] < 0.02]
    if len(low) > 3:
        from scipy.spatial import ConvexHull, Delaunay
        try:
            hull = Delaunay(low[ConvexHull(low[:, :2]).vertices, :2])
            base = base[hull.find_simplex(base[:, :2]) >= 0]
        except Exception:  # noqa: BLE001 - a degenerate footprint: keep the box's disc
            pass
    P = np.vstack([points, base])
    N = np.vstack([normals, np.tile([0.0, 0.0, -1.0], (len(base), 1))])
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
    pc.normals = o3d.utility.Vector3dVector(N)
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            pc, depth=config.poisson_depth, scale=1.1, linear_fit=True)
    dens = np.asarray(dens)
    if len(dens):
        mesh.remove_vertices_by_mask(dens < np.quantile(dens, config.density_quantile))
    V = np.asarray(mesh.vertices)
    tree = cKDTree(P)
    d, _ = tree.query(V)
    out = (V[:, 2] < -0.002) | (d > 4 * step) | np.any(V[:, :2] < lo[:2] - 2 * step, axis=1) \
        | np.any(V[:, :2] > hi[:2] + 2 * step, axis=1) | (V[:, 2] > hi[2] + 2 * step)
    mesh.remove_vertices_by_mask(out)
    mesh.remove_degenerate_triangles()
    mesh.remove_unreferenced_vertices()
    V = np.asarray(mesh.vertices).copy()
    V[:, 2] = np.maximum(V[:, 2], 0.0)
    return V, np.asarray(mesh.triangles).copy()


def build_model(views: Sequence[ObjectView], config: LearnConfig = LearnConfig(),
                given: Optional[int] = None, reference_rgb=None) -> LearnedModel:
    """The learned model of an object from its segmented views (see the module docstring).
    ``reference_rgb``: the support's colour as the map has it (RGB in [0, 1]): the views'
    colours are corrected by the light's gain measured on the support ring. PerceptionError
    when no view shows it, or it is smaller than ``min_object_size``."""
    views = [v for v in views if v is not None]
    given = len(views) if given is None else given
    if not views:
        raise PerceptionError("no view shows an object standing there")
    corrections = register_views(views, config)
    cloud = fuse(views, corrections, config)
    if len(cloud.points) < config.min_points:
        raise PerceptionError(f"too few points of the object ({len(cloud.points)}) to model it")
    support = float(np.median([v.support_height for v in views]))
    P = np.asarray(cloud.points)
    T = object_frame(P, support)
    Ti = np.linalg.inv(T)
    Po = P @ Ti[:3, :3].T + Ti[:3, 3]
    No = np.asarray(cloud.normals) @ Ti[:3, :3].T
    Co = np.asarray(cloud.colors)
    size = measure_size(Po, config)
    if max(size[0], size[1]) < config.min_object_size or size[2] < config.min_object_size / 2:
        raise PerceptionError(f"the object is too small to model ({100 * max(size[:2]):.1f} cm "
                              f"across, {100 * size[2]:.1f} cm high)")
    if reference_rgb is not None:
        # The support's colour in the map against its colour in the views: the light's gain
        # per channel (a white box under the simulated lamp reads 0.47 grey otherwise).
        ring = np.vstack([v.ring_colors for v in views])
        gain = np.median(ring, axis=0) / np.maximum(np.asarray(reference_rgb, float), 0.05)
        Co = np.clip(Co / np.maximum(gain, 0.05), 0, 1)
    centres, label = dominant_colours(Co, config)
    shares = np.bincount(label, minlength=len(centres)) / len(label)
    V, F = poisson_mesh(Po, No, config)
    meshes = []
    if len(F):
        from scipy.spatial import cKDTree
        _, nearest = cKDTree(Po).query(V[F].mean(axis=1))
        face_colour = label[nearest]
        for k, rgb in enumerate(centres):
            tri = F[face_colour == k]
            if len(tri):
                used, inv = np.unique(tri, return_inverse=True)
                meshes.append((V[used], inv.reshape(-1, 3), tuple(float(x) for x in rgb)))
    notes = []
    if len(views) < given:
        notes.append(f"{given - len(views)} of {given} views did not show the object")
    return LearnedModel(T, Po, No, Co, size,
                        [(tuple(float(x) for x in c), float(s)) for c, s in zip(centres, shares)],
                        meshes, len(views), given, [np.asarray(c) for c in corrections], notes)


def learn_object(frames, support_height: float, centre_xy,
                 config: LearnConfig = LearnConfig(), known=(), reference_rgb=None) -> LearnedModel:
    """``build_model`` over ``frames``: (depth m, colour uint8 RGB or None, Intrinsics,
    believed T_world_camera) of views around the object standing near ``centre_xy`` on the
    support at ``support_height``; ``known`` as ``segment_view``."""
    frames = list(frames)
    views = [segment_view(d, c, K, T, support_height, centre_xy, config, known)
             for d, c, K, T in frames]
    return build_model(views, config, given=len(frames), reference_rgb=reference_rgb)


# -- where to look from, and what colour it is ------------------------------------------------

def find_new_object(depth: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray,
                    T_world_surface: np.ndarray, size_xy, known_xy,
                    min_novelty: float = 0.05) -> tuple[Optional[np.ndarray], str]:
    """Where an object the map does not know stands on a surface in one view: the Euclidean
    cluster of the points 8 mm to 45 cm over the surface (``T_world_surface``: centre of its
    top face, z up; ``size_xy`` its extent) farthest from every known object's world x, y
    (``known_xy``). (world point (x, y, surface z), "") when found; (None, "nothing") when
    nothing stands there; (None, "known") when every cluster is within ``min_novelty`` (m)
    of an object the map has."""
    from hearth.perception.objects import euclidean_clusters
    ok = np.isfinite(depth) & (depth > 0)
    T = np.asarray(T_world_camera, dtype=float)
    pw = depth_to_points(depth, K, mask=ok, stride=2) @ T[:3, :3].T + T[:3, 3]
    Ts = np.asarray(T_world_surface, dtype=float)
    local = (pw - Ts[:3, 3]) @ Ts[:3, :3]
    on = (np.abs(local[:, 0]) < size_xy[0] / 2) & (np.abs(local[:, 1]) < size_xy[1] / 2) \
        & (local[:, 2] > 0.008) & (local[:, 2] < 0.45)
    sel = pw[on]
    clusters = euclidean_clusters(sel, 0.02, 20) if len(sel) else []
    if not clusters:
        return None, "nothing"
    known = [np.asarray(k, dtype=float)[:2] for k in known_xy]

    def novelty(c) -> float:
        m = sel[c, :2].mean(axis=0)
        return min((float(np.hypot(*(k - m))) for k in known), default=math.inf)
    best = max(clusters, key=novelty)
    if novelty(best) < min_novelty:
        return None, "known"
    xy = sel[best, :2].mean(axis=0)
    return np.array([xy[0], xy[1], float(Ts[2, 3])]), ""


def views_around(world, point, room_id: str, radii=(0.6, 0.75, 0.9, 1.1, 1.3),
                 bearings: int = 16, robot_radius: float = 0.30,
                 start_xy=None) -> list[tuple[float, float, float]]:
    """Base poses (x, y, yaw: facing ``point``) around a world ``point``: on each of
    ``bearings`` directions the nearest of ``radii`` that lies in the room (by the robot's
    radius) and clear of the room's furniture footprints by it; ordered by bearing, starting
    with the one nearest ``start_xy`` (where the robot stands) so a tour goes round once."""
    from hearth.perception.nbv import _box_distance, footprints
    from hearth.worldmodel.frames import room_contains
    room = world.get(room_id)
    boxes = footprints(world, room_id)
    c = np.asarray(point, dtype=float)
    out = []
    for k in range(bearings):
        a = 2 * math.pi * k / bearings
        for r in radii:
            x, y = c[0] + r * math.cos(a), c[1] + r * math.sin(a)
            if not room_contains(room, x, y, margin=-robot_radius):
                continue
            if any(_box_distance(np.array([[x, y]]), T, box)[0] <= robot_radius for T, box in boxes):
                continue
            out.append((x, y, math.remainder(a + math.pi, 2 * math.pi)))
            break
    if out and start_xy is not None:
        first = min(range(len(out)), key=lambda i: math.hypot(out[i][0] - start_xy[0],
                                                               out[i][1] - start_xy[1]))
        out = out[first:] + out[:first]
    return out


def spread(poses: Sequence, count: int, centre) -> list:
    """``count`` of ``poses`` spread round ``centre`` (each next the one whose bearing is
    farthest from those chosen), back in their given order."""
    if len(poses) <= count:
        return list(poses)
    c = np.asarray(centre, dtype=float)
    bearing = [math.atan2(p[1] - c[1], p[0] - c[0]) for p in poses]
    chosen = [0]
    while len(chosen) < count:
        far = max((i for i in range(len(poses)) if i not in chosen),
                  key=lambda i: min(abs(math.remainder(bearing[i] - bearing[j], 2 * math.pi))
                                    for j in chosen))
        chosen.append(far)
    return [poses[i] for i in sorted(chosen)]


def colour_name(rgb, palette: dict) -> str:
    """The name in ``palette`` (name -> RGB in [0, 1]) nearest an observed, shaded colour:
    by hue, then saturation and brightness for colours; by brightness for greys (shading
    darkens a colour, so brightness counts least)."""
    import colorsys
    h, s, v = colorsys.rgb_to_hsv(*np.clip(np.asarray(rgb, dtype=float), 0, 1))
    best, bd = "", math.inf
    for name, ref in palette.items():
        rh, rs, rv = colorsys.rgb_to_hsv(*ref)
        if rs < 0.2 or s < 0.2:
            d = 2 * abs(s - rs) + abs(v - rv) + (0 if rs < 0.2 and s < 0.2 else 1)
        else:
            d = 4 * abs(math.remainder(h - rh, 1.0)) + abs(s - rs) + 0.6 * abs(v - rv)
        if d < bd:
            best, bd = name, d
    return best


def hue_name(rgb, palette: dict, min_saturation: float = 0.25) -> str:
    """``colour_name`` for a colour with a hue; "" for a grey, white or black, which differ
    from each other in brightness only, which the light decides as much as the object."""
    import colorsys
    if colorsys.rgb_to_hsv(*np.clip(np.asarray(rgb, dtype=float), 0, 1))[1] < min_saturation:
        return ""
    return colour_name(rgb, palette)
