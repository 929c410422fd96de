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
from dataclasses import replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from hearth.worldmodel.frames import planar_T, transform_xy
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
    Apartment, LargeArticulatedObject, Model, ParkingPosition, Room, Switch,
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
GENERATOR_VERSION = 8


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
        add("wardrobe", lambda: cupboard(c, "wardrobe"), 0.85)
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

    def __init__(self, ctx: _Ctx, bounds):
        self.ctx = ctx
        self.bounds = bounds
        self.hulls: list[np.ndarray] = []
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
            if any(polygons_overlap(poly, h, 0.03) for h in self.hulls):
                continue
            r = ctx.cfg.robot_radius
            if not all(disc_clear(p, poly, r + 0.02) for p in self.parkings):
                continue
            keep = [pk for pk in piece.parking
                    if self.parking_free(*transform_xy(T, [(pk.pose.x, pk.pose.y)])[0], [poly])]
            if not keep:
                continue
            piece.parking = keep
            self.hulls.append(poly)
            self.parkings += [tuple(transform_xy(T, [(pk.pose.x, pk.pose.y)])[0]) for pk in keep]
            return pose
        return None


def _hull(piece: Piece, scratch) -> np.ndarray:
    """The piece's footprint: convex hull of its meshes (hearth.worldmodel.geometry) in its frame."""
    from hearth.worldmodel.geometry import object_meshes
    meshes = object_meshes(scratch, piece.obj, T_world_object=np.eye(4), children=False)
    pts = np.vstack([np.asarray(m.mesh.vertices) for m in meshes])
    return convex_hull_xy(pts)


def _room_polygon(room_bounds, pose: tuple[float, float, float]) -> np.ndarray:
    x0, y0, x1, y1 = room_bounds
    return transform_polygon(planar_T(*pose), np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]))


def _place_room(ctx: _Ctx, bounds, placed: list[np.ndarray]) -> tuple[float, float, float]:
    """A world pose (x, y, yaw) for a room with ``bounds`` (room frame) beside the rooms
    placed so far, ``room_gap`` clear of each; turned by any angle with the configured
    probability, else by a multiple of 90 degrees."""
    cfg = ctx.cfg
    turned = ctx.chance(cfg.turned_room_probability)
    for attempt in range(60):
        yaw = ctx.u(-math.pi, math.pi) if turned else ctx.pick([0.0, 0.5, 1.0, -0.5]) * math.pi
        if not placed:
            return (_mm(ctx.u(-3, 3)), _mm(ctx.u(-3, 3)), _deg(yaw))
        # beside a placed room: its centre plus a direction, far enough to clear it
        other = placed[int(ctx.rng.integers(len(placed)))]
        c = other.mean(0)
        a = ctx.u(-math.pi, math.pi)
        dirv = np.array([math.cos(a), math.sin(a)])
        poly0 = _room_polygon(bounds, (0.0, 0.0, _deg(yaw)))
        centre0 = poly0.mean(0)
        # Closer than half their smaller sides the two rooms overlap whatever the direction.
        start = 0.5 * (min(bounds[2] - bounds[0], bounds[3] - bounds[1])
                       + min(np.ptp(other, axis=0)) * 0.7)
        for dist in np.arange(start, start + 14.0, 0.25):
            cxy = c + dirv * dist
            pose = (_mm(cxy[0] - centre0[0]), _mm(cxy[1] - centre0[1]), _deg(yaw))
            poly = poly0 + (pose[0], pose[1])
            if not any(polygons_overlap(poly, q, cfg.room_gap) for q in placed):
                return pose
    # Nothing beside the others: far to the right of everything.
    x_max = max(q[:, 0].max() for q in placed)
    poly0 = _room_polygon(bounds, (0.0, 0.0, 0.0))
    return (_mm(x_max + cfg.room_gap + 1.0 - poly0[:, 0].min()), 0.0, 0.0)


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


def _room(ctx: _Ctx, kind: str, rid: str, scratch, placed_rooms: list[np.ndarray]):
    """A room of ``kind`` with its furniture: (Room, pieces, layout). A room whose required
    furniture (the kitchen's appliance) does not fit is drawn again, larger."""
    (w0, w1), (d0, d1) = ROOM_KINDS[kind]
    ctx.room_name = kind
    grow = 1.0
    for attempt in range(8):
        w, d = _mm(ctx.u(w0, w1) * grow), _mm(ctx.u(d0, d1) * grow)
        bx = _mm(ctx.pick([0.0, ctx.u(-2.0, 1.0)]))
        by = _mm(ctx.pick([0.0, ctx.u(-2.0, 1.0)]))
        bounds = (bx, by, _mm(bx + w), _mm(by + d))
        layout = _Layout(ctx, bounds)
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
    rpose = _place_room(ctx, bounds, placed_rooms)
    placed_rooms.append(_room_polygon(bounds, rpose))
    sw = Switch(f"{rid}_light", ctx.pick(["rotational", "prismatic"]),
                Pose(_mm(bounds[0] + 0.02), _mm(ctx.u(bounds[1] + 0.2, bounds[1] + 0.6)),
                     _mm(ctx.u(1.05, 1.3))), name=f"{kind} light")
    room = Room(rid, kind, pose=Pose(rpose[0], rpose[1], 0, 0, 0, rpose[2]), bounds=bounds,
                switches=[sw], objects=[p.obj for p in pieces])
    return room, pieces, layout


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
                   design_rng=np.random.default_rng([int(seed), 0x6B6E6F62]))
        scratch = World(Apartment(id="scratch", library=library), base_dir=Path(tmp))
        n_rooms = ctx.i(*config.rooms)
        others = [k for k in ROOM_KINDS if k != "kitchen"]
        kinds = ["kitchen"] + [others[i] for i in rng.permutation(len(others))[:n_rooms - 1]]
        rooms, pieces, layouts, placed = [], [], [], []
        for kind in kinds:
            rid = ctx.ids.exact(kind.replace(" ", "_"))
            room, ps, layout = _room(ctx, kind, rid, scratch, placed)
            rooms.append(room)
            pieces += ps
            layouts.append(layout)
        _ensure_table(ctx, rooms, pieces, layouts, scratch)
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


def _ensure_table(ctx: _Ctx, rooms, pieces, layouts, scratch) -> None:
    """Every home gets a table (fetching from a table is the first mission anyone runs)."""
    if any(p.obj.type == "table" for p in pieces):
        return
    order = sorted(range(len(rooms)), key=lambda i: -(rooms[i].bounds[2] - rooms[i].bounds[0])
                   * (rooms[i].bounds[3] - rooms[i].bounds[1]))
    for i in order:
        ctx.room_name = rooms[i].name
        piece = _build_and_place(ctx, lambda: table(ctx, "side"), layouts[i], scratch, 6)
        if piece is not None:
            rooms[i].objects.append(piece.obj)
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
