"""Small-object detection and hypothesis verification on a supporting surface.

Pipeline for one RGB-D view (all points in the world frame, metres):

1. ``find_support_plane``: RANSAC plane (``ransac_plane``, seeded) among the points near the
   height the map expects for a surface (e.g. the kitchen table's ``top``).
2. Points above the plane and inside the surface's extent; Euclidean clusters (connected
   components of a scipy KD-tree radius graph).
3. For each cluster and each candidate model (sampled from the map's small-object models):
   pose by an x/y/yaw search (objects stand upright on a known plane: z, roll and pitch are
   fixed by the plane), refined by planar ICP.
4. Verification of every hypothesis: inlier fraction of the model surface expected to be
   visible (points hidden behind nearer measurements are not counted against it), normal
   agreement, colour agreement in HSV, a penalty for scene points in the hypothesis' volume it
   does not explain and one for points another, stronger hypothesis already claims. Each
   hypothesis carries a ``confidence`` in [0, 1].

Pure functions: arrays and the map in, dataclasses out. See docs/objects.md.
"""
from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np
import open3d as o3d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from hearth.perception.camera import Intrinsics, depth_to_points, project
from hearth.perception.errors import PerceptionError
from hearth.perception.registration import (associate, converged, planar_delta, planar_point_step,
                                     transform)


#: Materials on which Kinect-class sensors often return no depth (see hearth.robot.noise).
DROPOUT_MATERIALS = frozenset({"glass", "dark", "shiny"})


@dataclass(frozen=True)
class DetectionConfig:
    """Parameters of ``detect_objects`` (metres, radians)."""
    stride: int = 2                 #: keep every stride-th pixel row/column
    plane_window: float = 0.05      #: points within this of the expected surface height
    plane_distance: float = 0.008   #: RANSAC inlier distance
    min_height: float = 0.008       #: object points start this far above the plane
    max_height: float = 0.40
    surface_margin: float = 0.03    #: around the surface's extent
    cluster_radius: float = 0.015
    min_cluster_points: int = 15
    sparse_cluster_radius: float = 0.035  #: for the points no dense cluster took
    sparse_min_points: int = 10
    inlier_distance: float = 0.010
    icp_iterations: int = 12
    yaw_steps: int = 8              #: initial yaws for models that are not rotationally symmetric
    occlusion_margin: float = 0.02  #: a model point is hidden when measured this much nearer
    #: A model point whose surface the ray meets at more than this angle from its normal,
    #: with no return at its pixel, does not speak against the hypothesis (as on glass): a
    #: Kinect-class sensor drops most returns at grazing incidence (beyond 75-85 degrees;
    #: hearth.robot.noise). A book standing in an open drawer, seen from above along its
    #: covers, lost half its expected points that way and was refused at the right pose
    #: (0.42). A return elsewhere along the ray still counts against it (``hidden``).
    grazing_deg: float = 80.0
    accept_confidence: float = 0.45  #: ``Detection.accepted`` threshold
    #: ``Detection.accepted`` also needs this share of the model's facing surface in sight
    #: (not hidden behind nearer measurements) when the supporting furniture is what hides
    #: most of the rest: the few points of a model mostly hidden behind a cupboard's side can
    #: be that side's own edge, unexplained by its model when the believed camera is a few
    #: centimetres off, in a colour that agrees (a blue bottle "found" at 0.46 confidence on a
    #: slate-blue cupboard, 12 % of it in sight). A model hidden by something else (an object
    #: the map does not know) is accepted as before.
    min_visible_fraction: float = 0.25
    furniture_hiding_distance: float = 0.04  #: a hiding point this near the furniture is its own
    model_spacing: float = 0.005    #: model surface sample spacing
    furniture_distance: float = 0.012  #: points this near the supporting furniture's model are its own
    #: A model's colours one by one (``ObjectModel.colour_part``): a colour with at least
    #: ``min_part_points`` inliers of which under ``part_agreement`` agree scales the
    #: confidence down in proportion (a grey tin taken for a glass jar whose red lid it lacks:
    #: 82 % of the inliers agree, none of the lid's).
    min_part_points: int = 8
    part_agreement: float = 0.5
    #: Scene points over the model's outline seen from above (within ``taller_outline``, and
    #: ``taller_depth`` inside its edge) standing more than ``taller_margin`` over its top:
    #: a share of ``max_taller`` of them takes the confidence to 0 (an amber tin 2 cm taller
    #: than the amber cup taken for it; on 463 objects found right, none).
    taller_margin: float = 0.015
    taller_outline: float = 0.005
    taller_depth: float = 0.02      #: ... and this far inside the outline's edge
    max_taller: float = 0.10
    #: Hypotheses of two of the map's objects on the same points whose confidences lie within
    #: ``prior_tie``: the one the map puts within ``prior_radius`` (m) claims them first
    #: (``_resolve``; a navy and a blue cup differ in brightness only, which the colour test
    #: leaves out: shading changes it).
    prior_tie: float = 0.05
    prior_radius: float = 1.0


# -- models -----------------------------------------------------------------------------------

@dataclass
class ObjectModel:
    """A small object's model surface in its own frame (z up, origin on its base)."""
    object_id: str
    points: np.ndarray      #: (N, 3) object frame
    normals: np.ndarray     #: (N, 3) outward unit normals
    hsv: np.ndarray         #: (N, 3) in [0, 1]
    radius: float           #: xy extent from the origin
    height: float
    symmetric: bool         #: rotationally symmetric about z (yaw unobservable)
    tree: cKDTree = field(repr=False, default=None)
    #: (N,) points on glass, dark or shiny visuals: a depth sensor often returns nothing there
    dropout: Optional[np.ndarray] = field(repr=False, default=None)
    #: (N,) which colour of the model each point has (0, 1, ...: its visuals' colours, one
    #: index per distinct colour: a cup's body and handle share one, a jar's lid has its own)
    colour_part: Optional[np.ndarray] = field(repr=False, default=None)

    def __post_init__(self):
        if self.tree is None:
            self.tree = cKDTree(self.points)
        if self.dropout is None:
            self.dropout = np.zeros(len(self.points), bool)
        if self.colour_part is None:
            self.colour_part = np.unique(np.round(self.hsv, 3), axis=0,
                                         return_inverse=True)[1].reshape(-1)


