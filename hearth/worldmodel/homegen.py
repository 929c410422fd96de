"""Generated homes: valid world files that differ the way real homes do.

``generate_home(seed, config)`` builds a home in memory (a ``World``); ``make_home(seed,
out_dir, config)`` writes it as ``out_dir/world.xml`` with its meshes in ``out_dir/meshes/``.
The same seed and configuration give byte-identical files (one numpy Generator from the seed
drives every choice). docs/world-format.md ("Generated homes") lists what varies.

How a home is made:

1. Rooms (2-5, a kitchen always) of several kinds and sizes; each room's bounds are in its
   own frame, offset from its origin, and the room pose puts it in the world, turned by any
   angle for some rooms; rooms are placed next to each other without overlapping.
2. Furniture, one builder per kind (``table``, ``bookshelf``, ``cupboard``, ``drawer_unit``,
   ``fridge``, ``appliance`` (oven, cooker, hob), ``chair``). A builder makes the object in a
   canonical frame (origin on the floor under its footprint's centre, front towards +x) with
   candidate parking positions, the views every parking position must give (its front, its
   top surface, its shelves, its knob panel) and the points the arm must reach.
3. Layout: each piece is placed with its back to a wall (facing into the room) or free-standing
   at any angle. Its footprint is the convex hull of its meshes (hearth.worldmodel.geometry); it
   must not overlap another footprint, must leave every parking position placed so far free,
   and keeps only the parking positions of its own that are inside the room by the robot
   radius and clear of every footprint.
4. Small objects of several kinds and colours (some close in hue) on, in and under furniture:
   on tables, on lower shelves, inside closed cupboards and fridges, under tables.
5. Some objects are then turned inside their own frame (their front becomes local +y, -x or
   -y) with the pose compensating, so nothing may assume that objects face their local +x.

Meshes (door panels, table tops, shelf sides) are small ASCII PLY files named after their
content. ``generate_home`` writes them into ``mesh_dir`` (default: the cache directory
``$HEARTH_HOMEGEN_DIR``, else ``~/.cache/hearth/homegen``) and sets the world's ``base_dir``
there, so the world can be rendered at once; ``make_home`` writes them next to world.xml.

This module lays out rooms (steps 1 and 3) and makes the home; the rest is in its neighbours:
homegen_config.py (``HomeConfig``, ``HomeGenError``), homegen_palette.py (colours and words),
homegen_pieces.py (what a builder works with and returns, parking positions and ``sees``),
homegen_furniture.py (the builders, step 2), homegen_knobs.py (knob states and designs),
homegen_objects.py (small objects, step 4) and homegen_geometry.py (footprints and meshes).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from hearth.worldmodel.frames import planar_T, transform_xy
from hearth.worldmodel.outline import outline_contains
from hearth.worldmodel.homegen_config import HomeConfig, HomeGenError
from hearth.worldmodel.homegen_furniture import (
    appliance, bookshelf, chair, cupboard, drawer_unit, fridge, table,
)
from hearth.worldmodel.homegen_geometry import (
    convex_hull_xy, disc_clear, polygon_inside_rect, polygons_overlap, transform_polygon,
)
from hearth.worldmodel.homegen_objects import small_objects
from hearth.worldmodel.homegen_pieces import (
    _clean, _Ctx, _deg, _Ids, _keep_visible, _level_compose, _Meshes, _mm, Piece,
)
from hearth.worldmodel.nodes import (
    Apartment, Doorway, LargeArticulatedObject, Model, ParkingPosition, Room, Switch,
)
from hearth.worldmodel.pose import Pose


#: Bump when a seed's home changes (hearth/executive/scenarios.py keeps generated homes per version):
#: 2 = knob designs varied (KNOB_FAMILIES); 3 = a tip or dot stands out from the grip it sits on;
#: 4 = a skirt knob's dot stands 1 mm proud of its cap as built (not level with it on some homes).
#: 5 = knobs drawn from a design space (base, grip, marker, materials, stand-off), off anywhere in the travel;
#: 6 = a low-contrast or dark-on-dark line or dot stands 1.5-3 mm proud (a printed pointer stands out in colour);
#: 7 = a marker sits on its grip's top as built (rounded), not half a millimetre inside it;
#: 8 = the knob panel's place and off mid-travel drawn from the designs' generator (the rest
#:     of a seed's home as in version 4).
#: 9 = a chest's top drawer has a floor (a part surface) that may hold a small object (drawn
#:     from a generator of its own); half the bedroom wardrobes have two sliding doors on one
#:     track with recessed pulls (issue 43, drawers).
#: 10 = rooms joined by doorways (sides facing across the gap between them), some through a
#:     corridor, some L-shaped; the home turned as a whole; furniture leaves every doorway and
#:     parking position reachable (issue 43, rooms). 9 and 10 were made on two branches at the
#:     same time (each without the other's change); the home cache is kept per version, so
#: 11 = both together.
GENERATOR_VERSION = 11


# -- rooms --------------------------------------------------------------------------------------

#: kind -> (width range, depth range, furniture plan: (builder name, probability, args))
ROOM_KINDS = {
    "kitchen": ((3.4, 5.5), (3.0, 4.6)),
    "living room": ((3.8, 6.5), (3.2, 5.0)),
    "bedroom": ((3.0, 4.6), (2.9, 4.2)),
    "bathroom": ((2.2, 3.2), (2.0, 2.9)),
    "study": ((2.8, 4.2), (2.6, 3.6)),
    "dining room": ((3.2, 4.8), (3.0, 4.2)),
}


def _furniture_plan(ctx: _Ctx, kind: str) -> list[tuple[str, Callable[[], Piece], bool]]:
    """(label, builder, required) for a room, in the order they are placed."""
    c = ctx
    P = []

    def add(label, fn, p=1.0, required=False):
        if required or c.chance(p):
            P.append((label, fn, required))

    if kind == "kitchen":
        main = c.pick(["oven", "cooker", "cooker", "hob"])
        k1 = c.i(c.cfg.knobs_per_appliance[0], min(c.cfg.knobs_per_appliance[1], c.knobs_left))
        c.knobs_left -= k1
        add(main, lambda m=main, k=k1: appliance(c, m, k), required=True)
        second = "hob" if main == "oven" else c.pick(["oven", "hob"])
        if c.knobs_left >= max(2, c.cfg.knobs_per_appliance[0]) and c.chance(c.cfg.second_appliance_probability):
            k2 = c.i(max(2, c.cfg.knobs_per_appliance[0]), min(4, c.knobs_left))
            c.knobs_left -= k2
            add(second, lambda m=second, k=k2: appliance(c, m, k))
        add("fridge", lambda: fridge(c), 0.85)
        add("cupboard", lambda: cupboard(c), 1.0)
        add("cupboard", lambda: cupboard(c), 0.5)
        add("cabinet", lambda: cupboard(c, "cabinet"), c.cfg.wall_cabinet_probability)
        add("drawers", lambda: drawer_unit(c), 0.6)
        add("table", lambda: table(c, c.pick(["table", "table", "bar"])), 0.85)
        add("bookshelf", lambda: bookshelf(c), 0.2)
        add("chair", lambda: chair(c), 0.5)
    elif kind == "living room":
        add("table", lambda: table(c, "coffee"), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.4)
        add("sideboard", lambda: cupboard(c, "sideboard"), 0.6)
        add("table", lambda: table(c, "side"), 0.6)
        add("drawers", lambda: drawer_unit(c), 0.3)
        add("chair", lambda: chair(c), 0.3)
    elif kind == "bedroom":
        add("wardrobe", lambda: cupboard(c, "wardrobe", sliding=c.chance(0.5)), 0.85)
        add("drawers", lambda: drawer_unit(c), 0.7)
        add("table", lambda: table(c, "bedside"), 0.5)
        add("drawers", lambda: drawer_unit(c, "bedside"), 0.4)
        add("bookshelf", lambda: bookshelf(c), 0.5)
    elif kind == "bathroom":
        add("cabinet", lambda: cupboard(c, "cabinet"), 0.9)
        add("table", lambda: table(c, "counter"), 0.8)
        add("drawers", lambda: drawer_unit(c), 0.3)
    elif kind == "study":
        add("table", lambda: table(c, "desk"), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.4)
        add("drawers", lambda: drawer_unit(c), 0.6)
        add("cupboard", lambda: cupboard(c), 0.4)
        add("chair", lambda: chair(c), 0.5)
    elif kind == "dining room":
        add("table", lambda: table(c, "dining"), 1.0)
        add("chair", lambda: chair(c), 0.8)
        add("chair", lambda: chair(c), 0.6)
        add("sideboard", lambda: cupboard(c, "sideboard"), 0.7)
        add("bookshelf", lambda: bookshelf(c), 0.3)
    return P


class _Layout:
    """Free floor of one room while its furniture is placed (room frame, metres)."""

    def __init__(self, ctx: _Ctx, bounds, floor: Optional[np.ndarray] = None,
                 missing: list[np.ndarray] = (), doors: list[np.ndarray] = ()):
        self.ctx = ctx
        self.bounds = bounds
        self.floor = _floor_poly(bounds, None) if floor is None else np.asarray(floor, float)
        # Footprints, and the corner an L-shaped room lacks (``missing``): no furniture and
        # no parking position there.
        self.hulls: list[np.ndarray] = [np.asarray(k, float) for k in missing]
        # The approach to each doorway (``doors``): no furniture, but the robot may park
        # there (it is in nobody's way but its own).
        self.doors: list[np.ndarray] = list(doors)
        self.parkings: list[tuple[float, float]] = []

    def parking_free(self, x: float, y: float, extra: list[np.ndarray] = ()) -> bool:
        r = self.ctx.cfg.robot_radius
        x0, y0, x1, y1 = self.bounds
        if not (x0 + r + 0.01 <= x <= x1 - r - 0.01 and y0 + r + 0.01 <= y <= y1 - r - 0.01):
            return False
        return all(disc_clear((x, y), h, r + 0.02) for h in (*self.hulls, *extra))

    def try_place(self, piece: Piece) -> Optional[tuple[float, float, float]]:
        """A room-frame pose (x, y, yaw) for the piece, or None after the configured tries.
        Keeps the piece's free parking positions."""
        ctx = self.ctx
        x0, y0, x1, y1 = self.bounds
        hull = piece.hull
        back = -hull[:, 0].min()
        half_w = max(-hull[:, 1].min(), hull[:, 1].max())
        reach_r = float(np.max(np.hypot(hull[:, 0], hull[:, 1])))
        for _ in range(ctx.cfg.placement_tries):
            if piece.mount == "wall":
                wall = ctx.i(0, 3)
                # inward normal yaw and the wall line, per wall: x0, x1, y0, y1
                if wall in (0, 1):
                    L, lo = y1 - y0, y0
                else:
                    L, lo = x1 - x0, x0
                if L < 2 * half_w + 0.04:
                    continue
                s = lo + ctx.u(half_w + 0.02, L - half_w - 0.02)
                gap = ctx.u(0.01, 0.04)
                if wall == 0:
                    pose = (x0 + back + gap, s, 0.0)
                elif wall == 1:
                    pose = (x1 - back - gap, s, math.pi)
                elif wall == 2:
                    pose = (s, y0 + back + gap, math.pi / 2)
                else:
                    pose = (s, y1 - back - gap, -math.pi / 2)
            else:
                m = reach_r + 0.05
                if x1 - x0 < 2 * m or y1 - y0 < 2 * m:
                    continue
                pose = (ctx.u(x0 + m, x1 - m), ctx.u(y0 + m, y1 - m), ctx.u(-math.pi, math.pi))
            pose = (_mm(pose[0]), _mm(pose[1]), _deg(pose[2]))
            T = planar_T(*pose)
            poly = transform_polygon(T, hull)
            if not polygon_inside_rect(poly, self.bounds, 0.0):
                continue
            if any(polygons_overlap(poly, h, 0.03) for h in (*self.hulls, *self.doors)):
                continue
            r = ctx.cfg.robot_radius
            if not all(disc_clear(p, poly, r + 0.02) for p in self.parkings):
                continue
            keep = [pk for pk in piece.parking
                    if self.parking_free(*transform_xy(T, [(pk.pose.x, pk.pose.y)])[0], [poly])]
            if keep:
                joined = self.joined(poly, [tuple(transform_xy(T, [(pk.pose.x, pk.pose.y)])[0])
                                            for pk in keep])
                keep = [pk for pk, j in zip(keep, joined or ()) if j]
            if not keep:
                continue
            piece.parking = keep
            self.hulls.append(poly)
            self.parkings += [tuple(transform_xy(T, [(pk.pose.x, pk.pose.y)])[0]) for pk in keep]
            return pose
        return None


    def joined(self, poly: np.ndarray, parkings: list) -> Optional[list[bool]]:
        """With a piece of footprint ``poly`` placed too: which of ``parkings`` (room frame
        x, y) the robot reaches from the doorways and the parking positions kept so far
        (the room's occupancy grid, hearth/worldmodel/navigation.py), or None when the piece
        would cut one of those off from the others. A piece may stand clear of every
        doorway's approach and still wall one off with its neighbours."""
        from hearth.worldmodel.navigation import NavConfig, grid_from_polygons
        # A cell wider than the robot: a gap just wide enough on this room's grid may close
        # on the home's, whose cells are turned with the home (and drawn from the meshes).
        grid = grid_from_polygons([self.floor], [("", h) for h in (*self.hulls, poly)],
                                  NavConfig(robot_radius=self.ctx.cfg.robot_radius + 0.05))
        anchors = [np.mean(d, axis=0) for d in self.doors] + list(self.parkings)
        regions = {grid.region_at(*a) for a in anchors}
        if 0 in regions or len(regions) > 1:
            return None
        here = [grid.region_at(*p) for p in parkings]
        region = next(iter(regions)) if regions else next((r for r in here if r), 0)
        return [r != 0 and r == region for r in here]


