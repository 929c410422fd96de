"""Fine pose of a bar handle on a registered door or drawer face (RAMCIP 5.2.1.1).

The face comes from the part's geometry (``hearth.perception.articulated.part_face``: a box or a
mesh), registered with its part: a plane (its outward normal and a point on its outer
surface) and its rectangle. Then, from the observed points:

1. The face plane: a least-squares plane (SVD) through the observed points within
   ``plane_band`` of the plane, iterated: each fit selects the points near the last one, so a
   prior a few degrees off (a door angle read 2-3 degrees wrong moves a far edge by 2 cm)
   converges onto the face instead of fitting the strip where prior and face cross.
2. The face region: points on that plane inside the face rectangle enlarged by
   ``bounds_margin``; their convex hull (scipy) in plane coordinates.
3. The handle: points inside the hull's extrusion standing ``standoff_range`` proud of the
   plane (default 1 to 12 cm), near the handle the map expects, and within ``standoff_slack``
   of the map's standoff (what else stands out of a face near a handle: a table edge in
   front, a knob, the edge of the other door); of those the bar is the outermost layer (the
   standoff feet lie nearer the face). Then once more in a tube around the bar found.
4. Orientation: +x the plane normal (out of the face), +z the bar's principal axis in the
   plane, weighed against the direction the map gives the bar on its face: the measured
   angle's variance (the points' spread across the bar over their number and their spread
   along it) against ``axis_prior_deg``, so a short bar seen in a few points does not swing
   the frame by its noise, and a long bar seen well is taken as measured. The map's handle
   frame is kept whatever its axes are (a handle imported from URDF need not have +x out of
   the face): the measured face frame is turned into it by the rotation the map has between
   the two.
5. Position across the bar: the camera sees only the front half of a round bar, so the
   centroid of its points sits in front of the axis; for points spread evenly across the
   bar's silhouette the mean depth offset is pi/4 * radius, so the centroid is pushed that far
   back along the viewing ray.
6. Position along the bar: from its ends, where they are seen to be ends: just beyond a seen
   end, the view must show what lies behind the bar (the face, or anything further). Where it
   shows nothing (the image border, a dropout on a shiny bar) or something nearer (an
   occluder), the bar may go on, and that end says nothing. Both ends seen: their middle; one:
   that end and the map's length; none: the map's coordinate along the bar (``prior_used``).

Pure: points, poses and the map's handle description in, a pose out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay, QhullError, cKDTree

from hearth.perception.errors import PerceptionError
from hearth.perception.registration import single_threaded_blas


@dataclass(frozen=True)
class HandleConfig:
    """Lengths in metres, angles in degrees.

    ``min_face_angle_cos``: the face must be seen within ~80 degrees of its normal (cos 0.17),
    else its handle is behind it or seen edge-on. ``standoff_slack``: how far the bar may
    stand from where the map's standoff puts it. ``axis_prior_deg`` / ``face_prior_deg``: how
    well the registered part gives the bar's direction in its face / the face's normal (the
    measured ones are weighed against them by their variances). ``max_axis_deg``: a bar further than this
    from the map's direction is something else. ``max_end_gap``: how far beyond a bar's last
    point the view is searched for what lies behind it (an end seen further out is not
    seen); ``end_tolerance``: how far a bar's last point may lie beyond its end (noise)."""
    standoff_range: tuple[float, float] = (0.01, 0.12)
    plane_band: float = 0.012
    plane_iterations: int = 4
    bounds_margin: float = 0.05
    face_inset: float = 0.01
    search_radius: float = 0.08        # around the expected handle, in the plane, beyond its length
    min_points: int = 15
    min_face_angle_cos: float = 0.17
    standoff_slack: float = 0.02
    axis_prior_deg: float = 1.0
    face_prior_deg: float = 1.0
    max_axis_deg: float = 15.0
    max_end_gap: float = 0.015
    end_tolerance: float = 0.002


@dataclass
class HandleEstimate:
    """``T_world_handle``: the handle frame as the map defines it (for a handle described as
    Hearth's world format says: origin on the bar's axis at its centre, +x out of the face, +z
    along the bar). ``points``: observed points on the bar; ``prior_used``: the along-bar
    coordinate came from the map; ``ends_seen``: how many bar ends were seen (0-2);
    ``standoff``: measured face-to-axis distance (m); ``plane_normal`` / ``plane_point``: the
    fitted face plane (world)."""
    handle_id: str
    T_world_handle: np.ndarray
    points: int
    standoff: float
    prior_used: bool
    plane_normal: np.ndarray
    plane_point: np.ndarray
    ends_seen: int = 0


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares plane through points: (centroid, unit normal)."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    return c, vt[2]


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _fail(message: str, handle_id: str):
    return PerceptionError(message, node=handle_id or None)