def model_from_world(world, object_id: str, spacing: float = 0.005) -> ObjectModel:
    """Sample a small object's model (from ``hearth.worldmodel.geometry``) into coloured surface
    points with normals, dropping its base (it stands on a surface and is never seen)."""
    from hearth.worldmodel.geometry import small_object_meshes
    obj = world.get(object_id)
    meshes = small_object_meshes(world, obj, T_world_object=np.eye(4))
    if not meshes:
        raise PerceptionError(f"{object_id} has no model")
    pts, nrm, col, lossy = [], [], [], []
    o3d.utility.random.seed(0)  # the same model samples every time
    for lm in meshes:
        m = lm.mesh
        m.compute_triangle_normals()
        area = m.get_surface_area()
        n = max(int(area / spacing ** 2), 30)
        pc = m.sample_points_uniformly(number_of_points=n, use_triangle_normal=True)
        p = np.asarray(pc.points)
        pts.append(p)
        nrm.append(np.asarray(pc.normals))
        col.append(np.tile(colorsys.rgb_to_hsv(*lm.color), (len(p), 1)))
        lossy.append(np.full(len(p), lm.material in DROPOUT_MATERIALS))
    P, N, C, L = np.vstack(pts), np.vstack(nrm), np.vstack(col), np.concatenate(lossy)
    keep = ~((P[:, 2] < 0.003) & (N[:, 2] < -0.9))
    P, N, C, L = P[keep], N[keep], C[keep], L[keep]
    # Points of one visual that lie inside another (a handle's end in the body) are not surface.
    P, N, C, L = _drop_inner(meshes, P, N, C, L)
    radius = float(np.linalg.norm(P[:, :2], axis=1).max())
    height = float(P[:, 2].max())
    model = ObjectModel(object_id, P, N, C, radius, height, symmetric=False, dropout=L)
    model.symmetric = _is_symmetric(model)
    return model


def _drop_inner(meshes, P, N, C, L):
    if len(meshes) < 2:
        return P, N, C, L
    scene = o3d.t.geometry.RaycastingScene()
    for lm in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
    occ = scene.compute_occupancy(o3d.core.Tensor((P - 0.0015 * N).astype(np.float32))).numpy()
    inside = occ > 0.5
    # compute_occupancy counts a point inside its own closed visual too; shifting it along its
    # outward normal by 1.5 mm and asking again separates "inside another visual".
    occ2 = scene.compute_occupancy(o3d.core.Tensor((P + 0.0015 * N).astype(np.float32))).numpy()
    keep = ~(inside & (occ2 > 0.5))
    return P[keep], N[keep], C[keep], L[keep]


def _is_symmetric(model: ObjectModel) -> bool:
    for a in (math.pi / 4, math.pi / 3):
        R = _rot_z(a)
        d, _ = model.tree.query(model.points @ R.T)
        if np.percentile(d, 95) > 0.006:
            return False
    return True


def model_library(world, object_ids: Optional[Sequence[str]] = None,
                  spacing: float = 0.005) -> dict[str, ObjectModel]:
    """Models of the given small objects (default: every small object in the map)."""
    ids = object_ids if object_ids is not None else [o.id for o in world.small_objects()]
    return {oid: _cached_model(world, oid, spacing) for oid in ids}


_MODEL_CACHE: dict = {}


def _cached_model(world, oid: str, spacing: float) -> ObjectModel:
    obj = world.get(oid)
    key = (oid, repr(obj.model), spacing)
    m = _MODEL_CACHE.get(key)
    if m is None:
        if len(_MODEL_CACHE) > 256:
            _MODEL_CACHE.clear()
        m = _MODEL_CACHE[key] = model_from_world(world, oid, spacing)
    return m


# -- results ------------------------------------------------------------------------------------

@dataclass
class Hypothesis:
    """One object hypothesis. ``T_world_object`` places the model; scores are in [0, 1]."""
    object_id: str
    T_world_object: np.ndarray
    confidence: float
    inlier_fraction: float
    normal_agreement: float
    color_agreement: float
    unexplained: float         #: fraction of scene points in its volume it does not explain
    conflict: float            #: fraction of its inliers a stronger hypothesis claims
    visible_fraction: float    #: expected model surface not hidden by nearer measurements
    cluster: int
    inliers: np.ndarray = field(repr=False, default=None)  #: indices into Detection.points_world
    #: of the model surface hidden by nearer measurements, the share hidden by the supporting
    #: furniture itself (measured only for hypotheses the visibility gate would refuse)
    hidden_by_furniture: float = 0.0
    #: the colour agreement of the model's worst-agreeing colour (``ObjectModel.colour_part``)
    #: among those with ``DetectionConfig.min_part_points`` inliers or more (1 with none)
    worst_part_color: float = 1.0
    #: share of the scene points over its outline seen from above, ``taller_depth`` or more
    #: inside its edge, standing over its top by more than ``DetectionConfig.taller_margin``
    #: (a taller object is not this one)
    taller: float = 0.0

    def mostly_hidden_by_furniture(self, min_visible_fraction: float) -> bool:
        """Whether less than ``min_visible_fraction`` of the model is in sight and the
        supporting furniture hides most of the rest (``DetectionConfig.min_visible_fraction``):
        such a hypothesis is not accepted, nor verified."""
        return self.visible_fraction < min_visible_fraction and self.hidden_by_furniture >= 0.5

    @property
    def position(self) -> np.ndarray:
        return self.T_world_object[:3, 3].copy()

    @property
    def yaw(self) -> float:
        return math.atan2(self.T_world_object[1, 0], self.T_world_object[0, 0])


@dataclass
class Detection:
    """Everything ``detect_objects`` found in one view."""
    plane: Optional[np.ndarray]            #: (a, b, c, d), a x + b y + c z + d = 0, world frame
    surface: Optional[str]                 #: "large_object/surface" it belongs to
    points_world: np.ndarray               #: the points above the plane
    colors_hsv: np.ndarray
    clusters: list[np.ndarray]             #: indices into points_world
    hypotheses: list[Hypothesis]           #: best first
    accept_confidence: float = 0.5
    min_visible_fraction: float = 0.0

    @property
    def accepted(self) -> list[Hypothesis]:
        """Hypotheses at or above the acceptance confidence that no stronger one contradicts
        and that are not mostly hidden by the furniture they stand on
        (``DetectionConfig.min_visible_fraction``)."""
        return [h for h in self.hypotheses if h.confidence >= self.accept_confidence
                and not h.mostly_hidden_by_furniture(self.min_visible_fraction)
                and h.conflict < 0.5]

    def best(self, object_id: str) -> Optional[Hypothesis]:
        hs = [h for h in self.hypotheses if h.object_id == object_id]
        return hs[0] if hs else None