def _hull(piece: Piece, scratch) -> np.ndarray:
    """The piece's footprint: convex hull of its meshes (hearth.worldmodel.geometry) in its frame."""
    from hearth.worldmodel.geometry import object_meshes
    meshes = object_meshes(scratch, piece.obj, T_world_object=np.eye(4), children=False)
    pts = np.vstack([np.asarray(m.mesh.vertices) for m in meshes])
    return convex_hull_xy(pts)


def _outline(ctx: _Ctx, bounds) -> Optional[list[tuple[float, float]]]:
    """An L-shaped floor inside ``bounds`` (a corner cut out, never the (xmin, ymin) one
    where the light switch is), or None for a rectangle."""
    x0, y0, x1, y1 = bounds
    w, d = x1 - x0, y1 - y0
    if min(w, d) < 3.2 or not ctx.chance(ctx.cfg.l_shaped_probability):
        return None
    nw, nd = _mm(w * ctx.u(0.3, 0.45)), _mm(d * ctx.u(0.3, 0.45))
    corner = ctx.i(1, 3)
    if corner == 1:        # (xmax, ymin)
        poly = [(x0, y0), (x1 - nw, y0), (x1 - nw, y0 + nd), (x1, y0 + nd), (x1, y1), (x0, y1)]
    elif corner == 2:      # (xmax, ymax)
        poly = [(x0, y0), (x1, y0), (x1, y1 - nd), (x1 - nw, y1 - nd), (x1 - nw, y1), (x0, y1)]
    else:                  # (xmin, ymax)
        poly = [(x0, y0), (x1, y0), (x1, y1), (x0 + nw, y1), (x0 + nw, y1 - nd), (x0, y1 - nd)]
    return [(_mm(x), _mm(y)) for x, y in poly]


