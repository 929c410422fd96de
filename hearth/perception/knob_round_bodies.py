"""Round bodies: a knob whose body is cylinders or discs on its axis with a marker off it
(``round_body_levels``, ``marker_dot``): the centre from the depth of its top's rim at the
image's own resolution (``body_center``) and the marker's colour about that centre
(``dot_profile``). The method is described in hearth/perception/knobs.py."""

from __future__ import annotations

import math
from typing import Optional, Sequence

import cv2
import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.perception.knob_canvas import plane_homography, rectify
from hearth.perception.knob_shapes import KnobShape, _Caster


def round_body_levels(shape: KnobShape, tol: float = 0.02) -> Optional[tuple[float, ...]]:
    """The heights (m above the panel, ascending) of the flat tops of a knob whose body (every
    visual but the markers) is round about its axis: cylinders and discs centred on it (a
    skirt, a cap; the plain knob), so that only the marker tells its angle and the depth of
    its body says nothing of it. None for any other shape (a grip bar, a pointer), for a
    shape without a marker, or a symmetric one. ``tol``: how far (share of the outline radius)
    a visual's rim may stray from a circle about the axis."""
    if shape.symmetry != 1 or "marker" not in shape.roles:
        return None
    levels = []
    for v, role in zip(shape.vertices, shape.roles):
        if role == "marker":
            continue
        rad = np.hypot(v[:, 0], v[:, 1])
        rim = rad > 0.5 * rad.max()
        if (not rim.any() or np.ptp(rad[rim]) > tol * shape.radius
                or abs(v[rim, 0].mean()) > tol * shape.radius or abs(v[rim, 1].mean()) > tol * shape.radius):
            return None
        levels.append(float(v[:, 2].max()))
    if not levels:
        return None
    return tuple(sorted({round(z, 5) for z in levels}))


