"""Fine pose of a bar handle on a registered door or drawer face (RAMCIP 5.2.1.1).

1. The face plane: observed points near the registered face (within ``plane_band`` of the
   plane the registration puts it in) are fitted with a least-squares plane (SVD).
2. The face: points on that plane inside the part's face rectangle, enlarged by
   ``bounds_margin``; their convex hull (scipy) in plane coordinates.
3. The handle: points inside the hull's extrusion that stand proud of the plane by
   ``standoff_range`` (default 1 to 12 cm: real bar handles stand 1 to over 10 cm proud),
   nearest the handle the map expects; of those, the bar is the outermost layer.
4. Orientation: +x the plane normal (out of the face), +z the bar's principal axis (PCA in the
   plane, signed like the map's), +y completing the frame.
5. Position: the camera sees only the front half of a round bar, so the centroid of its points
   sits in front of the axis; for points spread evenly across the bar's silhouette the mean
   depth offset is pi/4 * radius, so the centroid is pushed that far back along the viewing
   ray. Along the bar, when less than ``min_visible_length`` of its length is seen (partly
   hidden, or dropouts on a shiny bar), the coordinate comes from the map prior instead (for a
   vertical bar: its height).

Pure: points, poses and the map's handle description in, a pose out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay, QhullError

from perception.errors import PerceptionError
from perception.registration import single_threaded_blas


@dataclass(frozen=True)
class HandleConfig:
    """Lengths in metres."""
    standoff_range: tuple[float, float] = (0.01, 0.12)
    plane_band: float = 0.012
    bounds_margin: float = 0.05
    search_radius: float = 0.08        # around the expected handle, in the plane, beyond its length
    min_points: int = 15
    min_visible_length: float = 0.8    # fraction of the bar's length seen to trust its extent


@dataclass
class HandleEstimate:
    """``T_world_handle``: the handle frame (origin on the bar's axis at its centre, +x out of
    the face, +z along the bar). ``points``: observed points on the bar; ``prior_used``: the
    along-bar coordinate came from the map; ``standoff``: measured face-to-axis distance (m)."""
    handle_id: str
    T_world_handle: np.ndarray
    points: int
    standoff: float
    prior_used: bool
    plane_normal: np.ndarray
    plane_point: np.ndarray


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares plane through points: (centroid, unit normal)."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    return c, vt[2]


@single_threaded_blas
def estimate_handle(observed_world: np.ndarray, T_world_part: np.ndarray,
                    face_half_extent: tuple[float, float, float, float],
                    T_world_handle_prior: np.ndarray, radius: float, length: float,
                    standoff: float, camera_position: np.ndarray, handle_id: str = "",
                    cfg: HandleConfig = HandleConfig()) -> HandleEstimate:
    """The handle's fine pose from observed world points around a registered part.

    ``T_world_handle_prior``: where the registered model puts the handle (its +x is the face
    normal). ``face_half_extent``: (umin, umax, vmin, vmax) of the face rectangle in the
    handle frame's (y, z) coordinates. ``radius``, ``length``, ``standoff``: the map's bar.
    Raises PerceptionError when the face or the bar is not seen.
    """
    P = np.asarray(observed_world, dtype=float)
    Tp = np.asarray(T_world_handle_prior, dtype=float)
    x0, y0, z0 = Tp[:3, 0], Tp[:3, 1], Tp[:3, 2]
    face_point = Tp[:3, 3] - standoff * x0
    # 1. the face plane from points near the registered face
    rel = P - face_point
    dist = rel @ x0
    uu, vv = rel @ y0, rel @ z0
    umin, umax, vmin, vmax = face_half_extent
    m = cfg.bounds_margin
    in_bounds = (uu > umin - m) & (uu < umax + m) & (vv > vmin - m) & (vv < vmax + m)
    on_face = in_bounds & (np.abs(dist) < cfg.plane_band)
    if on_face.sum() < 3 * cfg.min_points:
        raise PerceptionError(f"the face is not seen ({int(on_face.sum())} points on it)",
                              node=handle_id or None)
    c, n = fit_plane(P[on_face])
    if n @ x0 < 0:
        n = -n
    # Refit once on the points near the fitted plane (drops the odd handle foot).
    d2 = (P - c) @ n
    on_face = in_bounds & (np.abs(d2) < cfg.plane_band * 0.5)
    c, n = fit_plane(P[on_face])
    if n @ x0 < 0:
        n = -n
    # plane coordinates: e1 along the prior bar axis projected into the plane
    e2 = z0 - (z0 @ n) * n
    e2 /= np.linalg.norm(e2)
    e1 = np.cross(e2, n)
    rel = P - c
    h = rel @ n
    a, b = rel @ e1, rel @ e2
    # 2. the convex hull of the face points, extruded along the normal
    face2d = np.stack([a[on_face], b[on_face]], axis=1)
    try:
        hull = Delaunay(face2d[::max(1, len(face2d) // 2000)])
    except QhullError:
        raise PerceptionError("the face points are degenerate", node=handle_id or None) from None
    lo, hi = cfg.standoff_range
    cand = (h > lo) & (h < hi)
    # 3. near the expected handle
    pc = Tp[:3, 3] - c
    pa, pb = pc @ e1, pc @ e2
    near = (np.abs(a - pa) < cfg.search_radius) & (np.abs(b - pb) < length / 2 + cfg.search_radius)
    cand &= near
    idx = np.nonzero(cand)[0]
    if len(idx):
        idx = idx[hull.find_simplex(np.stack([a[idx], b[idx]], axis=1)) >= 0]
    if len(idx) < cfg.min_points:
        raise PerceptionError(f"no handle stands out of the face ({len(idx)} points)",
                              node=handle_id or None)
    # the bar: the outermost layer (the standoff feet lie nearer the face)
    top = np.percentile(h[idx], 90)
    bar = idx[h[idx] > top - 1.6 * radius]
    if len(bar) < cfg.min_points // 2:
        bar = idx
    Q = P[bar]
    # 4. orientation
    q2 = np.stack([a[bar], b[bar]], axis=1)
    q2c = q2 - q2.mean(axis=0)
    _, _, vt = np.linalg.svd(q2c, full_matrices=False)
    axis2 = vt[0]
    z = axis2[0] * e1 + axis2[1] * e2
    if z @ z0 < 0:
        z = -z
    x = n
    y = np.cross(z, x)
    # 5. position: push the centroid back along the viewing ray by pi/4 * radius
    centroid = Q.mean(axis=0)
    ray = centroid - np.asarray(camera_position, dtype=float)
    ray /= np.linalg.norm(ray)
    p = centroid + (math.pi / 4) * radius * ray
    along = (Q - p) @ z
    lo_s, hi_s = np.percentile(along, [1, 99])
    prior_used = (hi_s - lo_s) < cfg.min_visible_length * length
    if prior_used:
        # Partly hidden: the centre along the bar from the map, the rest from the data.
        p = p + ((Tp[:3, 3] - p) @ z) * z
    else:
        p = p + 0.5 * (lo_s + hi_s) * z
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, p
    return HandleEstimate(handle_id, T, len(bar), float((p - c) @ n), bool(prior_used), n, c)


def face_extent_in_handle_frame(face_corners_world: np.ndarray,
                                T_world_handle: np.ndarray) -> tuple[float, float, float, float]:
    """(umin, umax, vmin, vmax): the face's corners in the handle frame's y and z."""
    T_inv = np.linalg.inv(T_world_handle)
    q = face_corners_world @ T_inv[:3, :3].T + T_inv[:3, 3]
    return (float(q[:, 1].min()), float(q[:, 1].max()), float(q[:, 2].min()),
            float(q[:, 2].max()))


def rotation_error_deg(T_a: np.ndarray, T_b: np.ndarray, symmetric_bar: bool = True) -> float:
    """Angle between two handle frames; a bar turned end for end (z -> -z, y -> -y) counts as
    the same handle when ``symmetric_bar``."""
    def ang(Ra, Rb):
        c = (np.trace(Ra.T @ Rb) - 1) / 2
        return math.degrees(math.acos(float(np.clip(c, -1, 1))))
    e = ang(T_a[:3, :3], T_b[:3, :3])
    if symmetric_bar:
        flip = np.diag([1.0, -1.0, -1.0])
        e = min(e, ang(T_a[:3, :3] @ flip, T_b[:3, :3]))
    return e


__all__ = ["HandleConfig", "HandleEstimate", "estimate_handle", "face_extent_in_handle_frame",
           "fit_plane", "rotation_error_deg"]