def _floor_poly(bounds, outline) -> np.ndarray:
    if outline is not None:
        return np.array(outline, float)
    x0, y0, x1, y1 = bounds
    return np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], float)


def _notch(bounds, outline) -> list[np.ndarray]:
    """The corner an L-shaped floor lacks, as a rectangle of its bounds (room frame)."""
    if outline is None:
        return []
    x0, y0, x1, y1 = bounds
    P = np.array(outline, float)
    xs = sorted(set(P[:, 0]))
    ys = sorted(set(P[:, 1]))
    for i in range(len(xs) - 1):
        for j in range(len(ys) - 1):
            cx, cy = (xs[i] + xs[i + 1]) / 2, (ys[j] + ys[j + 1]) / 2
            if not outline_contains([tuple(p) for p in P], cx, cy):
                return [np.array([(xs[i], ys[j]), (xs[i + 1], ys[j]), (xs[i + 1], ys[j + 1]),
                                  (xs[i], ys[j + 1])])]
    return []


@dataclass
class _Placed:
    """A room placed so far: its node, world pose (x, y, yaw), floor polygon in its frame,
    convex hull of the floor in the world, and its layout (None for a corridor)."""
    room: Room
    pose: tuple[float, float, float]
    floor: np.ndarray
    hull_world: np.ndarray
    layout: Optional["_Layout"]
    #: Where a later room's doorway may go (furnished rooms keep the floor in front of them
    #: free): (centre, u along the side, n outward, side length, keep-out) in the room's frame.
    slots: list = None
    #: The keep-outs of its doorways and slots (room frame), whose middles (0.45 m inside)
    #: the furniture leaves joined by floor the robot can drive on.
    door_keeps: list = None


