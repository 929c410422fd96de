"""The semantic draft of a home from its fused point cloud (Rusu et al., seed 001; RAMCIP 3.2).

Pure functions over arrays: ``points_map`` (N, 3) in the map frame (z up, floor at z = 0,
metres), ``normals_map`` (N, 3) unit normals facing free space, ``colors`` (N, 3) in 0..1.

The stages, each a function:

1. ``find_rooms``: floor points (horizontal, at z = 0) on a top-down grid; each connected
   piece of free floor is a room. Its outline is the best rectangle (the world format's rooms
   are rectangles with a pose): the yaw from the walls' normals (modulo 90 degrees) and each
   side at the median of the wall points facing into the room, taken in a band of height
   where only walls stand (above every piece of furniture, below the ceiling).
2. ``find_objects``: what stands on the floor inside a room, not wall nor ceiling, on a
   top-down grid: each connected footprint is a large object. Its box (``ObjectDraft``): the
   yaw from its vertical faces' normals (else the footprint's minimum-area rectangle), each
   side at its face plane where a face looks that way, else at the points' extreme.
3. ``find_fixtures``: on each side face and on the top, the front-most surface on a grid;
   what stands more than ``fixture_min`` proud of its median surroundings is a fixture: an
   elongated, thin one is a bar handle (its axis vertical or horizontal), a small round one a
   knob (radius and depth measured). The front is the side with the most fixtures, else the
   side away from the nearest wall, else the one showing the most horizontal levels.
4. The types: hearth/mapping/classify.py (features of each object, a classifier trained on
   generated homes, as Rusu trained on simulated kitchens).
5. ``articulate``: parts from the fixtures and the type: a drawer unit's handles each give a
   drawer; an oven's or cooker's horizontal handle a door hinged at the bottom; any other
   handle a door hinged on the edge away from its handle (two handles side by side: two
   doors, each hinged at its outer edge; stacked handles: doors one over the other).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hearth.perception.errors import PerceptionError


@dataclass(frozen=True)
class DraftConfig:
    """Settings of the draft (metres, radians)."""
    floor_band: float = 0.03           #: floor points: |z| under this, normal up
    room_grid: float = 0.05            #: top-down grid of the rooms
    min_room_area: float = 1.5         #: m^2 of seen floor
    wall_band: tuple = (2.15, 2.42)    #: heights where only walls stand (walls 2.5 high)
    wall_margin: float = 0.015         #: points this near a room side are wall
    #: points this near a room side are wall whatever their normal (the outline is good to a
    #: centimetre or two; furniture stands at least a centimetre off the wall)
    wall_strip: float = 0.025
    object_grid: float = 0.01          #: top-down grid of the objects
    object_min_area: float = 0.03      #: m^2 of footprint
    object_min_height: float = 0.25
    max_object_height: float = 2.14
    fixture_grid: float = 0.01
    fixture_window: float = 0.15       #: the surroundings a fixture stands out of
    fixture_min: float = 0.012         #: proud of its surroundings by at least
    handle_min_length: float = 0.07
    handle_max_width: float = 0.065
    handle_min_elongation: float = 1.8
    knob_max_size: float = 0.10
    #: a bar handle's radius: 1 cm voxels cannot measure it; the front of the bar is seen and
    #: its axis put this far behind (the middle of the 5-15 mm of household bar handles)
    handle_radius: float = 0.009
    ridge_band: float = 0.006          #: a handle's ridge: cells this near its front-most


# -- results ------------------------------------------------------------------------------------

@dataclass
class RoomDraft:
    """A rectangular room: centre and yaw in the map frame, size along its own x and y."""
    x: float
    y: float
    yaw: float
    size_x: float
    size_y: float
    floor_area: float

    def corners(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        R = np.array([[c, -s], [s, c]])
        hx, hy = self.size_x / 2, self.size_y / 2
        return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ R.T + (self.x, self.y)

    def to_local(self, xy: np.ndarray) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        d = np.asarray(xy, dtype=float)[..., :2] - (self.x, self.y)
        return np.stack([d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c], -1)


@dataclass
class Fixture:
    """A handle or knob on a side (``side``: 0..3 the box's +x, +y, -x, -y face; 4 the top).
    ``position_map``: its centre (a handle's bar axis, a knob's back face on the panel) in
    the map frame; ``u``, ``v``: across the face (m from the face's centre, v up; on the top
    u across and v towards the back); ``vertical``: a handle along v."""
    kind: str
    side: int
    position_map: np.ndarray
    u: float
    v: float
    length: float
    width: float
    depth: float
    vertical: bool = False


@dataclass
class PartDraft:
    """A door or drawer of an object (object frame, front towards +x): ``hinge`` "+y" or
    "-y" (the edge of the face it turns about), "bottom" (doors) or "" (drawers), the face's y0..y1 and z0..z1 and its handle."""
    kind: str
    hinge: str
    y0: float
    y1: float
    z0: float
    z1: float
    handle: Optional[Fixture] = None


@dataclass
class ObjectDraft:
    """A large object: its box (centre, yaw of its front, size along its front axis x and
    across y, z from ``z0`` to ``z1``), the points it was found from, its fixtures."""
    room: int
    x: float
    y: float
    yaw: float
    size_x: float
    size_y: float
    z0: float
    z1: float
    index: np.ndarray = field(repr=False)
    fixtures: list = field(default_factory=list)
    front_known: bool = False
    wall_distance: float = math.inf
    levels: list = field(default_factory=list)
    fill: float = 1.0
    type: str = ""
    confidence: float = 0.0
    parts: list = field(default_factory=list)

    def R(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, -s], [s, c]])

    def to_local(self, xy: np.ndarray) -> np.ndarray:
        return (np.asarray(xy, dtype=float)[..., :2] - (self.x, self.y)) @ self.R()

    def footprint(self) -> np.ndarray:
        hx, hy = self.size_x / 2, self.size_y / 2
        return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ self.R().T + (self.x, self.y)