def body_center(depth: np.ndarray, K: Intrinsics, T_wc: np.ndarray, T_c: np.ndarray, shape: KnobShape,
                caster: "_Caster", levels: Sequence[float], center, alpha: float, psi: float,
                iterations: int = 4, roi_radii: float = 1.35, min_pixels: int = 8):
    """The centre (m, canvas frame of ``T_c``) of a round-bodied knob (``round_body_levels``)
    from the depth image at its own pixels, starting at ``center``: the pixels measured
    above the mid-height between the body's top and the step below it (the cap over the
    skirt), and the same pixels of the body rendered at the current centre (the exact caster,
    the real camera), each mask's centroid taken on the plane of the top; the centre moves by the
    difference of the measured and rendered centroids until it settles. Only the top's mask
    (the pixels above the mid-height between the top and the step below it) is used: the
    marker stands on it. A shift of the knob along its face shifts the mask's centroid by as much,
    while what the view does to the masks (a side wall seen obliquely, the pixel lattice,
    the rim's share of pixels) is the same in both: so the centre comes to a fraction of a
    pixel from a hundred or more rim pixels, where the correlation peak of the canvas heights
    (8 px per radius, ``_depth_center``) places it to about a millimetre. Hand-written: no
    library fits a rendered step-edge outline with perspective and occlusion.
    Returns (centre, dict(pixels, moved_m)) or None when too few pixels were measured."""
    R_canvas_cam = np.linalg.inv(T_c)[:3, :3] @ T_wc[:3, :3]
    C = (np.linalg.inv(T_c) @ np.append(T_wc[:3, 3], 1.0))[:3]
    face = shape.face
    # the image box: the body's outline on the panel and on the face plane
    T_cam_canvas = np.linalg.inv(T_wc) @ T_c
    a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
    rr = roi_radii * shape.radius
    pts = []
    for z in (0.0, -face):
        P = np.stack([center[0] + rr * np.cos(a), center[1] + rr * np.sin(a), np.full_like(a, z),
                      np.ones_like(a)])
        pts.append((T_cam_canvas @ P)[:3])
    P = np.concatenate(pts, 1)
    if np.any(P[2] <= 1e-3):
        return None
    u = K.fx * P[0] / P[2] + K.cx
    v = K.fy * P[1] / P[2] + K.cy
    u0, v0 = max(int(np.floor(u.min())), 0), max(int(np.floor(v.min())), 0)
    u1, v1 = min(int(np.ceil(u.max())) + 1, K.width), min(int(np.ceil(v.max())) + 1, K.height)
    if u1 - u0 < 3 or v1 - v0 < 3:
        return None
    uu, vv = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    dc = np.stack([(uu.ravel() - K.cx) / K.fx, (vv.ravel() - K.cy) / K.fy, np.ones(uu.size)], 1)
    d = dc @ R_canvas_cam.T
    dz = np.where(np.abs(d[:, 2]) > 1e-9, d[:, 2], -1e-9)
    Zm = np.asarray(depth, dtype=np.float64)[v0:v1, u0:u1].ravel()
    hm = C[2] + Zm * d[:, 2] + face                   # measured height above the panel
    Pm = C[None, :2] + Zm[:, None] * d[:, :2]          # the measured points on the face's axes
    valid = (Zm > 0) & (hm > -0.03) & (hm < face + 0.03)
    tops = [float(z) for z in levels]
    taus = [(lo + hi) / 2 for lo, hi in zip([0.0] + tops[:-1], tops)]
    # each pixel's ray on the top's plane (canvas z = top - face)
    q = [C[None, :2] + d[:, :2] * ((tops[-1] - face - C[2]) / dz)[:, None]]
    q_panel = C[None, :2] + d[:, :2] * ((-face - C[2]) / dz)[:, None]
    q_face = C[None, :2] + d[:, :2] * ((0.0 - C[2]) / dz)[:, None]
    c = np.array(center, dtype=float)
    moved, used = 0.0, 0
    for _ in range(iterations):
        roi = valid & ((np.hypot(*(q_panel - c).T) <= rr) | (np.hypot(*(q_face - c).T) <= rr))
        O = C - np.array([c[0], c[1], -face])
        _lab, t = caster.labels(O, d, np.array([alpha]), -psi, with_t=True)
        t = t[0]
        hr = np.where(np.isfinite(t), C[2] + t * d[:, 2] + face, 0.0)
        panel = roi & ~np.isfinite(t)
        if panel.sum() < min_pixels:
            return None
        # the top's rim only: the marker stands on the top, and a lower step's centre (the
        # skirt's) is off the top's when the believed axis leans (and its step over the
        # panel is nearer the depth noise): home 1's centre error 0.60 -> 0.36 mm at the
        # median (p90 1.20 -> 0.89) against both steps weighted by their pixels
        mr = roi & (hr > taus[-1])
        nr = int(mr.sum())
        if nr < min_pixels or not (mr & valid).any():
            return None
        # the measured heights put on the rendered ones by the top itself (the median
        # difference over the rendered top), not by the panel: a knob standing half a
        # millimetre off its panel (a bezel's gap, a recess) moved the cut on the side wall
        # the camera sees, and with it the centre towards the camera, 0.1-0.4 mm with the
        # obliquity on views without noise (docs/knobs.md, "The top as the reference")
        off = float(np.median(hm[mr & valid] - hr[mr & valid]))
        mm = np.flatnonzero(roi)                       # indices, the masks' in their order
        mm = mm[hm[mm] - off > taus[-1]]
        # only measured top pixels that could be this knob's: on the top's plane within its
        # rendered radius and a quarter radius more. A packed neighbour's top (2 radii away,
        # its edge inside the region of interest) would pull the centroid towards it, and
        # each step pulls more: home 8's skirt knobs 2.15 radii apart, centres 7-17 mm off
        # towards the neighbour and dot angles 20-45 degrees off on a quarter of the views.
        r_top = float(np.hypot(*(q[-1][mr] - c).T).max())
        mm = mm[np.hypot(*(q[-1][mm] - c).T) <= r_top + 0.25 * shape.radius]
        # ... and whose measured point itself lies within the rendered top's radius of the
        # axis and half a radius more (a quarter cut noisy rims: home 784's centre p90 1.4 ->
        # 2.6 mm). Projected onto the top's plane, a neighbour's tall cap seen over the knob
        # from 45-60 degrees came within reach, and the centre walked towards it 5-17 mm on
        # views without noise (homes 8 and 17; docs/knobs.md, "Points, not their shadows")
        r3 = float(np.hypot(*(C[None, :2] + t[mr][:, None] * d[mr, :2] - c).T).max())
        mm = mm[np.hypot(*(Pm[mm] - c).T) <= r3 + 0.5 * shape.radius]
        used = int(mm.size)
        if used < min_pixels:
            return None
        step = q[-1][mm].mean(0) - q[-1][mr].mean(0)
        c = c + step
        moved = float(np.hypot(*(c - np.asarray(center))))
        # settled to a tenth of a millimetre (0.02 mm: nearly every call ran its four casts,
        # the depth's noise moving it more than that; the dot's angle moves by 0.5 degrees
        # at most)
        if np.hypot(*step) < 1e-4:
            break
    return (float(c[0]), float(c[1])), dict(pixels=used, moved_m=moved)