def _outer_edges(floor: np.ndarray, margin: float, door: float):
    """Sides of a floor polygon on its bounding box, long enough for a door ``margin`` from
    each corner: (a, u, n, length) with u along the side, n its outward normal."""
    lo, hi = floor.min(0), floor.max(0)
    n_ = len(floor)
    for i in range(n_):
        a, b = floor[i], floor[(i + 1) % n_]
        e = b - a
        L = float(np.linalg.norm(e))
        if L < door + 2 * margin:
            continue
        on_box = (abs(a[0] - b[0]) < 1e-9 and (abs(a[0] - lo[0]) < 1e-9 or abs(a[0] - hi[0]) < 1e-9)) \
            or (abs(a[1] - b[1]) < 1e-9 and (abs(a[1] - lo[1]) < 1e-9 or abs(a[1] - hi[1]) < 1e-9))
        if on_box:
            u = e / L
            yield a, u, np.array([u[1], -u[0]]), L


def _keep_out(centre, u, inward, width: float, depth: float = 0.9) -> np.ndarray:
    """The floor in front of a doorway that furniture leaves free (room frame): the door's
    width and 0.35 m each side, ``depth`` into the room."""
    h = width / 2 + 0.35
    c = np.asarray(centre, float)
    return np.array([c - u * h, c + u * h, c + u * h + inward * depth, c - u * h + inward * depth])