# -- stage 1: rooms -----------------------------------------------------------------------------

def _grid_index(xy: np.ndarray, origin: np.ndarray, cell: float) -> np.ndarray:
    return np.floor((xy - origin) / cell).astype(np.int64)


def _dominant_yaw(normals_xy: np.ndarray) -> float:
    """The yaw (modulo 90 degrees, in (-45, 45]) the horizontal normals line up with."""
    a = np.arctan2(normals_xy[:, 1], normals_xy[:, 0])
    w = np.hypot(normals_xy[:, 0], normals_xy[:, 1])
    m = np.sum(w * np.exp(4j * a))
    yaw = float(np.angle(m)) / 4
    # refine on the normals within 10 degrees of the first estimate (outliers out)
    d = np.angle(np.exp(4j * (a - yaw))) / 4
    keep = np.abs(d) < math.radians(10)
    if keep.sum() > 10:
        yaw += float(np.median(d[keep]))
    return yaw


def find_rooms(points_map: np.ndarray, normals_map: np.ndarray,
               cfg: DraftConfig = DraftConfig()) -> tuple[list[RoomDraft], np.ndarray]:
    """Rooms (see the module docstring) and, per point, the index of its room (-1: none)."""
    from scipy import ndimage
    P, N = np.asarray(points_map, float), np.asarray(normals_map, float)
    if len(P) == 0:
        raise PerceptionError("the fused map has no points")
    floor = (np.abs(P[:, 2]) < cfg.floor_band) & (N[:, 2] > 0.9)
    if floor.sum() < 100:
        raise PerceptionError("the fused map shows no floor (no horizontal points at z = 0)")
    origin = P[floor, :2].min(0) - 1.0
    ij = _grid_index(P[floor, :2], origin, cfg.room_grid)
    shape = tuple(ij.max(0) + 3)
    occ = np.zeros(shape, bool)
    occ[ij[:, 0], ij[:, 1]] = True
    occ = ndimage.binary_closing(occ, np.ones((3, 3)), iterations=2)
    labels, n = ndimage.label(occ)
    vertical = (P[:, 2] > 0.1) & (P[:, 2] < cfg.wall_band[1]) & (np.abs(N[:, 2]) < 0.3)
    vidx = np.flatnonzero(vertical)
    vij = _grid_index(P[vidx, :2], origin, cfg.room_grid)
    inside_grid = np.all((vij >= 0) & (vij < shape), axis=1)
    vidx, vij = vidx[inside_grid], vij[inside_grid]
    rooms: list[RoomDraft] = []
    room_of = np.full(len(P), -1, np.int64)
    for k in range(1, n + 1):
        mask = labels == k
        area = float(mask.sum()) * cfg.room_grid ** 2
        if area < cfg.min_room_area:
            continue
        near = ndimage.binary_dilation(mask, np.ones((3, 3)), iterations=int(0.3 / cfg.room_grid))
        widx = vidx[near[vij[:, 0], vij[:, 1]]]
        cells = np.argwhere(mask) * cfg.room_grid + origin + cfg.room_grid / 2
        if len(widx) < 200:
            continue
        # the walls and most furniture line up with the room: the yaw of all vertical faces
        yaw = _dominant_yaw(N[widx, :2])
        c, s = math.cos(yaw), math.sin(yaw)
        uv = P[widx, :2] @ np.array([[c, -s], [s, c]])
        nuv = N[widx, :2] @ np.array([[c, -s], [s, c]])
        fuv = cells @ np.array([[c, -s], [s, c]])
        sides = []
        for ax in (0, 1):
            f_lo, f_hi = np.percentile(fuv[:, ax], [0.5, 99.5])
            lo = _wall_plane(uv[nuv[:, ax] > 0.9, ax], +1, f_lo, cfg)
            hi = _wall_plane(uv[nuv[:, ax] < -0.9, ax], -1, f_hi, cfg)
            sides.append((f_lo if lo is None else lo, f_hi if hi is None else hi))
        (u0, u1), (v0, v1) = sides
        cu, cv = (u0 + u1) / 2, (v0 + v1) / 2
        cx, cy = c * cu - s * cv, s * cu + c * cv
        yaw, sx, sy = _tidy_yaw(yaw, u1 - u0, v1 - v0)
        room = RoomDraft(cx, cy, yaw, sx, sy, area)
        q = room.to_local(P[:, :2])
        inside = (np.abs(q[:, 0]) <= sx / 2 + 0.05) & (np.abs(q[:, 1]) <= sy / 2 + 0.05)
        room_of[inside & (room_of < 0)] = len(rooms)
        rooms.append(room)
    if not rooms:
        raise PerceptionError("no room found in the fused map (no floor with walls around it)")
    return rooms, room_of