# -- the pipeline -------------------------------------------------------------------------------

#: Below this sine of the angle between a view ray and a surface, the surface is seen edge-on
#: (about 12 degrees): the simulated and real Kinect-class sensors return no depth there.
GRAZING_SIN = 0.2


def expected_surfaces(world, T_world_camera: np.ndarray, K: Intrinsics,
                      depth: Optional[np.ndarray] = None, max_range: float = 4.0
                      ) -> list[tuple[str, np.ndarray, float, float]]:
    """Surfaces of the map's large objects of which some part is in view:
    (``object/surface``, ``T_world_surface``, size_x, size_y): first the one the camera aims at
    (the median depth of the central pixels lies on or above it), then the most seen near the
    image centre. With
    ``depth``, a surface point counts as seen only where the measured depth agrees with it
    (a shelf behind a cupboard door projects into the image but is not seen)."""
    out = []
    T_cw = np.linalg.inv(T_world_camera)
    aim = None  # what the camera looks at: the median depth of the central pixels
    if depth is not None:
        h, w = np.asarray(depth).shape
        win = np.asarray(depth)[h // 2 - 20:h // 2 + 20, w // 2 - 20:w // 2 + 20]
        win = win[np.isfinite(win) & (win > 0)]
        if win.size:
            aim = T_world_camera[:3, :3] @ np.array([0.0, 0.0, float(np.median(win))]) \
                + T_world_camera[:3, 3]
    g = np.linspace(-0.45, 0.45, 7)
    gx, gy = np.meshgrid(g, g)
    for obj in world.large_objects():
        # its own surfaces and its parts' (a drawer's floor, where the drawer is now)
        for s in world.surfaces_of(obj.id):
            T = s.T_world_surface
            local = np.c_[gx.ravel() * s.size_x, gy.ravel() * s.size_y, np.zeros(gx.size)]
            pw = local @ T[:3, :3].T + T[:3, 3]
            pc = pw @ T_cw[:3, :3].T + T_cw[:3, 3]
            uv, front = project(pc, K)
            seen = front & (uv[:, 0] >= 0) & (uv[:, 0] < K.width - 0.5) & (uv[:, 1] >= 0) & \
                (uv[:, 1] < K.height - 0.5) & (pc[:, 2] < max_range)
            if depth is not None and seen.any():
                px = np.round(uv[seen]).astype(int)
                measured = np.asarray(depth)[px[:, 1], px[:, 0]]
                agree = np.abs(measured - pc[seen, 2]) < 0.03
                # A surface seen nearly edge-on (a shelf at eye level) gives no depth at all:
                # a depth sensor drops grazing returns. No reading there is no disagreement.
                ray = pw[seen] - T_world_camera[:3, 3]
                sin_inc = np.abs(ray @ T[:3, 2]) / np.maximum(np.linalg.norm(ray, axis=1), 1e-9)
                grazing = ~(np.isfinite(measured) & (measured > 0)) & (sin_inc < GRAZING_SIN)
                seen[np.flatnonzero(seen)] = agree | grazing
            if seen.any():
                # The camera looks at what matters: seen points near the image centre count most.
                r = np.hypot(uv[seen, 0] - K.cx, uv[seen, 1] - K.cy) / (0.4 * K.width)
                aimed = False
                if aim is not None:
                    a = T[:3, :3].T @ (aim - T[:3, 3])
                    aimed = abs(a[0]) < s.size_x / 2 + 0.1 and abs(a[1]) < s.size_y / 2 + 0.1 \
                        and -0.05 < a[2] < 0.5
                out.append((f"{obj.id}/{s.surface}", T, s.size_x, s.size_y,
                            (not aimed, -float(np.exp(-r ** 2).sum()))))
    out.sort(key=lambda t: t[4])
    return [t[:4] for t in out]


def find_support_plane(points_world: np.ndarray, expected_height: float,
                       config: DetectionConfig = DetectionConfig(),
                       rng_seed: int = 0) -> Optional[np.ndarray]:
    """RANSAC plane (a, b, c, d), normal up, among points within ``plane_window`` of the
    expected height; None when too few points or the plane is not horizontal."""
    near = points_world[np.abs(points_world[:, 2] - expected_height) < config.plane_window]
    if len(near) < 50:
        return None
    if len(near) > 4000:  # RANSAC needs far fewer points than a view has
        near = near[np.random.default_rng(rng_seed).choice(len(near), 4000, replace=False)]
    plane, inl = ransac_plane(near, config.plane_distance, 200, rng_seed)
    if plane is None:
        return None
    # Supporting surfaces are horizontal and the camera's tilt is known, so a plane tilted by
    # more than a few degrees is not the surface but a mix of what lies near its height (a
    # shelf's front edge, a cabinet's back wall): no plane then, the map's height is used.
    if plane[2] < math.cos(math.radians(4)) or len(inl) < 30:
        return None
    # The height: the median of the inliers (RANSAC's plane is from three points).
    z = near[inl, 2]
    return np.array([0.0, 0.0, 1.0, -float(np.median(z))])


def ransac_plane(points: np.ndarray, distance: float, trials: int,
                 rng_seed: int = 0) -> tuple[Optional[np.ndarray], np.ndarray]:
    """RANSAC plane (a, b, c, d) with a unit normal, c >= 0, and the indices of its inliers
    (points within ``distance``), from ``trials`` planes through three points drawn with
    ``rng_seed``; (None, []) when every draw is degenerate. The same points and seed give the
    same plane on every run.

    Written here rather than calling open3d's ``segment_plane``: that runs its trials on
    threads and, for the same points and seed, returns planes that differ from run to run
    (a different inlier set, so a support height 0.1 mm off, and a detection that flips
    near a threshold: the next-best-view benchmark moved by 0.07 between identical runs).
    scikit-learn's RANSACRegressor is deterministic but fits one trial at a time; all
    trials here are scored at once with one matrix product."""
    n = len(points)
    if n < 3:
        return None, np.zeros(0, dtype=int)
    rng = np.random.default_rng(rng_seed)
    idx = np.stack([rng.choice(n, 3, replace=False) for _ in range(trials)])
    p0, p1, p2 = points[idx[:, 0]], points[idx[:, 1]], points[idx[:, 2]]
    normals = np.cross(p1 - p0, p2 - p0)
    norm = np.linalg.norm(normals, axis=1)
    ok = norm > 1e-12
    if not ok.any():
        return None, np.zeros(0, dtype=int)
    normals = normals[ok] / norm[ok, None]
    d = -np.einsum("ij,ij->i", normals, p0[ok])
    counts = (np.abs(points @ normals.T + d) <= distance).sum(axis=0)
    best = int(np.argmax(counts))                # the first of equals: deterministic
    plane = np.append(normals[best], d[best])
    if plane[2] < 0:
        plane = -plane
    inliers = np.flatnonzero(np.abs(points @ plane[:3] + plane[3]) <= distance)
    return plane, inliers


def euclidean_clusters(points: np.ndarray, radius: float, min_points: int) -> list[np.ndarray]:
    """Connected components of the radius graph (scipy; faster here than open3d's DBSCAN,
    which would also label core/border points we do not need)."""
    if len(points) == 0:
        return []
    tree = cKDTree(points)
    pairs = tree.query_pairs(radius, output_type="ndarray")
    n = len(points)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    out = [np.flatnonzero(labels == k) for k in np.unique(labels)]
    out = [c for c in out if len(c) >= min_points]
    out.sort(key=len, reverse=True)
    return out


def rgb_to_hsv(rgb: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 or [0, 1] RGB -> HSV in [0, 1] (OpenCV's ranges rescaled)."""
    import cv2
    a = np.asarray(rgb)
    if a.size == 0:
        return np.zeros((0, 3))
    if a.dtype != np.uint8:
        a = np.clip(a * 255.0, 0, 255).astype(np.uint8)
    hsv = cv2.cvtColor(a.reshape(-1, 1, 3), cv2.COLOR_RGB2HSV_FULL).reshape(-1, 3)
    return hsv.astype(np.float64) / 255.0


def color_agreement(hsv_a: np.ndarray, hsv_b: np.ndarray, sat: float = 0.25,
                    hue_tol: float = 25 / 360) -> np.ndarray:
    """Per pair: 1 where two HSV colours agree (both saturated with hues within ``hue_tol``,
    or both unsaturated), else 0. Value is ignored: shading changes it, not the hue."""
    sa, sb = hsv_a[:, 1] > sat, hsv_b[:, 1] > sat
    dh = np.abs(hsv_a[:, 0] - hsv_b[:, 0])
    dh = np.minimum(dh, 1 - dh)
    return np.where(sa & sb, dh < hue_tol, ~sa & ~sb).astype(float)


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _planar_T(x, y, z, yaw) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = _rot_z(yaw)
    T[:3, 3] = (x, y, z)
    return T


def planar_icp(scene_xyz: np.ndarray, model: ObjectModel, x: float, y: float, yaw: float,
               z: float, view_dir_xy: np.ndarray, iterations: int = 12,
               max_dist: float = 0.03, final_dist: float = 0.008):
    """Fit x, y, yaw of an upright model to scene points (world frame) on a plane at height
    ``z``: the plane fixes z, roll and pitch, so this is registration.py's ICP skeleton
    (associate, solve, converged) with point-to-point residuals in x, y and yaw (x and y only
    for a rotationally symmetric model), whose step has a closed form (``planar_point_step``),
    the gate shrinking from ``max_dist`` to ``final_dist`` over the iterations. Scene points
    are associated with the model points whose normals face the camera (``view_dir_xy``:
    horizontal direction from the camera to the object). Returns (x, y, yaw, rmse,
    n_inliers)."""
    rmse, n_in = np.inf, 0
    for gate in np.geomspace(max_dist, final_dist, iterations):
        R = _rot_z(yaw)
        mp, tree = _front_tree(model, R[:2, :2].T @ view_dir_xy)
        local = (scene_xyz - np.array([x, y, z])) @ R  # world -> object frame (R^T p)
        i_s, i_m, d = associate(tree, local, gate)
        n_in = len(i_s)
        if n_in < 6:
            return x, y, yaw, np.inf, 0
        rmse = float(np.sqrt(np.mean(d ** 2)))
        # the matched model points in the world, moved onto their scene points
        step, c = planar_point_step((mp[i_m] @ R.T)[:, :2] + (x, y), scene_xyz[i_s],
                                    turn=not model.symmetric)
        o = planar_delta(step, c) @ np.array([x, y, 0.0, 1.0])
        moved = math.hypot(o[0] - x, o[1] - y)
        x, y, yaw = float(o[0]), float(o[1]), yaw + float(step[2])
        # converged: the origin moved under 0.2 mm and the model turned under 0.11 degrees
        if converged([moved, step[2]], (2e-4, 2e-3)) and gate < 2 * final_dist:
            break
    return x, y, yaw, rmse, n_in


_VIEW_BINS = 16


def _front_tree(model: ObjectModel, view_dir_model_xy: np.ndarray):
    """Model points whose normals face a camera looking along ``view_dir_model_xy`` (object
    frame, horizontal) and their KD-tree, cached per 1/16 turn of viewing direction."""
    b = int(round(math.atan2(view_dir_model_xy[1], view_dir_model_xy[0])
                  / (2 * math.pi / _VIEW_BINS))) % _VIEW_BINS
    cache = model.__dict__.setdefault("_front", {})
    hit = cache.get(b)
    if hit is None:
        a = b * 2 * math.pi / _VIEW_BINS
        front = model.normals[:, :2] @ np.array([math.cos(a), math.sin(a)]) < 0.1
        if front.sum() < 10:
            front[:] = True
        mp = model.points[front]
        hit = cache[b] = (mp, cKDTree(mp))
    return hit


def detect_objects(world, depth: np.ndarray, color: Optional[np.ndarray], K: Intrinsics,
                   T_world_camera: np.ndarray, candidates: Optional[Sequence[str]] = None,
                   surface: Optional[str] = None,
                   config: DetectionConfig = DetectionConfig()) -> Detection:
    """Detect and verify the map's small objects on the surface in view.

    ``depth`` metres (0 = none), ``color`` uint8 RGB (None: colour agreement is not used),
    ``T_world_camera`` the (believed) camera pose. ``candidates``: small-object ids whose
    models to try (default: every small object in the map). ``surface``: "object/surface"
    (default: the nearest surface in view). Raises PerceptionError when no surface is in view.
    """
    T_world_camera = np.asarray(T_world_camera, dtype=float)
    surfaces = expected_surfaces(world, T_world_camera, K, depth)
    if surface is not None:
        surfaces = [s for s in surfaces if s[0] == surface] or [
            _surface_by_name(world, surface)]
    if not surfaces:
        raise PerceptionError("no supporting surface of the map in view")
    name, T_ws, sx, sy = surfaces[0]

    d = np.asarray(depth, dtype=np.float64)
    s = config.stride
    pts_c = depth_to_points(d, K, stride=s)
    ok = np.isfinite(d[::s, ::s]) & (d[::s, ::s] > 0)
    P = pts_c @ T_world_camera[:3, :3].T + T_world_camera[:3, 3]
    if color is not None:
        hsv_all = rgb_to_hsv(np.asarray(color)[::s, ::s][ok])
    else:
        hsv_all = np.zeros((len(P), 3))

    # Position in the surface's frame (its extent). The plane is sought among the points
    # over the surface only: beside an open drawer, another horizontal face 2 cm under the
    # drawer's floor held more points within the window than the floor itself (a book at
    # the back of the drawer was then fitted 2 cm low and refused as "taller" than its
    # model). With too few points over the surface, the whole view's.
    local = (P - T_ws[:3, 3]) @ T_ws[:3, :3]
    inside = (np.abs(local[:, 0]) < sx / 2 + config.surface_margin) & \
             (np.abs(local[:, 1]) < sy / 2 + config.surface_margin)
    plane = None
    # A surface at or above the camera shows its underside, not its top: a plane found near
    # its height there is the board's lower face, a board's thickness too low (a shelf at
    # 1.39 m seen by a 1.31 m head: 1.4 cm). The map's height is used then.
    if T_ws[2, 3] < T_world_camera[2, 3] - config.plane_window / 2:
        plane = find_support_plane(P[inside], T_ws[2, 3], config)
        if plane is None:           # too little of it in view: the plane of the whole view
            plane = find_support_plane(P, T_ws[2, 3], config)
    height0 = -plane[3] if plane is not None else T_ws[2, 3]
    # Height above the plane.
    h = P @ plane[:3] + plane[3] if plane is not None else P[:, 2] - height0
    # On a shelf, what stands on the shelf above is not on this one: the column ends below it.
    top = min(config.max_height, _headroom(world, name, T_ws, sx, sy) - config.min_height)
    above = inside & (h > config.min_height) & (h < top)
    if above.any():
        # What the map's furniture explains is not a small object: a shelf's back and sides,
        # the shelf above, a cupboard's walls.
        above[np.flatnonzero(above)] = ~_explained_by_furniture(
            world, name.split("/")[0], P[above], config.furniture_distance)
    pts, hsv = P[above], hsv_all[above]
    clusters = euclidean_clusters(pts, config.cluster_radius, config.min_cluster_points)
    # Glass and dark objects return few, scattered points: what is left over is grouped once
    # more at a coarser radius (a few points of a jar 2 cm apart are one object).
    left = np.setdiff1d(np.arange(len(pts)), np.concatenate(clusters)) if clusters \
        else np.arange(len(pts))
    if len(left) >= config.sparse_min_points:
        clusters += [left[c] for c in euclidean_clusters(pts[left], config.sparse_cluster_radius,
                                                         config.sparse_min_points)]

    models = model_library(world, candidates, config.model_spacing)
    cam = T_world_camera[:3, 3]
    hyps: list[Hypothesis] = []
    normals = _normals(pts, clusters)
    T_cw = np.linalg.inv(T_world_camera)
    tree_xy = cKDTree(pts[:, :2]) if len(pts) else None
    tree_xyz = cKDTree(pts) if len(pts) else None
    for ci, idx in enumerate(clusters):
        cp = pts[idx]
        for model in models.values():
            for seeds in _initial_poses(cp, hsv[idx] if color is not None else None, model,
                                        cam, config):
                x, y = seeds[0][:2]
                vd = np.array([x, y]) - cam[:2]
                vd /= max(np.linalg.norm(vd), 1e-9)
                # Fit to the points near the seed, from any cluster: a cluster may hold touching
                # objects, and an occluder may split one object into several clusters.
                near = np.asarray(tree_xy.query_ball_point((x, y), model.radius + 0.03), int)
                if len(near) < 6:
                    continue
                npts = pts[near]
                # Coarse to fine: a few ICP steps from every yaw, then finish the best two.
                coarse = [planar_icp(npts, model, x, y, a, height0, vd, 4, 0.03, 0.012)
                          for (x, y, a) in seeds]
                coarse.sort(key=lambda r: (-r[4], r[3]))
                for (x0, y0, a0, _, n0) in coarse[:2]:
                    if n0 < 6:
                        continue
                    x1, y1, yaw1, rmse, n_in = planar_icp(npts, model, x0, y0, a0, height0,
                                                          vd, config.icp_iterations, 0.015)
                    if n_in < 6:
                        continue
                    T = _planar_T(x1, y1, height0, yaw1)
                    hyps.append(_verify(model, T, ci, pts, hsv, normals, tree_xy, tree_xyz, d,
                                        K, T_cw, color is not None, config))
    believed = {oid: world.T_world(oid)[:2, 3] for oid in models if oid in world}
    hyps = _resolve(hyps, believed, config)
    for h in hyps:
        if h.confidence >= config.accept_confidence and h.visible_fraction < config.min_visible_fraction:
            h.hidden_by_furniture = _hidden_by_furniture(world, name.split("/")[0],
                                                         models[h.object_id], h.T_world_object,
                                                         d, K, T_cw, config)
    return Detection(plane, name, pts, hsv, clusters, hyps, config.accept_confidence,
                     config.min_visible_fraction)


def _model_in_view(model: ObjectModel, T: np.ndarray, depth, K, T_cw, config: DetectionConfig):
    """The model at ``T`` seen by the camera: its points and normals in the world, its
    points in the camera frame, their pixels (u, v), the depth measured there (0 outside the
    image), and which facing points are expected and which of those are hidden by a
    measurement nearer than ``occlusion_margin``."""
    R = T[:3, :3]
    mp_w = model.points @ R.T + T[:3, 3]
    mn_w = model.normals @ R.T
    pc = mp_w @ T_cw[:3, :3].T + T_cw[:3, 3]
    nc = mn_w @ T_cw[:3, :3].T
    facing = np.einsum("ij,ij->i", nc, pc) < 0
    uv, front = project(pc, K)
    u = np.round(uv[:, 0]).astype(int)
    v = np.round(uv[:, 1]).astype(int)
    inimg = front & (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
    measured = np.zeros(len(pc))
    measured[inimg] = depth[v[inimg], u[inimg]]
    expected = facing & inimg
    hidden = expected & (measured > 0) & (measured < pc[:, 2] - config.occlusion_margin)
    return mp_w, mn_w, pc, u, v, measured, expected, hidden


def _hidden_by_furniture(world, furniture: str, model: ObjectModel, T: np.ndarray, depth, K,
                         T_cw, config: DetectionConfig) -> float:
    """Of the model's facing surface hidden by nearer measurements, the share whose hiding
    measurement lies on the furniture's own model (within ``furniture_hiding_distance``)."""
    _, _, _, u, v, measured, _, hidden = _model_in_view(model, T, depth, K, T_cw, config)
    if not hidden.any():
        return 0.0
    z = measured[hidden]
    p_cam = np.stack([(u[hidden] - K.cx) / K.fx * z, (v[hidden] - K.cy) / K.fy * z, z], axis=1)
    p_world = transform(np.linalg.inv(T_cw), p_cam)
    return float(_explained_by_furniture(world, furniture, p_world,
                                         config.furniture_hiding_distance).mean())


def _headroom(world, surface: str, T_ws: np.ndarray, sx: float, sy: float) -> float:
    """Metres from a surface up to the next surface of the same furniture above it that
    overlaps it (a shelf's underside is a few cm lower still, but the furniture's own points
    are removed anyway); infinity when none."""
    oid, sid = surface.split("/", 1)
    node = world.get(oid) if oid in world else None
    best = math.inf
    for s in (world.surfaces_of(oid) if node is not None else ()):
        if s.surface == sid:
            continue
        T = s.T_world_surface
        dz = T[2, 3] - T_ws[2, 3]
        c = np.linalg.inv(T_ws) @ T[:, 3]
        if dz > 0.02 and abs(c[0]) < (sx + s.size_x) / 2 and abs(c[1]) < (sy + s.size_y) / 2:
            best = min(best, float(dz))
    return best


def _explained_by_furniture(world, object_id: str, points_world: np.ndarray,
                            distance: float) -> np.ndarray:
    """Which points lie within ``distance`` of the large object's own model (its parts in
    their believed states; not the small objects it holds)."""
    from hearth.worldmodel.geometry import distance_to_object
    return distance_to_object(world, object_id, points_world) < distance


def _surface_by_name(world, surface: str):
    oid, sid = surface.split("/")
    for s in world.surfaces_of(oid):
        if s.surface == sid:
            return (surface, s.T_world_surface, s.size_x, s.size_y)
    raise PerceptionError(f"no surface {surface!r} in the map")


def _normals(pts: np.ndarray, clusters: list[np.ndarray]) -> np.ndarray:
    """Normals per cluster from the 16 nearest points within 4 cm: on a dense surface the 16
    nearest lie within a centimetre, so the radius only matters where points are sparse (a
    glass jar returns about one pixel in ten), where a 2 cm radius left 3-5 neighbours and
    normals too noisy to agree with the model's."""
    out = np.zeros_like(pts)
    for idx in clusters:
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts[idx]))
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=0.04, max_nn=16))
        out[idx] = np.asarray(pc.normals)
    return out