def _attach(ctx: _Ctx, floor: np.ndarray, placed: list[_Placed], hosts: list[int],
            corridor: bool):
    """Where a room with ``floor`` (its frame) goes: beside one of the placed rooms
    ``hosts``, a side of it facing a side of the host ``room_gap`` away, joined by a doorway.
    Returns (host index, world pose, doorway pose in the host's frame, door width, keep-out
    in the host's frame, keep-out in the new room's frame, the host's slot index or None)
    or None. Nothing is changed until ``_join``."""
    cfg = ctx.cfg
    g = cfg.room_gap
    for _ in range(60):
        hi = hosts[int(ctx.rng.integers(len(hosts)))]
        host = placed[hi]
        width = _mm(ctx.u(*cfg.door_width))
        m_host = 0.15 if host.layout is None else 0.4
        m_new = 0.15 if corridor else 0.4
        edges = list(_outer_edges(host.floor, m_host, width))
        if not edges:
            continue
        if host.slots is not None:           # a furnished room: a doorway slot it kept free
            if not host.slots:
                continue
            si = int(ctx.rng.integers(len(host.slots)))
            P_slot, u, n, L, _k = host.slots[si]
            a = P_slot - u * (m_host + width / 2)    # so that s_host below is the slot's centre
            L_host = None
        else:
            si = None
            a, u, n, L = edges[int(ctx.rng.integers(len(edges)))]
            L_host = L
        q = ctx.i(0, 3)
        R = np.array([[math.cos(q * math.pi / 2), -math.sin(q * math.pi / 2)],
                      [math.sin(q * math.pi / 2), math.cos(q * math.pi / 2)]])
        R = np.round(R)
        mine = [(b, v, k, Lb) for b, v, k, Lb in _outer_edges(floor, m_new, width)
                if np.allclose(R @ k, -n)]
        if not mine:
            continue
        b, v, k, Lb = mine[int(ctx.rng.integers(len(mine)))]
        s_host = m_host + width / 2 if L_host is None else \
            ctx.u(m_host + width / 2, max(L - m_host - width / 2, m_host + width / 2))
        s_new = ctx.u(m_new + width / 2, max(Lb - m_new - width / 2, m_new + width / 2))
        P_host = a + u * s_host                        # door centre on the host's floor edge
        P_new = b + v * s_new                          # and on the new room's, its frame
        t = P_host + n * g - R @ P_new                 # new room frame -> host frame
        T_host = planar_T(*host.pose)
        T_new = T_host @ planar_T(float(t[0]), float(t[1]), q * math.pi / 2)
        x, y = _mm(T_new[0, 3]), _mm(T_new[1, 3])
        yaw = _deg(math.atan2(T_new[1, 0], T_new[0, 0]))
        hull = convex_hull_xy(transform_polygon(planar_T(x, y, yaw), floor))
        if any(polygons_overlap(hull, p.hull_world, g - (0.02 if i == hi else 0.0))
               for i, p in enumerate(placed)):
            continue
        keep_host = _keep_out(P_host, u, -n, width)
        keep_new = _keep_out(P_new, v, -k, width)
        door = Pose(_mm(P_host[0] + n[0] * g / 2), _mm(P_host[1] + n[1] * g / 2), 0, 0, 0,
                    _deg(math.atan2(n[1], n[0])))
        return hi, (x, y, yaw), door, width, keep_host, keep_new, si
    return None


def _door_slots(ctx: _Ctx, floor: np.ndarray, n: int = 2):
    """Up to ``n`` places on different outer sides of a floor where later rooms' doorways
    may go, and their keep-outs (room frame): reserved before the furniture is placed."""
    width = ctx.cfg.door_width[1]
    edges = list(_outer_edges(floor, 0.4, width))
    order = ctx.rng.permutation(len(edges))[:n] if edges else []
    slots, keeps = [], []
    for i in order:
        a, u, nrm, L = edges[int(i)]
        s_ = ctx.u(0.4 + width / 2, max(L - 0.4 - width / 2, 0.4 + width / 2))
        P = a + u * s_
        keeps.append(_keep_out(P, u, -nrm, width))
        slots.append((P, u, nrm, L, keeps[-1]))
    return slots, keeps


def _first_pose(ctx: _Ctx) -> tuple[float, float, float]:
    """The first room's world pose: the home turned by any angle with the configured
    probability, else by a multiple of 90 degrees (the others are turned with it, by
    multiples of 90 degrees: their sides face each other across the doorways)."""
    turned = ctx.chance(ctx.cfg.turned_room_probability)
    yaw = ctx.u(-math.pi, math.pi) if turned else ctx.pick([0.0, 0.5, 1.0, -0.5]) * math.pi
    return (_mm(ctx.u(-3, 3)), _mm(ctx.u(-3, 3)), _deg(yaw))


def _join(ctx: _Ctx, placed: list[_Placed], hi: int, new_id: str, door: Pose, width: float,
          keep_host: np.ndarray, slot: Optional[int] = None) -> None:
    """The doorway from placed room ``hi`` to the new room, written in the host room: its
    passage spans the gap between the two floors and 5 cm into each."""
    host = placed[hi]
    host.room.doorways.append(Doorway(ctx.ids.exact(f"door_{host.room.id}_{new_id}"), door,
                                      width, _mm(ctx.cfg.room_gap + 0.1), new_id))
    if slot is not None:
        # The slot's keep-out (as wide as the widest door) stays in the layout; the slot is
        # taken.
        host.slots.pop(slot)
    elif host.layout is not None:
        host.layout.doors.append(keep_host)