def _wall_plane(coord: np.ndarray, facing: int, floor_edge: float, cfg: DraftConfig
                ) -> Optional[float]:
    """A wall facing ``facing`` (+1: into +axis) near the floor's edge ``floor_edge``: of the
    vertical points facing that way within 30 cm of it, the outermost 1 cm slab with a wall's
    worth of points (furniture faces stand further in)."""
    sel = coord[np.abs(coord - floor_edge) < 0.3]
    if len(sel) < 100:
        return None
    edges = np.arange(floor_edge - 0.305, floor_edge + 0.31, 0.01)
    h, e = np.histogram(sel, edges)
    need = max(100, 0.25 * h.max())
    good = np.flatnonzero(h >= need)
    if len(good) == 0:
        return None
    k = good[0] if facing > 0 else good[-1]
    slab = sel[(sel >= e[k] - 0.01) & (sel < e[k + 1] + 0.01)]
    return float(np.median(slab))


def _tidy_yaw(yaw: float, sx: float, sy: float) -> tuple[float, float, float]:
    """A rectangle's yaw in [0, pi/2) with its sizes swapped to match (the same rectangle)."""
    yaw = math.remainder(yaw, math.pi)
    if yaw < 0:
        yaw += math.pi
    if yaw >= math.pi / 2:
        return yaw - math.pi / 2, sy, sx
    return yaw, sx, sy


# -- stage 2: large objects ---------------------------------------------------------------------