def _initial_poses(cp: np.ndarray, hsv: np.ndarray, model: ObjectModel, cam: np.ndarray,
                   config: DetectionConfig):
    """Seeds (x, y, yaw) for a model in a cluster: one per model-sized piece of the cluster
    (k-means centres), moved half a radius away from the camera (only the near side is seen);
    several yaws unless the model is symmetric (one list of seeds per piece). Pieces whose
    colours mostly disagree with the model's (``_gate_colours``) are skipped (a cheap gate
    before any ICP)."""
    xy = cp[:, :2]
    extent = np.ptp(xy, axis=0).max() if len(xy) > 1 else 0.0
    k = max(1, int(math.ceil(extent / (2 * model.radius + 0.01))))
    if k == 1:
        centres = [xy.mean(0)]
        groups = [np.arange(len(xy))]
    else:
        from scipy.cluster.vq import kmeans2
        centres, lab = kmeans2(xy, min(k, len(xy)), seed=0, minit="++")
        groups = [np.flatnonzero(lab == i) for i in range(len(centres))]
    colours = _gate_colours(model)
    out = []
    for c, g in zip(centres, groups):
        if len(g) < 6:
            continue
        if hsv is not None and max(color_agreement(hsv[g], np.tile(m, (len(g), 1))).mean()
                                   for m in colours) < 0.25:
            continue
        v = c - cam[:2]
        v /= max(np.linalg.norm(v), 1e-9)
        x, y = c + v * model.radius * 0.5
        yaws = [0.0] if model.symmetric else list(np.arange(config.yaw_steps) * 2 * math.pi
                                                  / config.yaw_steps)
        out.append([(float(x), float(y), float(a)) for a in yaws])
        if not model.symmetric and model.height < model.radius and len(g) >= 10:
            import cv2
            rect = cv2.minAreaRect(np.asarray(xy[g], np.float32))
            out.append(_rectangle_seeds(rect, model) + _edge_seeds(rect, model, cam))
    return out