def _corridor(ctx: _Ctx, placed: list[_Placed]) -> Optional[int]:
    """A corridor (a bare room, long and narrow) joined to a placed room; its index in
    ``placed``, or None when none fits."""
    cfg = ctx.cfg
    for _ in range(6):
        w, L = _mm(ctx.u(*cfg.corridor_width)), _mm(ctx.u(*cfg.corridor_length))
        floor = _floor_poly((0.0, 0.0, L, w), None)
        hosts = [i for i, p in enumerate(placed) if p.layout is not None]
        at = _attach(ctx, floor, placed, hosts, corridor=True)
        if at is None:
            continue
        hi, pose, door, width, keep_host, _keep_new, slot = at
        rid = ctx.ids.new("corridor")
        room = Room(rid, ctx.ids.name(rid.replace("_", " ")),
                    pose=Pose(pose[0], pose[1], 0, 0, 0, pose[2]),
                    bounds=(0.0, 0.0, L, w))
        _join(ctx, placed, hi, rid, door, width, keep_host, slot)
        placed.append(_Placed(room, pose, floor, convex_hull_xy(
            transform_polygon(planar_T(*pose), floor)), None))
        return len(placed) - 1
    return None


def _build_and_place(ctx: _Ctx, build: Callable[[], Piece], layout: "_Layout", scratch,
                     tries: int) -> Optional[Piece]:
    """Build a piece (up to ``tries`` designs) until one has a parking position that sees it
    and fits the room; the piece with its room-frame pose set, or None."""
    for _ in range(tries):
        piece = build()
        _keep_visible(ctx.cfg, piece)
        if not piece.parking:
            continue
        piece.hull = _hull(piece, scratch)
        pose = layout.try_place(piece)
        if pose is not None:
            piece.obj.pose = Pose(pose[0], pose[1], piece.lift, 0, 0, pose[2])
            piece.obj.parking = list(piece.parking)
            piece.obj.default_parking = piece.parking[0].id     # candidates come best first
            return piece
    return None


def _room(ctx: _Ctx, kind: str, rid: str, scratch, placed: list[_Placed], later: int = 1):
    """A room of ``kind`` with its furniture, placed beside the rooms so far (directly, or
    through a new corridor) and joined to one by a doorway: (Room, pieces, layout). A room
    whose required furniture (the kitchen's appliance) does not fit is drawn again, larger.
    ``later``: how many rooms are still to come (none: no doorway slots are kept; a home of
    one room is a rectangle drawn exactly as in version 8, which the one-room homes of the
    mapping tests and benchmarks are)."""
    (w0, w1), (d0, d1) = ROOM_KINDS[kind]
    ctx.room_name = kind
    hosts = [i for i, p in enumerate(placed) if p.layout is not None]
    corridors = sum(p.layout is None for p in placed)
    if placed and corridors < 2 and ctx.chance(ctx.cfg.corridor_probability):
        c = _corridor(ctx, placed)
        if c is not None:
            hosts = [c]
    grow = 1.0
    for attempt in range(12):
        w, d = _mm(ctx.u(w0, w1) * grow), _mm(ctx.u(d0, d1) * grow)
        bx = _mm(ctx.pick([0.0, ctx.u(-2.0, 1.0)]))
        by = _mm(ctx.pick([0.0, ctx.u(-2.0, 1.0)]))
        bounds = (bx, by, _mm(bx + w), _mm(by + d))
        outline = _outline(ctx, bounds) if placed or later else None
        floor = _floor_poly(bounds, outline)
        missing = _notch(bounds, outline)
        at = None
        if placed:
            at = _attach(ctx, floor, placed, hosts, corridor=False)
            if at is None:
                hosts = [i for i, p in enumerate(placed)]     # beside any room, then
                grow *= 0.92
                continue
        slots, slot_keeps = _door_slots(ctx, floor, 3 if not placed else 2) if later \
            else ([], [])
        door_keeps = ([at[5]] if at is not None else []) + slot_keeps
        layout = _Layout(ctx, bounds, floor, missing, door_keeps)
        pieces, ok = [], True
        knobs_before = ctx.knobs_left
        ids_before = set(ctx.ids.used), set(ctx.ids.names)
        for label, build, required in _furniture_plan(ctx, kind):
            piece = _build_and_place(ctx, build, layout, scratch, 6 if required else 1)
            if piece is not None:
                pieces.append(piece)
            elif required:
                ok = False
                break
        if ok:
            break
        ctx.knobs_left = knobs_before
        ctx.ids.used, ctx.ids.names = ids_before
        grow *= 1.12
    else:  # pragma: no cover - the kitchen grows until its appliance fits
        raise HomeGenError(f"could not lay out the {kind}")
    rpose = _first_pose(ctx) if at is None else at[1]
    sw = Switch(f"{rid}_light", ctx.pick(["rotational", "prismatic"]),
                Pose(_mm(bounds[0] + 0.02), _mm(ctx.u(bounds[1] + 0.2, bounds[1] + 0.6)),
                     _mm(ctx.u(1.05, 1.3))), name=f"{kind} light")
    room = Room(rid, kind, pose=Pose(rpose[0], rpose[1], 0, 0, 0, rpose[2]),
                bounds=None if outline is not None else bounds, outline=outline,
                switches=[sw], objects=[p.obj for p in pieces])
    if at is not None:
        _join(ctx, placed, at[0], rid, at[2], at[3], at[4], at[6])
    placed.append(_Placed(room, rpose, floor, convex_hull_xy(
        transform_polygon(planar_T(*rpose), floor)), layout, slots, door_keeps))
    return room, pieces, layout