def find_objects(points_map: np.ndarray, normals_map: np.ndarray, rooms: list[RoomDraft],
                 room_of: np.ndarray, cfg: DraftConfig = DraftConfig()) -> list[ObjectDraft]:
    """The large objects of every room (see the module docstring), boxes without a front."""
    from scipy import ndimage
    P, N = np.asarray(points_map, float), np.asarray(normals_map, float)
    out: list[ObjectDraft] = []
    for r, room in enumerate(rooms):
        q = room.to_local(P[:, :2])
        inner = ((np.abs(q[:, 0]) < room.size_x / 2 - cfg.wall_margin)
                 & (np.abs(q[:, 1]) < room.size_y / 2 - cfg.wall_margin))
        # wall surface: within 5 cm of a side and facing away from it (furniture standing
        # against a wall shows it its sides and top, never a face parallel to it)
        c, s_ = math.cos(room.yaw), math.sin(room.yaw)
        nq = N[:, :2] @ np.array([[c, -s_], [s_, c]])
        gx, gy = room.size_x / 2 - np.abs(q[:, 0]), room.size_y / 2 - np.abs(q[:, 1])
        wall = (((gx < 0.08) & (np.abs(nq[:, 0]) > 0.7)) | ((gy < 0.08) & (np.abs(nq[:, 1]) > 0.7))
                | (np.minimum(gx, gy) < cfg.wall_strip))
        inner &= ~wall
        sel = np.flatnonzero((room_of == r) & inner & (P[:, 2] > cfg.floor_band)
                             & (P[:, 2] < cfg.max_object_height))
        if len(sel) == 0:
            continue
        origin = np.array([-room.size_x / 2, -room.size_y / 2])
        ij = _grid_index(q[sel], origin, cfg.object_grid)
        shape = (int(room.size_x / cfg.object_grid) + 2, int(room.size_y / cfg.object_grid) + 2)
        ij = np.clip(ij, 0, np.array(shape) - 1)
        occ = np.zeros(shape, bool)
        occ[ij[:, 0], ij[:, 1]] = True
        # a closing of one cell joins the sparse sides of a tall object seen from below its
        # top, and leaves a gap of two cells (furniture stands 3 cm apart or more) open
        occ = ndimage.binary_closing(occ, np.ones((2, 2)))
        labels, n = ndimage.label(occ, np.ones((3, 3)))
        areas = ndimage.sum(occ, labels, np.arange(1, n + 1)) * cfg.object_grid ** 2
        lab = labels[ij[:, 0], ij[:, 1]]
        for k in range(1, n + 1):
            idx = sel[lab == k]
            if len(idx) < 200 or areas[k - 1] < cfg.object_min_area:
                continue
            z = P[idx, 2]
            if np.percentile(z, 99.5) < cfg.object_min_height:
                continue
            obj = _box(P, N, idx, r, room, cfg)
            obj.fill = float(areas[k - 1] / max(obj.size_x * obj.size_y, 1e-6))
            out.append(obj)
    return out


def _face_plane(coord: np.ndarray, normal_along: np.ndarray, sign: int) -> Optional[float]:
    """Where the face looking ``sign`` along an axis lies: the most populated 1 cm slab of the
    points whose normal looks that way, if enough of them."""
    sel = coord[sign * normal_along > 0.9]
    if len(sel) < 60:
        return None
    edges = np.arange(sel.min() - 0.005, sel.max() + 0.015, 0.01)
    if len(edges) < 2:
        return float(np.median(sel))
    h, e = np.histogram(sel, edges)
    # the outermost slab holding at least 40% of the best one's points: the face, not a shelf
    good = np.flatnonzero(h >= 0.4 * h.max())
    k = good[-1] if sign > 0 else good[0]
    inslab = sel[(sel >= e[k] - 0.005) & (sel < e[k + 1] + 0.005)]
    return float(np.median(inslab))


def _box(P, N, idx, r, room: RoomDraft, cfg: DraftConfig) -> ObjectDraft:
    import cv2
    xy, n = P[idx, :2], N[idx]
    vert = np.abs(n[:, 2]) < 0.3
    if vert.sum() > 100:
        yaw = _dominant_yaw(n[vert, :2])
    else:
        (_, _), (_, _), ang = cv2.minAreaRect(xy.astype(np.float32))
        yaw = math.radians(ang)
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s], [s, c]])
    uv = xy @ R
    nuv = n[:, :2] @ R
    sides = []
    for ax in (0, 1):
        lo_e, hi_e = np.percentile(uv[:, ax], [0.3, 99.7])
        lo = _face_plane(uv[:, ax], nuv[:, ax], -1)
        hi = _face_plane(uv[:, ax], nuv[:, ax], +1)
        lo = lo if lo is not None and lo < lo_e + 0.1 else lo_e
        hi = hi if hi is not None and hi > hi_e - 0.1 else hi_e
        sides.append((lo, hi))
    (u0, u1), (v0, v1) = sides
    cu, cv = (u0 + u1) / 2, (v0 + v1) / 2
    z = P[idx, 2]
    z0 = float(np.percentile(z, 0.2))
    z0 = 0.0 if z0 < 0.08 else z0
    obj = ObjectDraft(r, c * cu - s * cv, s * cu + c * cv, yaw, u1 - u0, v1 - v0, z0,
                      float(np.percentile(z, 99.8)), idx)
    corners = room.to_local(obj.footprint())
    gaps = np.concatenate([room.size_x / 2 - np.abs(corners[:, 0]),
                           room.size_y / 2 - np.abs(corners[:, 1])])
    obj.wall_distance = float(max(gaps.min(), 0.0))
    hz = P[idx][N[idx, 2] > 0.9, 2]
    obj.levels = _levels(hz)
    return obj