def _gate_colours(model: ObjectModel) -> list[np.ndarray]:
    """The colours a piece of the model is expected to show (cached): the median colour of
    the parts a depth sensor returns, and that of its glass, dark or shiny parts, apart. A
    glass jar's median colour over all its surface is its glass, which returns almost no
    depth: what is seen of it is mostly its lid."""
    got = model.__dict__.get("_gate")
    if got is None:
        got = [np.median(model.hsv[m], axis=0) for m in (~model.dropout, model.dropout)
               if m.any()]
        model.__dict__["_gate"] = got
    return got


def _rectangle_seeds(rect, model: ObjectModel) -> list[tuple[float, float, float]]:
    """Seeds for a flat object (lower than its radius: a book lying down, a remote) seen
    from above: its whole top is in view, so the smallest rectangle around the piece
    (OpenCV ``minAreaRect``) has the object's centre and its sides along the object's
    principal axes (four yaws: a rectangle's sides are a quarter turn apart). Point-to-point
    ICP alone does not pull a flat face across itself: inside the overlap every scene point
    has a model point within the sampling distance, so only the few points beyond an edge
    move it, and a seed shifted away from the camera (the other seeds) stalls centimetres
    off."""
    (cx, cy), _, angle = rect
    base = math.radians(angle) - _principal_angle(model)
    return [(float(cx), float(cy), float(base + k * math.pi / 2)) for k in range(4)]