def _release_slots(placed: list[_Placed]) -> None:
    """Give the floor of doorway slots no room was joined to back to the furniture."""
    for p in placed:
        for slot in p.slots or ():
            keep = slot[4]
            p.layout.doors = [h for h in p.layout.doors if h is not keep]
            p.door_keeps = [k for k in p.door_keeps if k is not keep]
        if p.slots:
            p.slots.clear()


def _turn_front(ctx: _Ctx, piece: Piece) -> None:
    """Turn an object's contents by a quarter or half turn inside its own frame and its pose
    back by the same, so the object stands where it stood but its front is no longer its
    local +x."""
    obj = piece.obj
    if obj.model.ref is not None:
        return
    c = ctx.pick([math.pi / 2, math.pi, -math.pi / 2])
    R = Pose(0, 0, 0, 0, 0, c)

    def turn(p: Pose) -> Pose:
        return _level_compose(R, p)

    for v in obj.model.visuals:     # mesh vertices are in the visual's frame: turning it turns them
        v.pose = turn(v.pose)
    obj.parking = [ParkingPosition(p.id, Pose.planar(*(lambda q: (q.x, q.y, q.yaw))(turn(p.pose))))
                   for p in obj.parking]
    obj.surfaces = [replace(s, pose=turn(s.pose)) for s in obj.surfaces]
    for ch in obj.children:
        if ch.part:         # in the part's frame, which the joint origin turns
            continue
        ch.pose = turn(ch.pose)
        ch.default_positions = [replace(d, pose=turn(d.pose)) if d.parent == obj.id else d
                                for d in ch.default_positions]
    if isinstance(obj, LargeArticulatedObject):
        for p in obj.parts:
            p.joint.origin = turn(p.joint.origin)
        for k in obj.knobs:
            k.pose = turn(k.pose)
        for h in obj.handles:
            h.pose = turn(h.pose)
    obj.pose = _clean(replace(obj.pose, yaw=obj.pose.yaw - c))    # level: yaws add


# -- the home -----------------------------------------------------------------------------------

def default_mesh_dir() -> Path:
    """Where ``generate_home`` writes meshes when no directory is given."""
    return Path(os.environ.get("HEARTH_HOMEGEN_DIR", Path.home() / ".cache" / "hearth" / "homegen"))


def generate_home(seed: int, config: HomeConfig = HomeConfig(), mesh_dir=None):
    """A generated home as a ``World`` (in memory; the meshes it references are written to
    ``mesh_dir``, default ``default_mesh_dir()``, which becomes the world's ``base_dir``).
    Deterministic per seed and configuration. HomeGenError for a configuration or seed it
    cannot use."""
    import tempfile
    from hearth.worldmodel.world import World
    config.check()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise HomeGenError(f"home seed must be a whole number >= 0, not {seed!r}")
    mesh_dir = Path(mesh_dir) if mesh_dir is not None else default_mesh_dir()
    rng = np.random.default_rng(int(seed))
    library: dict[str, Model] = {}
    with tempfile.TemporaryDirectory(prefix="hearth-homegen-") as tmp:
        ctx = _Ctx(rng, config, _Ids(), _Meshes(Path(tmp)), library, knobs_left=config.max_knobs,
                   design_rng=np.random.default_rng([int(seed), 0x6B6E6F62]),
                   drawer_rng=np.random.default_rng([int(seed), 0x64726177]))
        scratch = World(Apartment(id="scratch", library=library), base_dir=Path(tmp))
        n_rooms = ctx.i(*config.rooms)
        others = [k for k in ROOM_KINDS if k != "kitchen"]
        kinds = ["kitchen"] + [others[i] for i in rng.permutation(len(others))[:n_rooms - 1]]
        pieces, placed = [], []
        for i, kind in enumerate(kinds):
            rid = ctx.ids.exact(kind.replace(" ", "_"))
            _room_node, ps, _layout = _room(ctx, kind, rid, scratch, placed, len(kinds) - 1 - i)
            pieces += ps
        _release_slots(placed)
        _ensure_table(ctx, placed, pieces, scratch)
        rooms = [p.room for p in placed]            # corridors among them, in order made
        pieces = _reachable(rooms, pieces, library, Path(tmp), _door_middle(placed[0]))
    small_objects(ctx, pieces)
    for pc in pieces:
        if ctx.chance(config.front_turn_probability):
            _turn_front(ctx, pc)
    used_models = {o.model.ref for r in rooms for o in r.objects if o.model.ref is not None}
    library = {k: m for k, m in library.items() if k in used_models}
    apartment = Apartment(id=f"home_{int(seed)}", name=f"Generated home {int(seed)}",
                          rooms=rooms, library=library)
    world = World(apartment, path=None, base_dir=mesh_dir)
    ctx.meshes.write(mesh_dir, _mesh_files(apartment))
    from hearth.worldmodel.chargers import place_charger
    place_charger(world)
    return world