def _face_plane(P: np.ndarray, c: np.ndarray, n: np.ndarray, cfg: HandleConfig,
                handle_id: str, inside: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(point, unit normal, mask of P on it): the plane fitted iteratively from (c, n) through
    the points of P ``inside`` the face's rectangle."""
    n0 = n
    band = cfg.plane_band
    for i in range(max(1, cfg.plane_iterations)):
        on = inside & (np.abs((P - c) @ n) < band)
        if on.sum() < 3 * cfg.min_points:
            raise _fail(f"the face is not seen ({int(on.sum())} points on it)", handle_id)
        c_new, n_new = fit_plane(P[on])
        if n_new @ n0 < 0:
            n_new = -n_new
        moved = abs((c_new - c) @ n_new) + np.linalg.norm(np.cross(n_new, n))
        c, n = c_new, n_new
        if i >= 1 and moved < 1e-4:
            break
        band = cfg.plane_band * 0.5 if i >= 1 else cfg.plane_band
    on = inside & (np.abs((P - c) @ n) < cfg.plane_band * 0.5)
    if on.sum() < 3 * cfg.min_points:
        raise _fail(f"the face is not seen ({int(on.sum())} points on it)", handle_id)
    return c, _weigh_normal(P[on], c, n, n0, math.radians(cfg.face_prior_deg)), on


def _weigh_normal(Q: np.ndarray, c: np.ndarray, n: np.ndarray, n0: np.ndarray,
                  prior_sigma: float) -> np.ndarray:
    """The fitted normal ``n`` weighed against the registered face's ``n0``, tilt by tilt: a
    plane through a narrow strip of face (a drawer front half hidden below the one above)
    fixes its tilt about the strip's length poorly. Along each principal direction of the
    points in the plane, the tilt's variance is the points' variance off the plane over their
    number times their variance along that direction; it is weighed against
    ``prior_sigma`` (rad)."""
    d = Q - c
    off = float(np.mean((d @ n) ** 2))
    inplane = d - np.outer(d @ n0, n0)
    lam, vec = np.linalg.eigh(inplane.T @ inplane / len(Q))
    out = n0.copy()
    for k in (1, 2):                           # the two largest: directions in the plane
        dk = vec[:, k]
        alpha = float(n @ dk) / float(n @ n0)
        var = off / (len(Q) * max(float(lam[k]), 1e-12))
        out = out + alpha * prior_sigma ** 2 / (prior_sigma ** 2 + var) * dk
    return _unit(out)


def _bar_axis(q2: np.ndarray, prior_dir: np.ndarray, prior_sigma: float) -> np.ndarray:
    """Unit direction (plane coordinates) of the bar through points ``q2`` (N, 2): the
    principal axis, its angle from ``prior_dir`` shrunk by its variance against the prior's
    (``prior_sigma``, rad): var(angle) ~ spread across / (N * spread along)."""
    q = q2 - q2.mean(axis=0)
    cov = q.T @ q / len(q)
    w, v = np.linalg.eigh(cov)
    axis = v[:, 1]
    if axis @ prior_dir < 0:
        axis = -axis
    perp = np.array([-prior_dir[1], prior_dir[0]])
    theta = math.atan2(float(axis @ perp), float(axis @ prior_dir))
    var_meas = max(w[0], 1e-12) / (len(q) * max(w[1], 1e-12))
    k = prior_sigma ** 2 / (prior_sigma ** 2 + var_meas)
    t = k * theta
    return math.cos(t) * prior_dir + math.sin(t) * perp


def _end_gap(end: np.ndarray, z: np.ndarray, cam: np.ndarray, radius: float, tree: cKDTree,
             ranges: np.ndarray, spacing: float, max_probe: float) -> float:
    """How far beyond the last bar point ``end`` (world, on the axis; ``z`` outwards) the
    view first shows what lies behind the bar (m): the bar ends within that gap. Probes step
    outwards along the axis, one observation apart in the image; the first that sees anything
    decides: mostly something behind (further than the bar's front) gives the gap, the bar or
    something nearer (the bar goes on, an occluder) or nothing up to ``max_probe`` (the image
    border, dropouts) gives inf. ``tree``: unit viewing directions of the observations,
    ``ranges`` theirs, ``spacing`` their angular spacing (rad).

    What a probe sees of the bar itself is passed over: seen steeply (from above a vertical
    bar, beside a horizontal one), the view just past an end meets the bar's own front or its
    end cap (points within the bar's tube, not beyond its last point); the probes go on until
    they see past it."""
    # Probes 1 mm apart along the axis, looked at when their viewing direction has moved a
    # whole observation on (the first 1.5 clear of the bar's last point, so the bar itself is
    # not taken for what lies past it; a bar seen end-on moves little in the image).
    last = _unit(end - cam)
    need = 1.5 * spacing
    d = 0.001
    while d <= max_probe + 1e-9:
        v = end + d * z - cam
        rng = float(np.linalg.norm(v))
        u = v / rng
        if np.linalg.norm(u - last) >= need:
            idx = tree.query_ball_point(u, spacing)
            if idx:
                X = cam + tree.data[idx] * ranges[idx, None]
                t = (X - end) @ z
                radial = np.linalg.norm((X - end) - np.outer(t, z), axis=1)
                own = (radial < radius + 0.003) & (t < 0.002)
                if own.mean() <= 0.5:
                    rest = ranges[idx][~own]
                    # most of it behind (a noisy point of the bar's edge may stray into the cone)
                    return d if np.mean(rest > rng + radius) > 0.5 else math.inf
            last, need = u, spacing
        d += 0.001
    return math.inf


@single_threaded_blas
def estimate_handle(observed_world: np.ndarray, T_world_face: np.ndarray,
                    face_half_size: tuple[float, float], T_world_handle_prior: np.ndarray,
                    radius: float, length: float, standoff: float, camera_position: np.ndarray,
                    handle_id: str = "", cfg: HandleConfig = HandleConfig(),
                    bar_axis: int = 2, prior_trusted: bool = True) -> HandleEstimate:
    """The handle's fine pose from observed world points around a registered part.

    ``T_world_face``: the registered face (``part_face``): origin on its outer surface, +x its
    outward normal, y and z in its plane; ``face_half_size``: (y, z) half sizes of its
    rectangle (m). ``T_world_handle_prior``: where the registered model puts the handle, in
    the map's handle frame, whose axis ``bar_axis`` (0, 1, 2) runs along the bar.
    ``radius``, ``length``, ``standoff``: the map's bar. ``observed_world``: every observed
    point of the view (world; the bar ends are checked against what lies behind them).
    ``prior_trusted``: whether the prior's position can stand in for a bar hidden at both
    ends (not when its object's base could not be registered: the map's pose may be
    centimetres off).
    Raises PerceptionError when the face or the bar is not seen, or what is seen is not the
    bar the map describes.
    """
    P_all = np.asarray(observed_world, dtype=float)
    cam = np.asarray(camera_position, dtype=float)
    Tf = np.asarray(T_world_face, dtype=float)
    Tp = np.asarray(T_world_handle_prior, dtype=float)
    n0, fy, fz, c0 = Tf[:3, 0], Tf[:3, 1], Tf[:3, 2], Tf[:3, 3]
    p_prior, z_prior = Tp[:3, 3], Tp[:3, bar_axis]
    # 0. the face must face the camera: a handle on a face seen from behind (a door opened
    # past 90 degrees) or edge-on is not in view, whatever stands out there.
    v = cam - p_prior
    cos_view = float(v @ n0) / float(np.linalg.norm(v))
    if cos_view < cfg.min_face_angle_cos:
        raise _fail(f"its face is seen {math.degrees(math.acos(max(-1.0, min(1.0, cos_view)))):.0f}"
                    f" degrees from its normal: turned away or edge-on", handle_id)
    # 1. the face plane from points near the registered face, inside its rectangle shrunk by
    # ``face_inset`` (the fronts of neighbouring drawers, a few millimetres in front or
    # behind, and the mixed pixels at its edges stay out); what stands out of it is looked
    # for within the rectangle grown by ``bounds_margin``
    hy, hz = face_half_size
    m = cfg.bounds_margin
    rel = P_all - c0
    uu, ww = np.abs(rel @ fy), np.abs(rel @ fz)
    in_bounds = ((uu < hy + m) & (ww < hz + m)
                 & (np.abs(rel @ n0) < cfg.standoff_range[1] + 0.05))
    P = P_all[in_bounds]
    inside = (uu[in_bounds] < hy - cfg.face_inset) & (ww[in_bounds] < hz - cfg.face_inset)
    c, n, on_face = _face_plane(P, c0, n0, cfg, handle_id, inside)
    # plane coordinates: e2 the map's bar direction in the plane, e1 across it
    e2 = z_prior - (z_prior @ n) * n
    if np.linalg.norm(e2) < 0.5:
        raise _fail("the map's bar does not lie along its face", handle_id)
    e2 = _unit(e2)
    e1 = np.cross(e2, n)
    rel = P - c
    h = rel @ n
    a, b = rel @ e1, rel @ e2
    # 2. the convex hull of the face points, extruded along the normal
    face2d = np.stack([a[on_face], b[on_face]], axis=1)
    try:
        hull = Delaunay(face2d[::max(1, len(face2d) // 2000)])
    except QhullError:
        raise _fail("the face points are degenerate", handle_id) from None
    # 3. the bar: near the expected handle, standing out about as far as the map says
    lo, hi = cfg.standoff_range
    pc = p_prior - c
    pa, pb = pc @ e1, pc @ e2
    s_lo = max(lo, standoff - radius - cfg.standoff_slack)
    s_hi = min(hi, standoff + radius + cfg.standoff_slack)
    cand = ((h > s_lo) & (h < s_hi) & (np.abs(a - pa) < cfg.search_radius)
            & (np.abs(b - pb) < length / 2 + cfg.search_radius))
    near_idx = idx = np.nonzero(cand)[0]
    if len(idx):
        idx = idx[hull.find_simplex(np.stack([a[idx], b[idx]], axis=1)) >= 0]
    if len(idx) < cfg.min_points:
        raise _fail(f"no handle stands out of the face ({len(idx)} points)", handle_id)
    prior_dir = np.array([0.0, 1.0])                # e2 in (a, b)
    sigma = math.radians(cfg.axis_prior_deg)
    bar = _outermost(idx, h, radius, cfg.min_points)
    axis2 = _bar_axis(np.stack([a[bar], b[bar]], axis=1), prior_dir, sigma)
    # ... once more, in a tube around the bar found: drops what stood nearby, and takes the
    # bar's length beyond the face's edge (a bar may reach past a door's bottom edge)
    q2 = np.stack([a[near_idx], b[near_idx]], axis=1)
    mid = np.stack([a[bar], b[bar]], axis=1).mean(axis=0)
    across = (q2 - mid) @ np.array([-axis2[1], axis2[0]])
    h_bar = float(np.median(h[bar]))
    tube = near_idx[(np.abs(across) < radius + 0.01)
                    & (np.abs(h[near_idx] - h_bar) < 2 * radius + 0.01)]
    if len(tube) >= cfg.min_points:
        bar = _outermost(tube, h, radius, cfg.min_points)
        axis2 = _bar_axis(np.stack([a[bar], b[bar]], axis=1), prior_dir, sigma)
    turn = math.degrees(math.acos(min(1.0, abs(float(axis2 @ prior_dir)))))
    if turn > cfg.max_axis_deg:
        raise _fail(f"what stands out of the face runs {turn:.0f} degrees from the handle's "
                    f"direction: not the handle", handle_id)
    Q = P[bar]
    # 4. orientation
    z = axis2[0] * e1 + axis2[1] * e2
    x = n
    y = np.cross(z, x)
    # 5. across the bar: push the centroid back along the viewing ray by pi/4 * radius
    centroid = Q.mean(axis=0)
    ray = _unit(centroid - cam)
    p = centroid + (math.pi / 4) * radius * ray
    measured_standoff = float((p - c) @ n)
    if abs(measured_standoff - standoff) > cfg.standoff_slack:
        raise _fail(f"what stands out of the face is {measured_standoff * 100:.1f} cm proud, "
                    f"the handle {standoff * 100:.1f} cm: not the handle", handle_id)
    # 6. along the bar, from the ends seen to be ends: each seen end bounds where the bar
    # ends (between its last point and the first view past it), and with the map's length
    # bounds the centre; an end not seen bounds it on one side only (the bar covers what is
    # seen of it).
    along = np.sort((Q - p) @ z)
    along = _drop_strays(along)
    s_min, s_max = float(along[0]), float(along[-1])
    if s_max - s_min > length + 0.03:
        raise _fail(f"what stands out of the face is {(s_max - s_min) * 100:.0f} cm long, the "
                    f"handle {length * 100:.0f} cm: not the handle", handle_id)
    # (past the bar's own front and end cap, which may hide a radius or two beyond its end)
    g_lo, g_hi = _end_gaps(P_all, cam, p, z, s_min, s_max, radius,
                           cfg.max_end_gap + 2 * radius)
    eps = cfg.end_tolerance
    lo_c = max(s_min - g_lo + length / 2, s_max - length / 2 - eps)
    hi_c = min(s_min + length / 2 + eps, s_max + g_hi - length / 2)
    seen = (math.isfinite(g_lo), math.isfinite(g_hi))
    if not any(seen) and not prior_trusted:
        raise _fail("neither end of the bar is seen and its object was not registered: where "
                    "along the bar it is is unknown", handle_id)
    if not any(seen):
        s = float(np.clip((p_prior - p) @ z, min(lo_c, hi_c), max(lo_c, hi_c)))
    elif lo_c <= hi_c:
        s = 0.5 * (lo_c + hi_c)
    else:                                     # the ends seen disagree with the map's length
        s = 0.5 * (s_min + s_max) if all(seen) else (
            s_min + length / 2 if seen[0] else s_max - length / 2)
    p = p + s * z
    C_est = np.stack([x, y, z], axis=1)
    T = np.eye(4)
    T[:3, :3] = C_est @ _canonical(Tp[:3, :3], n0, bar_axis).T @ Tp[:3, :3]
    T[:3, 3] = p
    return HandleEstimate(handle_id, T, len(bar), measured_standoff, not any(seen), n, c,
                          int(sum(seen)))


def _outermost(idx: np.ndarray, h: np.ndarray, radius: float, min_points: int) -> np.ndarray:
    """The bar among candidate points: the outermost layer (the standoff feet lie nearer the
    face)."""
    top = np.percentile(h[idx], 90)
    bar = idx[h[idx] > top - 1.6 * radius]
    return bar if len(bar) >= min_points // 2 else idx


def _canonical(R_prior: np.ndarray, n: np.ndarray, bar_axis: int) -> np.ndarray:
    """The face frame of the prior: +x the face normal, +z the bar (orthogonalised)."""
    z = R_prior[:, bar_axis] - (R_prior[:, bar_axis] @ n) * n
    z = _unit(z)
    return np.stack([n, np.cross(z, n), z], axis=1)


def _drop_strays(along: np.ndarray) -> np.ndarray:
    """Sorted along-bar coordinates without stray points at either end (a flying pixel at a
    depth edge): an end point further from its neighbour than 4 median gaps."""
    if len(along) < 8:
        return along
    gap = max(float(np.median(np.diff(along))), 1e-4)
    lo, hi = 0, len(along) - 1
    while lo < hi - 4 and along[lo + 1] - along[lo] > 4 * gap:
        lo += 1
    while hi > lo + 4 and along[hi] - along[hi - 1] > 4 * gap:
        hi -= 1
    return along[lo:hi + 1]


def _end_gaps(P_all: np.ndarray, cam: np.ndarray, p: np.ndarray, z: np.ndarray,
              s_min: float, s_max: float, radius: float,
              max_gap: float) -> tuple[float, float]:
    """(low end gap, high end gap): see ``_end_gap``. The observations are looked up by
    viewing direction within a cone around the bar."""
    reach = max(abs(s_min), abs(s_max)) + max_gap + 0.02
    axis_dir = _unit(p - cam)
    rng0 = float(np.linalg.norm(p - cam))
    d = P_all - cam
    r = np.linalg.norm(d, axis=1)
    ok = r > 1e-6
    u = d[ok] / r[ok, None]
    cone = u @ axis_dir > math.cos(math.atan2(reach, rng0))
    u, r = u[cone], r[ok][cone]
    if len(u) < 4:
        return math.inf, math.inf
    tree = cKDTree(u)
    nn, _ = tree.query(u[:: max(1, len(u) // 500)], k=2)
    spacing = float(np.median(nn[:, 1]))
    return (_end_gap(p + s_min * z, -z, cam, radius, tree, r, spacing, max_gap),
            _end_gap(p + s_max * z, z, cam, radius, tree, r, spacing, max_gap))


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


__all__ = ["HandleConfig", "HandleEstimate", "estimate_handle", "fit_plane",
           "rotation_error_deg"]