def _levels(z_horizontal: np.ndarray, min_points: int = 80) -> list[float]:
    """Heights of the horizontal surfaces (peaks of a 1 cm histogram)."""
    if len(z_horizontal) == 0:
        return []
    edges = np.arange(0.0, z_horizontal.max() + 0.02, 0.01)
    if len(edges) < 2:
        return []
    h, e = np.histogram(z_horizontal, edges)
    out = []
    for k in range(len(h)):
        if h[k] >= min_points and h[k] == h[max(0, k - 3):k + 4].max():
            if not out or e[k] - out[-1] > 0.04:
                out.append(float(e[k] + 0.005))
    return out


# -- stage 3: fixtures and the front ------------------------------------------------------------

_SIDE_DIRS = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]


def find_fixtures(points_map: np.ndarray, obj: ObjectDraft, cfg: DraftConfig = DraftConfig()
                  ) -> list[Fixture]:
    """Handles and knobs on the object's four sides and its top (map frame positions)."""
    P = np.asarray(points_map, float)[obj.index]
    loc = obj.to_local(P[:, :2])
    out = []
    half = (obj.size_x / 2, obj.size_y / 2, obj.size_x / 2, obj.size_y / 2)
    for side, (dx, dy) in enumerate(_SIDE_DIRS):
        d = loc[:, 0] * dx + loc[:, 1] * dy - half[side]      # out of the face (m)
        u = -loc[:, 0] * dy + loc[:, 1] * dx                  # across, left to right seen... +90 deg
        width = obj.size_y if side % 2 == 0 else obj.size_x
        sel = ((d > -0.03) & (d < 0.12) & (np.abs(u) < width / 2 - 0.015)
               & (P[:, 2] > obj.z0 + 0.015) & (P[:, 2] < obj.z1 - 0.015))
        if sel.sum() < 50:
            continue
        for f in _merge_bars(_proud(u[sel], P[sel, 2], d[sel], cfg)):
            kind, fu, fv, length, width, depth, vertical = f
            nrm = np.array([dx, dy])
            along = np.array([-dy, dx])
            xy_local = nrm * (half[side] + depth) + along * fu
            xy = obj.R() @ xy_local + (obj.x, obj.y)
            out.append(Fixture(kind, side, np.array([xy[0], xy[1], fv]), float(fu), float(fv),
                               length, width, depth, vertical))
    # the top: knobs near its edges (a hob's)
    top = P[:, 2] > obj.z1 - 0.12
    if top.sum() > 50:
        for f in _proud(loc[top, 1], loc[top, 0], P[top, 2] - obj.z1 + 0.0, cfg, top_face=True):
            kind, fu, fv, length, width, depth, vertical = f
            if kind != "knob":
                continue
            xy = obj.R() @ np.array([fv, fu]) + (obj.x, obj.y)
            plate = float(np.percentile(P[top, 2], 60))
            out.append(Fixture("knob", 4, np.array([xy[0], xy[1], plate]),
                               float(fu), float(fv), length, width, depth))
    return out