def _door_middle(p: _Placed) -> Optional[tuple[float, float]]:
    """World x, y of the middle of the room's first doorway keep-out (None: it has none)."""
    if not p.door_keeps:
        return None
    return tuple(transform_xy(planar_T(*p.pose), [np.mean(p.door_keeps[0], axis=0)])[0])


def _reachable(rooms, pieces, library, base_dir, start=None) -> list[Piece]:
    """Keep the parking positions the robot can drive to from ``start`` (world x, y: the
    approach to the kitchen's first doorway), else from the first room's first free parking
    position, on the occupancy grid of hearth/worldmodel/navigation.py; a piece left with
    none is taken out of the home. Returns the pieces kept."""
    from hearth.worldmodel.navigation import NoPath, nav_grid
    from hearth.worldmodel.world import World
    world = World(Apartment(id="scratch", rooms=rooms, library=library), base_dir=base_dir)
    grid = nav_grid(world)
    field = None
    if start is not None:
        try:
            field = grid.distances_from(*start)
        except NoPath:
            pass
    for pc in pieces if field is None else ():
        for _p, pose in world.parking_positions(pc.obj.id):
            try:
                field = grid.distances_from(pose.x, pose.y)
                break
            except NoPath:
                continue
        if field is not None:
            break
    if field is None:       # pragma: no cover - a kitchen's appliance always has a free front
        raise HomeGenError("no parking position of the home is free")
    kept = []
    for pc in pieces:
        ok = {p.id for p, pose in world.parking_positions(pc.obj.id)
              if math.isfinite(field.length_to(pose.x, pose.y))}
        pc.obj.parking = [p for p in pc.obj.parking if p.id in ok]
        pc.parking = [p for p in pc.parking if p.id in ok]
        room = next(r for r in rooms if pc.obj in r.objects)
        if not pc.obj.parking:
            room.objects.remove(pc.obj)
            continue
        if pc.obj.default_parking not in ok:
            pc.obj.default_parking = pc.obj.parking[0].id
        kept.append(pc)
    return kept


def _ensure_table(ctx: _Ctx, placed: list[_Placed], pieces, scratch) -> None:
    """Every home gets a table (fetching from a table is the first mission anyone runs)."""
    if any(p.obj.type == "table" for p in pieces):
        return
    rooms = [p for p in placed if p.layout is not None]
    order = sorted(range(len(rooms)), key=lambda i: -(rooms[i].room.bounds[2] - rooms[i].room.bounds[0])
                   * (rooms[i].room.bounds[3] - rooms[i].room.bounds[1]))
    for i in order:
        ctx.room_name = rooms[i].room.name
        piece = _build_and_place(ctx, lambda: table(ctx, "side"), rooms[i].layout, scratch, 6)
        if piece is not None:
            rooms[i].room.objects.append(piece.obj)
            pieces.append(piece)
            return


def _mesh_files(apartment: Apartment) -> set[str]:
    """Every mesh file the apartment references."""
    from hearth.worldmodel.validate import file_references
    return {getattr(h, a) for _, h, a in file_references(apartment) if a == "file"}


def make_home(seed: int, out_dir, config: HomeConfig = HomeConfig()) -> Path:
    """Write the home of ``seed`` as ``out_dir/world.xml`` (meshes in ``out_dir/meshes/``),
    atomically; returns the world file's path. The file is checked (schema and semantics)
    before it is written."""
    from hearth.worldmodel.io import atomic_write, parse_world, to_xml
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise HomeGenError(f"{out}: not a directory")
    world = generate_home(seed, config, mesh_dir=out)
    data = to_xml(world.apartment)
    parse_world(data, str(out / "world.xml"), base_dir=out.resolve())
    path = out / "world.xml"
    atomic_write(path, data)
    return path


def summary(world) -> dict:
    """Counts a person wants on one line: rooms, large and small objects, knobs."""
    return dict(rooms=[r.name for r in world.rooms], large=len(world.large_objects()),
                small=len(world.small_objects()), knobs=len(world.knobs()),
                turned=[r.name for r in world.rooms
                        if abs(math.remainder(r.pose.yaw, math.pi / 2)) > 1e-6])