def _edge_seeds(rect, model: ObjectModel, cam: np.ndarray) -> list[tuple[float, float, float]]:
    """Seeds for a flat object seen from the side (a book lying on a shelf at the head's
    height, its top out of sight): only its near faces are in view, so the piece is a strip
    along one of its edges, and ``_rectangle_seeds`` centre the model on that strip. Here
    the strip's long axis (OpenCV ``minAreaRect``) is taken for the object's long side, then
    for its short side, and the centre is put half the other side behind the strip, away
    from the camera; two yaws a half turn apart for each."""
    (cx, cy), (w, h), angle = rect
    a = math.radians(angle) + (0.0 if w >= h else math.pi / 2)   # the strip's long axis
    length, width = _footprint_sides(model)
    normal = np.array([-math.sin(a), math.cos(a)])
    if np.dot(normal, np.array([cx, cy]) - cam[:2]) < 0:
        normal = -normal                                           # away from the camera
    out = []
    for behind, turn in ((width, 0.0), (length, math.pi / 2)):
        x, y = np.array([cx, cy]) + normal * behind / 2
        yaw = a + turn - _principal_angle(model)
        out += [(float(x), float(y), float(yaw)), (float(x), float(y), float(yaw + math.pi))]
    return out


def _footprint_sides(model: ObjectModel) -> tuple[float, float]:
    """Extents (m) of the model's footprint along its major and minor axes (cached)."""
    got = model.__dict__.get("_sides")
    if got is None:
        a = _principal_angle(model)
        xy = model.points[:, :2] @ np.array([[math.cos(a), -math.sin(a)],
                                             [math.sin(a), math.cos(a)]])
        got = model.__dict__["_sides"] = (float(np.ptp(xy[:, 0])), float(np.ptp(xy[:, 1])))
    return got


