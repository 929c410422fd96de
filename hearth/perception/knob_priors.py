"""What the map says of each knob, as the reader needs it (``KnobPrior``, ``knob_priors``): its
frame, outline, states, travel, and what of it stands whatever its angle (``standing_profile``,
``near_round``). The method is described in hearth/perception/knobs.py."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hearth.perception.knob_shapes import KnobShape, knob_shape


@dataclass(frozen=True)
class KnobPrior:
    """What the map says of one knob: its frame at angle 0 in the world (registered or
    believed), its outline radius and face height (m, from its shape), its discrete states
    (names, angles in rad), its shape's key and symmetry, and its travel (``(lo, hi)`` rad:
    the angles it can stand at, from its off state through its settings the way it turns;
    None: any)."""
    knob_id: str
    T_world_knob: np.ndarray
    radius: float
    depth: float
    state_names: tuple[str, ...]
    state_angles: tuple[float, ...]
    shape: str = ""
    symmetry: int = 1
    travel: Optional[tuple[float, float]] = None
    off_state: str = ""
    #: what of the knob stands at every angle (``standing_profile``): ((radius, top height)
    #: m, ...) per visual but the markers; () unknown (a cylinder of the outline assumed)
    profile: tuple = ()
    #: the knob's body is ridged and otherwise round about its axis (``near_round``: a
    #: knurl): only its marker says its angle, and its ridges fit well at other angles
    round_grip: bool = False

    def T_world_face(self) -> np.ndarray:
        """The knob's front face (z = depth) at angle 0."""
        T = self.T_world_knob.copy()
        T[:3, 3] = T[:3, 3] + T[:3, 2] * self.depth
        return T

    def canvas_frame(self, T_world_camera: np.ndarray, aligned: bool = True) -> tuple[np.ndarray, float]:
        """The face frame turned by ``psi`` about the knob's axis so that its +y points towards
        the camera (projected on the face plane), and ``psi`` (rad); (face frame, 0) when not
        ``aligned``. A marker at knob angle a is at a - psi in this frame."""
        T = self.T_world_face()
        if not aligned:
            return T, 0.0
        v = T_world_camera[:3, 3] - T[:3, 3]
        ux, uy = float(T[:3, 0] @ v), float(T[:3, 1] @ v)
        if math.hypot(ux, uy) < 1e-9:
            return T, 0.0
        psi = math.atan2(-ux, uy)
        R = np.eye(4)
        c, s = math.cos(psi), math.sin(psi)
        R[:2, :2] = [[c, -s], [s, c]]
        return T @ R, psi


def knob_travel(knob) -> Optional[tuple[float, float]]:
    """The angles (rad, ``lo <= hi``) a knob that turns one way (``Knob.turns``) can stand
    at: from its off state through every setting that way; None for one that turns either
    way (or a symmetric one whose travel covers its period)."""
    if knob.turns == "either":
        return None
    sign = -1.0 if knob.turns == "clockwise" else 1.0
    off = knob.state_angle(knob.off)
    reach = max(((sign * (s.angle - off)) % (2 * math.pi)) for s in knob.states)
    if reach >= 2 * math.pi / knob.symmetry - 1e-9:
        return None
    lo, hi = sorted((off, off + sign * reach))
    return lo, hi


def knob_priors(world, object_id: Optional[str] = None,
                T_world_object: Optional[np.ndarray] = None) -> list[KnobPrior]:
    """Priors of every knob in the map (or of one object's knobs). ``T_world_object``: the
    object's registered pose, when it differs from the map's."""
    out = []
    lib = world.apartment.library
    for k in world.knobs(object_id):
        T_wp = world.T_world(world.parent(k.id).id)
        if T_world_object is not None and object_id is not None:
            T_wp = T_world_object @ np.linalg.inv(world.T_world(object_id)) @ T_wp
        s = _shape_of(k, lib, world.base_dir)
        out.append(KnobPrior(k.id, T_wp @ k.pose.matrix(), s.radius, s.face,
                             tuple(x.name for x in k.states), tuple(float(x.angle) for x in k.states),
                             s.key, s.symmetry, knob_travel(k), k.off, standing_profile(s),
                             near_round(s)))
    return out