def _proud(u: np.ndarray, v: np.ndarray, d: np.ndarray, cfg: DraftConfig, top_face=False):
    """Fixtures on one face: (kind, u, v, length, width, depth, vertical) of each blob that
    stands ``fixture_min`` out of the median of its surroundings on a height map."""
    from scipy import ndimage
    g = cfg.fixture_grid
    if top_face:
        # the top's surface: the hob plate at the highest level; the knobs stand on it
        base = float(np.percentile(d, 60))
        d = d - base
    iu = np.floor((u - u.min()) / g).astype(int)
    iv = np.floor((v - v.min()) / g).astype(int)
    H = np.full((iu.max() + 1, iv.max() + 1), np.nan)
    order = np.argsort(d)
    H[iu[order], iv[order]] = d[order]                       # the front-most per cell
    seen = ~np.isnan(H)
    if seen.sum() < 30:
        return []
    filled = np.where(seen, H, np.nanmin(H))
    w = max(3, int(cfg.fixture_window / g) | 1)
    bg = ndimage.median_filter(filled, size=w)
    # the surroundings must be a surface the camera saw (not the unseen edge of the face)
    seen_frac = ndimage.uniform_filter(seen.astype(float), size=w)
    proud = seen & (filled - bg > cfg.fixture_min) & (seen_frac > 0.6)
    labels, n = ndimage.label(proud, np.ones((3, 3)))
    out = []
    for k in range(1, n + 1):
        cells = np.argwhere(labels == k)
        if len(cells) < 4:
            continue
        cu = cells[:, 0] * g + u.min() + g / 2
        cv = cells[:, 1] * g + v.min() + g / 2
        ext_u, ext_v = np.ptp(cu) + g, np.ptp(cv) + g
        length, width = max(ext_u, ext_v), min(ext_u, ext_v)
        base = float(np.median(bg[cells[:, 0], cells[:, 1]]))
        top = float(np.percentile(filled[cells[:, 0], cells[:, 1]], 90))
        if (length >= cfg.handle_min_length and width <= cfg.handle_max_width and length < 1.0
                and length / width >= cfg.handle_min_elongation):
            # the bar is the front-most ridge of its blob: the fusion smears a thin bar along
            # the rays that passed it (downwards, seen from a head above it), so the centre is
            # taken over the cells near the ridge's height only
            ridge = filled[cells[:, 0], cells[:, 1]] >= top - cfg.ridge_band
            ridge = ridge if ridge.sum() >= 3 else np.ones(len(cells), bool)
            vertical = ext_v > ext_u
            # along the bar: the middle of its extent; across: the ridge's mean
            mu = (cu.min() + cu.max()) / 2 if not vertical else float(np.mean(cu[ridge]))
            mv = (cv.min() + cv.max()) / 2 if vertical else float(np.mean(cv[ridge]))
            out.append(("handle", float(mu), float(mv), float(length), float(width),
                        top - cfg.handle_radius, vertical))
        elif length <= cfg.knob_max_size and width >= 0.02 and length / width < cfg.handle_min_elongation:
            out.append(("knob", float(np.mean(cu)), float(np.mean(cv)), float(length),
                        float(width), base, False))
    return out


def _merge_bars(found: list) -> list:
    """Pieces of one bar handle (a long bar is sometimes fused in pieces) joined: handles in
    line (within 2.5 cm across, the same way) with a gap under 12 cm between them."""
    bars = [f for f in found if f[0] == "handle"]
    rest = [f for f in found if f[0] != "handle"]
    merged = True
    while merged:
        merged = False
        for i in range(len(bars)):
            for j in range(i + 1, len(bars)):
                a, b = bars[i], bars[j]
                if a[6] != b[6]:
                    continue
                across = abs(a[1] - b[1]) if a[6] else abs(a[2] - b[2])
                pa, pb = (a[2], b[2]) if a[6] else (a[1], b[1])
                gap = abs(pa - pb) - (a[3] + b[3]) / 2
                if across > 0.025 or gap > 0.12:
                    continue
                lo = min(pa - a[3] / 2, pb - b[3] / 2)
                hi = max(pa + a[3] / 2, pb + b[3] / 2)
                mid = (lo + hi) / 2
                other = (a[1] * a[3] + b[1] * b[3]) / (a[3] + b[3]) if a[6] else \
                    (a[2] * a[3] + b[2] * b[3]) / (a[3] + b[3])
                fu, fv = (other, mid) if a[6] else (mid, other)
                bars[i] = ("handle", fu, fv, hi - lo, max(a[4], b[4]), max(a[5], b[5]), a[6])
                bars.pop(j)
                merged = True
                break
            if merged:
                break
    return bars + rest