def _footprint_tree(model: ObjectModel) -> cKDTree:
    """KD-tree of the model's points projected on its base plane (cached): its outline seen
    from above."""
    t = model.__dict__.get("_footprint")
    if t is None:
        t = model.__dict__["_footprint"] = cKDTree(model.points[:, :2])
    return t


def _principal_angle(model: ObjectModel) -> float:
    """Angle (object frame, rad) of the major axis of the model's footprint (cached)."""
    a = model.__dict__.get("_principal")
    if a is None:
        xy = model.points[:, :2] - model.points[:, :2].mean(0)
        w, v = np.linalg.eigh(xy.T @ xy)
        major = v[:, int(np.argmax(w))]
        a = model.__dict__["_principal"] = float(math.atan2(major[1], major[0]))
    return a


def _verify(model: ObjectModel, T: np.ndarray, ci: int, pts, hsv, normals, tree_xy, tree_xyz,
            depth, K, T_cw, use_color: bool, config: DetectionConfig) -> Hypothesis:
    """Score one hypothesis against the view (see the module docstring)."""
    R = T[:3, :3]
    mp_w, mn_w, _, _, _, measured, expected, hidden = _model_in_view(model, T, depth, K, T_cw,
                                                                      config)
    visible = expected & ~hidden
    n_exp, n_vis = int(expected.sum()), int(visible.sum())
    visible_fraction = n_vis / n_exp if n_exp else 0.0

    # Model -> scene: how much of the visible model surface has a measurement on it. On glass,
    # dark or shiny visuals a missing return is what the sensor gives: no reading there does
    # not speak against the hypothesis (a reading elsewhere along the ray would: ``hidden``).
    dm, _ = tree_xyz.query(mp_w[visible], distance_upper_bound=config.inlier_distance * 1.5)
    eye = -T_cw[:3, :3].T @ T_cw[:3, 3]
    ray = mp_w - eye
    cos_in = -np.einsum("ij,ij->i", mn_w, ray) / np.maximum(np.linalg.norm(ray, axis=1), 1e-9)
    grazing = cos_in < math.cos(math.radians(config.grazing_deg))
    lost = ((model.dropout | grazing) & (measured <= 0))[visible]
    inlier_fraction = float((np.isfinite(dm) | lost).mean()) if n_vis else 0.0

    # Scene -> model: points in the hypothesis' column (its footprint, any height: a taller
    # object is not this one), explained or not.
    col = np.asarray(tree_xy.query_ball_point(T[:2, 3], model.radius + 0.04), int)
    local = (pts[col] - T[:3, 3]) @ R
    dd, jj = model.tree.query(local)
    expl = dd < config.inlier_distance
    # The footprint is the model's outline seen from above (not the circle around it: beside
    # a long book that circle holds its neighbours).
    d_foot = _footprint_tree(model).query(local[:, :2], distance_upper_bound=0.015)[0]
    inner = d_foot < 0.015
    # Just outside the outline and near the model's surface: within the circle around the
    # model any such point counts (a bigger object this one would be part of), beyond it
    # only where it continues the object's surface in the object's colour; a neighbour
    # further from the surface does not.
    close = ~inner & ~expl & (dd < 0.04)
    hug = close & (np.linalg.norm(local[:, :2], axis=1) < model.radius + 0.015)
    ring = close & ~hug
    extension = int(hug.sum())
    if ring.any() and expl.any():
        adj, _ = cKDTree(local[expl]).query(local[ring], distance_upper_bound=config.cluster_radius)
        same = color_agreement(hsv[col][ring], np.tile(np.median(model.hsv, 0), (ring.sum(), 1))) \
            if use_color else np.ones(ring.sum())
        extension += int((np.isfinite(adj) & (same > 0)).sum())
    n_region = int(inner.sum()) + extension
    unexplained = float((int((inner & ~expl).sum()) + extension) / n_region) if n_region else 1.0
    sel = expl & inner
    inliers = col[sel]
    worst_part = 1.0
    if sel.any():
        n_scene = normals[inliers]
        n_model = mn_w[jj[sel]]
        facing = np.abs(np.einsum("ij,ij->i", n_scene, n_model)) > 0.8
        normal_agreement = float(np.mean(facing))
        color = 1.0
        if use_color:
            agree = color_agreement(hsv[inliers], model.hsv[jj[sel]])
            color = float(agree.mean())
            # each colour of the model apart, on the inliers whose normal agrees with the
            # model's: a thin part (a pill box's 2 mm lid) seen edge-on is matched to the
            # points of the face beside it
            part = model.colour_part[jj[sel]]
            for p in np.unique(part[facing]):
                on = (part == p) & facing
                if on.sum() >= config.min_part_points:
                    worst_part = min(worst_part, float(agree[on].mean()))
    else:
        normal_agreement, color = 0.0, 0.0
    # well inside the outline (not near its edge, where a taller neighbour standing against
    # the object reaches once the pose is a centimetre or two off): a point standing over the
    # model's top there is not this object
    within = _deep_inside(model, local[:, :2], d_foot, config)
    n_within = int(within.sum())
    taller = float((within & (local[:, 2] > model.height + config.taller_margin)).sum()
                   / n_within) if n_within else 0.0
    # Too little of the model in sight to say anything: confidence falls with the count.
    support = min(1.0, n_vis * inlier_fraction / 40.0)
    # a colour of the model the view does not show, and an object taller than the model
    looks = min(1.0, worst_part / config.part_agreement) * max(0.0, 1.0 - taller / config.max_taller)
    confidence = inlier_fraction * normal_agreement * color * (1 - unexplained) ** 2 * support \
        * looks
    return Hypothesis(model.object_id, T, float(confidence), inlier_fraction, normal_agreement,
                      color, unexplained, 0.0, visible_fraction, ci, inliers,
                      worst_part_color=worst_part, taller=taller)