def near_round(shape: KnobShape, tol: float = 0.1) -> bool:
    """Whether a knob's body (every visual but the markers) is ridged and otherwise round
    about its axis: within ``tol`` of its outline radius at every height, and more than 2 %
    off a circle somewhere (a knurled ring, its ridges a few per cent deep). Its angle rests
    on its marker alone, a small part of the knob, while its ridges fit well every 12-22
    degrees, away from the marker's angle. A plain cylinder or a taper (round within 2 %)
    is not such a knob (its body fits alike at every angle: the marker decides), nor is a
    symmetric shape or one without a marker."""
    if shape.symmetry != 1 or "marker" not in shape.roles:
        return False
    ridged = False
    for v, role in zip(shape.vertices, shape.roles):
        if role == "marker":
            continue
        for z in np.unique(np.round(v[:, 2], 4)):
            ring = v[np.abs(v[:, 2] - z) < 5e-5]
            rad = np.hypot(ring[:, 0], ring[:, 1])
            rim = rad > 0.5 * rad.max()
            if not rim.any():
                continue
            if (np.ptp(rad[rim]) > tol * shape.radius or abs(ring[rim, 0].mean()) > tol * shape.radius
                    or abs(ring[rim, 1].mean()) > tol * shape.radius):
                return False
            ridged |= bool(np.ptp(rad[rim]) > 0.02 * shape.radius)
    return ridged


def standing_profile(shape: KnobShape) -> tuple:
    """What of a knob stands out of its panel whatever its angle: for each visual but the
    markers, the radius of the largest disc about the axis inside its outline on the face
    plane (a round cap's rim, a bar's half width, 0 where the visual does not cover the axis)
    and its top's height (m). A bar grip 8 mm wide on a 2 mm bezel stands 4 mm about the axis
    at its full height and over the whole bezel 2 mm: the knob panel's match looks for that,
    not for a cylinder of the outline (knob_panel)."""
    from scipy.spatial import ConvexHull, QhullError
    out = []
    for v, role in zip(shape.vertices, shape.roles):
        if role == "marker" or len(v) < 3:
            continue
        xy = np.asarray(v[:, :2], dtype=float)
        try:
            P = xy[ConvexHull(xy).vertices]
        except (QhullError, ValueError):
            continue
        E = np.roll(P, -1, axis=0) - P
        cross = E[:, 0] * (-P[:, 1]) - E[:, 1] * (-P[:, 0])      # origin left of every edge: inside
        L = np.hypot(E[:, 0], E[:, 1])
        ok = L > 1e-9
        inside = bool(np.all(cross[ok] >= -1e-9))
        r_in = float(np.min(np.abs(cross[ok]) / L[ok])) if inside and ok.any() else 0.0
        out.append((round(r_in, 5), round(float(v[:, 2].max()), 5)))
    return tuple(out)


_SHAPES: dict = {}


def canon(value, drop: frozenset = frozenset()):
    """A JSON-able, rounded copy of map nodes (dataclasses) without ``line`` fields, and
    without the fields of ``value`` itself named in ``drop``."""
    from dataclasses import fields, is_dataclass
    if is_dataclass(value):
        return {f.name: canon(getattr(value, f.name)) for f in fields(value)
                if f.name != "line" and f.name not in drop}
    if isinstance(value, (list, tuple)):
        return [canon(v) for v in value]
    if isinstance(value, float):
        return round(value, 6)
    return value


def _shape_of(knob, library, base_dir) -> KnobShape:
    """``knob_shape``, cached by what it is made of (a map's knobs are read again and again)."""
    key = repr((canon([knob.radius, knob.depth, knob.base, knob.grip, knob.marker,
                        knob.base_fixed, knob.symmetry, knob.described]),
                canon([library.get(m.ref) for m in (knob.base, knob.grip, knob.marker)
                        if m is not None and m.ref]), str(base_dir)))
    if key not in _SHAPES:
        if len(_SHAPES) > 256:
            _SHAPES.clear()
        _SHAPES[key] = knob_shape(knob, library, base_dir)
    return _SHAPES[key]