def marker_dot(shape: KnobShape) -> Optional[tuple[float, float, float, float]]:
    """Where a round-bodied knob's marker stands at angle 0: (angle about the axis, rad
    counter-clockwise from +y; its distance from the axis; its radius (m, the farthest of its
    points from its centre, in the face plane); the radius of the top it stands on), or None
    without a marker."""
    if "marker" not in shape.roles:
        return None
    mv = np.concatenate([v for v, r in zip(shape.vertices, shape.roles) if r == "marker"])
    m = mv[:, :2].mean(0)
    rho = float(np.hypot(*m))
    size = float(np.max(np.hypot(mv[:, 0] - m[0], mv[:, 1] - m[1])))
    body = [(float(v[:, 2].max()), float(np.hypot(v[:, 0], v[:, 1]).max()))
            for v, r in zip(shape.vertices, shape.roles) if r != "marker"]
    top = max(body)[1] if body else shape.radius
    return math.atan2(-m[0], m[1]), rho, size, top


def marker_proud(shape: KnobShape) -> float:
    """How far (m) a knob's marker stands out of the top of the rest of the knob (0: none,
    flush or sunk)."""
    if "marker" not in shape.roles:
        return 0.0
    mz = max(float(v[:, 2].max()) for v, r in zip(shape.vertices, shape.roles) if r == "marker")
    body = [float(v[:, 2].max()) for v, r in zip(shape.vertices, shape.roles) if r != "marker"]
    return max(0.0, mz - max(body)) if body else 0.0


def dot_profile(rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, T_c: np.ndarray, shape: KnobShape,
                center, px_per_radius: float = 32.0, step_deg: float = 1.0):
    """How much a marker-sized disc on the knob's top differs in colour from the top, at each
    relative angle (canvas frame of ``T_c``, ``step_deg`` apart) about ``center`` (m, canvas
    frame): the face plane rectified at ``px_per_radius`` about the centre, each pixel's
    colour distance from the top's median colour (the top without the marker), averaged over
    a disc of the marker's size (its image is blurred: a matched filter) at the marker's
    distance from the axis. Returns (angles of the marker at relative angle 0 added, rad;
    responses; the top's robust colour noise per pixel) or None (no marker)."""
    md = marker_dot(shape)
    if md is None:
        return None
    a0, rho_d, size, top = md
    rho = px_per_radius / shape.radius
    n = 2 * int(math.ceil(top * rho)) + 3
    H = plane_homography(K, T_wc, T_c, rho, n, center)
    win = rectify(rgb, H, n).astype(np.float32)
    c = (n - 1) / 2.0
    jj, ii = np.meshgrid(np.arange(n) - c, np.arange(n) - c)
    on_top = np.hypot(jj, ii) <= top * rho - 1.0
    if on_top.sum() < 20:
        return None
    ref = np.median(win[on_top], axis=0)
    D = np.linalg.norm(win - ref, axis=2).astype(np.float32)
    noise = float(np.median(D[on_top]) * 1.4826 + 1e-3)
    # disc sample points of the marker's size, its centre on the canvas (x right, y up)
    rr = np.sqrt(np.linspace(0.0, 1.0, 6)[1:])[:, None] * size * 0.8
    tt = np.linspace(0.0, 2 * math.pi, 10, endpoint=False)[None, :]
    disc = np.concatenate([[[0.0, 0.0]], np.stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()], 1)])
    # a marker standing proud of the top shows its side to the camera: seen on the face plane
    # (the marker's top) that side lies towards the camera, by up to its height times the
    # tangent of the obliquity. The disc swept that way is what the marker looks like; a disc
    # alone found it that far towards the camera (on views without noise, the reading's angle
    # error correlated -0.8 with the sine of the marker's direction from the camera's beyond
    # 45 degrees: docs/knobs.md, "The marker's side")
    proud = marker_proud(shape)
    if proud > 0:
        cam = (np.linalg.inv(T_c) @ np.append(T_wc[:3, 3], 1.0))[:3]
        v = cam[:2] - np.asarray(center, dtype=float)
        if cam[2] > 1e-6 and np.hypot(*v) > 1e-9:
            sweep = v * (proud / cam[2])             # towards the camera, proud * tan(obliquity)
            disc = np.concatenate([disc + f * sweep for f in (0.0, 0.5, 1.0)])
    alphas = np.radians(np.arange(0.0, 360.0, step_deg))
    mx, my = -rho_d * np.sin(alphas + a0), rho_d * np.cos(alphas + a0)
    X = (mx[:, None] + disc[None, :, 0]) * rho + c
    Y = c - (my[:, None] + disc[None, :, 1]) * rho
    S = cv2.remap(D, X.astype(np.float32), Y.astype(np.float32), cv2.INTER_LINEAR).mean(1)
    return alphas, S, noise