def _deep_inside(model: ObjectModel, xy: np.ndarray, d_foot: np.ndarray,
                 config: DetectionConfig) -> np.ndarray:
    """Which of the points ``xy`` (object frame) lie over the model's outline seen from above
    (within ``taller_outline`` of it) and ``taller_depth`` or more inside its edge: the
    outline reached from each in 8 directions ``taller_depth`` away (an erosion of the
    footprint; scipy's KD-tree of the model's footprint). An outline too small for any:
    the points over it."""
    over = d_foot < config.taller_outline
    if not over.any():
        return over
    tree = _footprint_tree(model)
    deep = over.copy()
    for a in np.linspace(0.0, 2 * math.pi, 8, endpoint=False):
        step = config.taller_depth * np.array([math.cos(a), math.sin(a)])
        idx = np.flatnonzero(deep)
        if not len(idx):
            break
        d = tree.query(xy[idx] + step, distance_upper_bound=config.taller_outline)[0]
        deep[idx[d >= config.taller_outline]] = False
    return deep if deep.any() else over


def _resolve(hyps: list[Hypothesis], believed: Optional[dict] = None,
             config: DetectionConfig = DetectionConfig()) -> list[Hypothesis]:
    """Keep the best pose per object and place; penalise hypotheses whose inliers a stronger
    one already claims (two models cannot explain the same points) and second places of the
    same object; best first. ``believed``: object id -> (x, y) where the map has it; of
    hypotheses within ``config.prior_tie`` of each other, those the map puts within
    ``config.prior_radius`` claim their points first (two objects of the map alike in shape
    and hue, a navy and a blue cup, fit the same points equally: where the map has one of them
    and not the other, that one is there)."""
    believed = believed or {}

    def at_home(h: Hypothesis) -> bool:
        xy = believed.get(h.object_id)
        return xy is not None and float(np.hypot(*(h.position[:2] - xy))) <= config.prior_radius

    hyps.sort(key=lambda h: h.confidence + (config.prior_tie if at_home(h) else 0.0),
              reverse=True)
    kept: list[Hypothesis] = []
    for h in hyps:
        if any(k.object_id == h.object_id and np.linalg.norm(k.position[:2] - h.position[:2]) < 0.05
               for k in kept):
            continue  # the same object at the same place from another seed or yaw
        kept.append(h)
    claimed: set[int] = set()
    placed: set[str] = set()
    for h in kept:
        mine = set(h.inliers.tolist())
        if mine:
            h.conflict = len(mine & claimed) / len(mine)
            h.confidence *= (1 - h.conflict)
        # an object already placed here claims no second place's points (the map holds it
        # once; the second place is scaled down below): a brown mug found where it stands does
        # not also take the amber mug's points beside it
        if h.conflict < 0.5 and h.object_id not in placed:
            claimed |= mine
            placed.add(h.object_id)
    kept.sort(key=lambda h: h.confidence, reverse=True)
    # The map holds each small object once: where a stronger hypothesis places the same object
    # elsewhere, this one is at most as likely as that one is wrong.
    best: dict[str, float] = {}
    for h in kept:
        if h.object_id in best:
            h.confidence *= (1 - best[h.object_id])
        else:
            best[h.object_id] = h.confidence
    kept.sort(key=lambda h: h.confidence, reverse=True)
    return kept


def verify_object(world, object_id: str, T_world_object: np.ndarray, depth: np.ndarray,
                  color: Optional[np.ndarray], K: Intrinsics, T_world_camera: np.ndarray,
                  tolerance: float = 0.03, config: DetectionConfig = DetectionConfig()
                  ) -> Optional[Hypothesis]:
    """The best hypothesis of ``object_id`` within ``tolerance`` (m, x/y) of a hypothesised
    pose in a new view, every map object competing for the same points (so the red cup does
    not verify as the blue one); None when there is none."""
    surface = None
    for obj in world.large_objects():
        # its own surfaces and its parts' (a drawer's floor, where the drawer is now)
        for s in world.surfaces_of(obj.id):
            T = s.T_world_surface
            local = np.linalg.inv(T) @ np.append(np.asarray(T_world_object)[:3, 3], 1.0)
            if abs(local[0]) < s.size_x / 2 + 0.05 and abs(local[1]) < s.size_y / 2 + 0.05 \
                    and abs(local[2]) < 0.05:
                surface = s.name
    det = detect_objects(world, depth, color, K, T_world_camera, surface=surface, config=config)
    p = np.asarray(T_world_object)[:2, 3]
    near = [h for h in det.hypotheses if h.object_id == object_id
            and np.linalg.norm(h.position[:2] - p) < tolerance]
    return near[0] if near else None