def choose_front(obj: ObjectDraft, room: RoomDraft) -> None:
    """Turn the box so that its front (+x) is the side with the most fixtures, else the side
    away from the nearest wall; sets ``front_known``."""
    counts = np.zeros(4)
    for f in obj.fixtures:
        if f.side < 4:
            counts[f.side] += 1.0 if f.kind == "handle" else 0.5
    if counts.max() > 0:
        side = int(np.argmax(counts))
        obj.front_known = True
    else:
        corners_far = []
        for side, (dx, dy) in enumerate(_SIDE_DIRS):
            half = obj.size_x / 2 if side % 2 == 0 else obj.size_y / 2
            p = obj.R() @ (np.array([dx, dy]) * (half + 0.5)) + (obj.x, obj.y)
            q = room.to_local(p)
            corners_far.append(min(room.size_x / 2 - abs(q[0]), room.size_y / 2 - abs(q[1])))
        # the side whose outward point is deepest inside the room looks into it
        side = int(np.argmax(corners_far))
        obj.front_known = obj.wall_distance < 0.12
    _turn(obj, side)


def _turn(obj: ObjectDraft, side: int) -> None:
    """Make side ``side`` (0..3) the box's +x: yaw turns by side * 90 degrees."""
    if side == 0:
        return
    obj.yaw = math.remainder(obj.yaw + side * math.pi / 2, 2 * math.pi)
    if side % 2 == 1:
        obj.size_x, obj.size_y = obj.size_y, obj.size_x
    for f in obj.fixtures:
        if f.side < 4:
            f.side = (f.side - side) % 4


# -- stage 5: parts -----------------------------------------------------------------------------

def handle_rows(handles: list) -> list[list]:
    """Handles grouped into rows, in the order given: a handle joins the first row whose first
    handle is within 15 cm of its height, else starts a row."""
    rows: list[list] = []
    for h in handles:
        for row in rows:
            if abs(row[0].v - h.v) < 0.15:
                row.append(h)
                break
        else:
            rows.append([h])
    return rows


def articulate(obj: ObjectDraft) -> list[PartDraft]:
    """Doors and drawers of a classified object with its front chosen (object frame: the
    front face at x = size_x / 2, y across, z up; see the module docstring)."""
    handles = sorted((f for f in obj.fixtures if f.kind == "handle" and f.side == 0),
                     key=lambda f: f.v)
    if not handles:
        return []
    w = obj.size_y / 2
    bottom = obj.z0 + 0.04 if obj.z0 == 0.0 else obj.z0
    top = obj.z1
    if obj.type == "drawers":
        parts, z = [], bottom
        for i, h in enumerate(handles):
            z1 = top if i == len(handles) - 1 else (h.v + handles[i + 1].v) / 2
            parts.append(PartDraft("drawer", "", -w, w, z, z1, h))
            z = z1
        return parts
    if obj.type in ("oven", "cooker"):
        h = max(handles, key=lambda f: f.length)
        return [PartDraft("door", "bottom", -w, w, bottom, h.v + 0.06, h)]
    # side-hinged doors (a fixture's u on the front is the object's y)
    rows = handle_rows(handles)
    parts = []
    for k, row in enumerate(rows):
        z0 = bottom if k == 0 else (rows[k - 1][0].v + row[0].v) / 2
        z1 = top if k == len(rows) - 1 else (row[0].v + rows[k + 1][0].v) / 2
        if len(row) == 1:
            h = row[0]
            hinge = "+y" if h.u < 0 else "-y"        # the hinge on the edge away from the handle
            parts.append(PartDraft("door", hinge, -w, w, z0, z1, h))
        else:
            row.sort(key=lambda f: f.u)
            cuts = [-w] + [(a.u + b.u) / 2 for a, b in zip(row, row[1:])] + [w]
            for i, h in enumerate(row):
                mid = (cuts[i] + cuts[i + 1]) / 2
                hinge = "+y" if h.u < mid else "-y"
                parts.append(PartDraft("door", hinge, cuts[i], cuts[i + 1], z0, z1, h))
    return parts


# -- the whole draft ----------------------------------------------------------------------------

@dataclass
class Draft:
    rooms: list
    objects: list
    unlabelled: list = field(default_factory=list)     #: (what, why) the draft could not label


def draft_geometry(points_map, normals_map, cfg: DraftConfig = DraftConfig()) -> Draft:
    """Stages 1-3: rooms, object boxes with their fixtures and fronts (no types yet)."""
    rooms, room_of = find_rooms(points_map, normals_map, cfg)
    objects = find_objects(points_map, normals_map, rooms, room_of, cfg)
    for obj in objects:
        obj.fixtures = find_fixtures(points_map, obj, cfg)
        choose_front(obj, rooms[obj.room])
    return Draft(rooms, objects)
