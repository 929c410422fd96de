"""Furniture builders of the home generator, one per kind: ``table``, ``bookshelf``,
``cupboard``, ``drawer_unit``, ``fridge``, ``appliance`` (oven, cooker, hob) and ``chair``.
Each makes a ``Piece`` in its canonical frame (origin on the floor under its footprint's
centre, front towards +x) with its parking candidates, views and reach points."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from hearth.worldmodel.homegen_geometry import box_mesh, extrude, merge, rounded_rect, transformed
from hearth.worldmodel.homegen_knobs import _knobs, _R_FRONT
from hearth.worldmodel.homegen_palette import BLACK, DARK, PAINTS, STEEL, WHITE, WOODS
from hearth.worldmodel.homegen_pieces import (
    TAU, around_parking, box, _Ctx, cyl, _deg, front_parking, _mm, Piece, _rot_pose,
    _surface_views, View,
)
from hearth.worldmodel.nodes import (
    Handle, Joint, LargeArticulatedObject, LargeObject, Model, ParkingPosition, Part,
    Surface, Visual,
)
from hearth.worldmodel.pose import Pose


# -- furniture builders (canonical frame: origin on the floor, front towards +x) ----------------

def table(ctx: _Ctx, kind: str = "table") -> Piece:
    """A table: rectangular, long and narrow, or round (cylinder top); legs or a pedestal;
    sometimes a mesh top (rounded corners) or mesh legs. ``kind``: table, coffee, side,
    dining, desk, counter, bedside."""
    cfg = ctx.cfg
    heights = {"coffee": (0.4, 0.5), "side": (0.5, 0.72), "bedside": (0.45, 0.65),
               "dining": (0.72, 0.78), "desk": (0.72, 0.77), "counter": (0.85, 0.95),
               "table": (0.72, 0.8), "bar": (0.95, 1.1)}[kind]
    lo, hi = max(cfg.table_height[0], heights[0]), min(cfg.table_height[1], heights[1])
    h = _mm(ctx.u(lo, hi) if lo <= hi else ctx.u(*cfg.table_height))
    color = ctx.pick(WOODS + PAINTS[:2])
    word = kind if kind in ("counter", "desk", "table") else f"{kind} table"
    oid = ctx.ids.new(word.replace(" ", "_"))
    name = ctx.ids.name(f"{ctx.room_name} {word}")
    round_top = kind in ("coffee", "side", "bar", "table", "dining") and ctx.chance(cfg.round_table_probability)
    t = _mm(ctx.u(0.02, 0.04))
    visuals: list[Visual] = []
    if round_top:
        r = _mm({"coffee": ctx.u(0.3, 0.5), "side": ctx.u(0.22, 0.35), "bar": ctx.u(0.3, 0.4),
                 "table": ctx.u(0.4, 0.6), "dining": ctx.u(0.45, 0.6)}[kind])
        sx = sy = 2 * r
        visuals.append(cyl(r, t, z=h - t / 2, color=color, name="top"))
        if ctx.chance(0.5):     # pedestal and foot
            visuals += [cyl(_mm(ctx.u(0.03, 0.06)), h - t - 0.02, z=(h - t) / 2 + 0.01, color=color,
                            name="leg"),
                        cyl(_mm(r * ctx.u(0.45, 0.7)), 0.02, z=0.01, color=color, name="foot")]
        else:
            lr, n_legs = r * 0.62, ctx.pick([3, 4])
            for k in range(n_legs):
                a = TAU * k / n_legs + math.pi / 4
                visuals.append(box(0.04, 0.04, h - t, lr * math.cos(a), lr * math.sin(a),
                                   (h - t) / 2, color=color, name="leg"))
        surface = Surface("top", Pose(0, 0, h), _mm(2 * r * 0.68), _mm(2 * r * 0.68))
    else:
        if kind in ("desk", "counter") or (kind in ("table", "dining", "side") and ctx.chance(0.2)):
            # long and narrow
            sx, sy = _mm(ctx.u(1.2, 1.9)), _mm(ctx.u(0.4, 0.6))
        elif kind in ("side", "bedside"):
            sx, sy = _mm(ctx.u(0.4, 0.7)), _mm(ctx.u(0.35, 0.55))
        elif kind == "coffee":
            sx, sy = _mm(ctx.u(0.8, 1.3)), _mm(ctx.u(0.5, 0.75))
        else:
            sx, sy = _mm(ctx.u(0.9, 1.6)), _mm(ctx.u(0.7, 1.0))
        if ctx.chance(cfg.mesh_probability):
            top = extrude(rounded_rect(sx, sy, ctx.u(0.02, 0.12)), h - t, h)
            visuals.append(Visual("mesh", file=ctx.meshes.add("table-top", top), color=color,
                                  name="top"))
        else:
            visuals.append(box(sx, sy, t, z=h - t / 2, color=color, name="top"))
        ls = _mm(ctx.u(0.035, 0.06))
        inset = ls / 2 + _mm(ctx.u(0.02, 0.06))
        corners = [(sxs * (sx / 2 - inset), sys_ * (sy / 2 - inset))
                   for sxs in (-1, 1) for sys_ in (-1, 1)]
        if ctx.chance(cfg.mesh_probability / 2):
            legs = merge(*[box_mesh((x, y, (h - t) / 2), (ls, ls, h - t)) for x, y in corners])
            visuals.append(Visual("mesh", file=ctx.meshes.add("table-legs", legs), color=color,
                                  name="legs"))
        else:
            visuals += [box(ls, ls, h - t, x, y, (h - t) / 2, color=color, name="leg")
                        for x, y in corners]
        surface = Surface("top", Pose(0, 0, h), _mm(sx - 0.04), _mm(sy - 0.04))
    obj = LargeObject(id=oid, type="table", name=name, pose=Pose(), model=Model(visuals),
                      affordances=["supporting_surface"], surfaces=[surface],
                      description=f"{'round ' if round_top else ''}{word}")
    mount = "wall" if kind in ("counter", "desk", "bedside", "side") and ctx.chance(0.7) else "free"
    return Piece(obj, mount, around_parking(ctx, oid, sx, sy), views=[View("top", (0.0, 0.0, h))],
                 reach=[(0.0, 0.0, h)], headroom={"top": math.inf})


def _carcass(depth, width, height, color, t=0.018, plinth=0.06, shelves=(), name_shelf="shelf"):
    """An open-fronted box (back, sides, top, bottom board over a plinth, shelves) with its
    bottom centre at the origin and its open front at x = depth/2."""
    v = [box(t, width, height, -depth / 2 + t / 2, 0, height / 2, color=color, name="back"),
         box(depth, t, height, 0, width / 2 - t / 2, height / 2, color=color, name="side"),
         box(depth, t, height, 0, -width / 2 + t / 2, height / 2, color=color, name="side"),
         box(depth, width, t, 0, 0, height - t / 2, color=color, name="top"),
         box(depth, width - 2 * t, t, 0, 0, plinth + t / 2, color=color, name="bottom")]
    if plinth > 0:
        v.append(box(depth - 0.03, width - 2 * t, plinth, -0.015, 0, plinth / 2, color=DARK,
                     name="plinth"))
    for z in shelves:
        v.append(box(depth - t - 0.01, width - 2 * t, t, -0.005 + t / 2, 0, z - t / 2, color=color,
                     name=name_shelf))
    return v


def _shelf_levels(ctx: _Ctx, bottom: float, top: float, n: int, min_gap: float = 0.22) -> list[float]:
    """Heights of ``n`` shelf tops between ``bottom`` and ``top`` (the highest at least
    ``min_gap`` under ``top``), gaps of at least ``min_gap``, unevenly spaced."""
    n = max(0, min(n, int((top - bottom) / min_gap) - 1))
    if n == 0:
        return []
    w = ctx.rng.uniform(0.7, 1.3, n + 1)
    span = top - bottom - (n + 1) * min_gap
    gaps = min_gap + span * w / w.sum()
    return [_mm(bottom + g) for g in np.cumsum(gaps)[:-1]]


def bookshelf(ctx: _Ctx) -> Piece:
    """Open shelving: 2-6 shelf levels (the bottom board 5-15 cm up, so some shelves are
    low), each a surface; sometimes mesh side panels (tapered)."""
    cfg = ctx.cfg
    D, W = _mm(ctx.u(0.25, 0.4)), _mm(ctx.u(0.5, 1.2))
    H = _mm(ctx.u(0.8, 2.0))
    t = _mm(ctx.u(0.018, 0.025))
    color = ctx.pick(WOODS + PAINTS)
    oid = ctx.ids.new("bookshelf")
    plinth = _mm(ctx.u(0.03, 0.12))
    n = ctx.i(*cfg.shelf_levels)
    levels = [_mm(plinth + t)] + _shelf_levels(ctx, plinth + t, H - t, n - 1, 0.24)
    v = _carcass(D, W, H, color, t, plinth, shelves=levels[1:])
    if ctx.chance(cfg.mesh_probability):        # tapered sides as one mesh
        v = [x for x in v if x.name != "side"]
        top_d = D * ctx.u(0.6, 1.0)
        prof = np.array([[-D / 2, 0.0], [D / 2, 0.0], [-D / 2 + top_d, H], [-D / 2, H]])
        sides = []
        for s in (1, -1):
            m = transformed(extrude(prof, -t / 2, t / 2), _Rx90(0.0, s * (W / 2 - t / 2)))
            sides.append(m)
        v.append(Visual("mesh", file=ctx.meshes.add("shelf-sides", merge(*sides)), color=color,
                        name="side"))
    surfaces, headroom = [], {}
    tops = levels + [H]
    for i, z in enumerate(levels):
        sid = "shelf_bottom" if i == 0 else f"shelf_{i}"
        surfaces.append(Surface(sid, Pose(_mm(t / 2), 0, z), _mm(D - t - 0.03), _mm(W - 2 * t - 0.02)))
        headroom[sid] = _mm(tops[i + 1] - t - z)
    open_above = set()
    if H <= 1.2:
        surfaces.append(Surface("top", Pose(0, 0, H), _mm(D - 0.02), _mm(W - 0.02)))
        headroom["top"] = math.inf
        open_above.add("top")
    obj = LargeObject(id=oid, type="bookshelf", name=ctx.ids.name(f"{ctx.room_name} bookshelf"),
                      pose=Pose(), model=Model(v), affordances=["supporting_surface"],
                      surfaces=surfaces, description=f"open shelving, {len(levels)} shelves")
    views = [View("face", (D / 2, 0.0, min(H / 2, 1.0)))]
    views += _surface_views(surfaces, headroom, D / 2, cfg, open_above)
    return Piece(obj, "free" if ctx.chance(cfg.free_standing_probability) else "wall",
                 front_parking(ctx, oid, D / 2, W), views=views,
                 reach=[(s.pose.x, s.pose.y, s.pose.z) for s in surfaces
                        if s.pose.z <= cfg.max_object_height],
                 headroom=headroom)


def _Rx90(x: float, y: float) -> np.ndarray:
    """A profile drawn in (x, z) and extruded along z, stood up: rotation about x by +90 deg
    (profile y -> up, extrusion -> -y), then moved to (x, y)."""
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    T[:3, 3] = (x, y, 0.0)
    return T


def _door_mesh(t: float, width: float, height: float, sign: int, inset: float) -> tuple:
    """A door panel with a raised frame, in the door's part frame: thickness along x centred
    on 0, from the hinge (y = 0) towards ``sign`` * y, from z = 0 up."""
    yc = sign * width / 2
    panel = box_mesh((0.0, yc, height / 2), (t, width, height))
    b, r = inset, 0.008
    frame = [box_mesh((t / 2 + r / 2, yc, b / 2), (r, width, b)),
             box_mesh((t / 2 + r / 2, yc, height - b / 2), (r, width, b)),
             box_mesh((t / 2 + r / 2, sign * b / 2, height / 2), (r, b, height - 2 * b)),
             box_mesh((t / 2 + r / 2, sign * (width - b / 2), height / 2), (r, b, height - 2 * b))]
    return merge(panel, *frame)


def _hinged_door(ctx: _Ctx, pid: str, name: str, front_x: float, hinge_y: float, width: float,
                 height: float, z0: float, side: int, color, t: float, handle_z: float,
                 vertical_handle: bool = True) -> Part:
    """A door on the front (x = ``front_x``) hinged at y = ``hinge_y`` on its ``side`` edge
    (+1: the hinge on the door's +y edge, the door reaching towards -y; -1 the other way).
    Positive joint states open it outwards; the handle is near the edge away from the hinge."""
    sign = -side
    joint = Joint("revolute", origin=Pose(_mm(front_x + t / 2 + 0.002), _mm(hinge_y), _mm(z0)),
                  axis=(0.0, 0.0, float(side)), lower=0.0,
                  upper=_deg(math.radians(ctx.u(95, 115))), state=0.0)
    if ctx.chance(ctx.cfg.mesh_probability):
        face = Visual("mesh", file=ctx.meshes.add("door", _door_mesh(t, width, height, sign,
                                                                     ctx.u(0.04, 0.08))),
                      color=color, name="face")
    else:
        face = box(t, width, height, 0, sign * width / 2, height / 2, color=color, name="face")
    standoff = _mm(ctx.u(0.025, 0.045))
    hy = sign * (width - ctx.u(0.04, 0.07))
    if vertical_handle:
        handle = Handle(f"{pid}_handle", Pose(_mm(t / 2 + standoff), _mm(hy), _mm(handle_z)),
                        radius=_mm(ctx.u(0.006, 0.012)), length=_mm(ctx.u(0.1, min(0.35, height * 0.4))),
                        standoff=standoff)
    else:
        hy = sign * (width - 0.05 - 0.06)
        handle = Handle(f"{pid}_handle", Pose(_mm(t / 2 + standoff), _mm(hy), _mm(handle_z),
                                              -math.pi / 2, 0, 0),
                        radius=_mm(ctx.u(0.006, 0.01)), length=0.1, standoff=standoff)
    return Part(pid, "door", joint, name=name, model=Model([face]), handles=[handle])


def cupboard(ctx: _Ctx, kind: str = "cupboard") -> Piece:
    """A cupboard with one door (hinged left or right) or two (hinged at the outer edges),
    1-3 shelves inside; ``kind``: cupboard (low, or tall with some probability), wardrobe
    (tall), sideboard (low, wide), cabinet (wall-mounted)."""
    cfg = ctx.cfg
    wall = kind == "cabinet"
    tall = kind == "wardrobe" or (kind == "cupboard" and ctx.chance(cfg.tall_cupboard_probability))
    two = kind in ("wardrobe", "sideboard") or (not wall and ctx.chance(cfg.two_door_probability))
    D = _mm(ctx.u(0.3, 0.4) if wall else ctx.u(0.4, 0.6))
    W = _mm(ctx.u(0.8, 1.2) if two else ctx.u(0.4, 0.6))
    H = _mm(ctx.u(0.5, 0.75) if wall else ctx.u(1.6, 2.1) if tall else ctx.u(0.7, 1.0))
    lift = _mm(ctx.u(0.9, 1.1)) if wall else 0.0
    t, dt = 0.018, _mm(ctx.u(0.018, 0.025))
    plinth = 0.0 if wall else _mm(ctx.u(0.04, 0.1))
    color = ctx.pick(PAINTS + WOODS[:3])
    oid = ctx.ids.new(kind)
    n_shelves = ctx.i(1, 3 if tall else 2) if H - plinth > 0.5 else 0
    shelves = _shelf_levels(ctx, plinth + t, H - t, n_shelves, 0.22)
    v = _carcass(D, W, H, color, t, plinth, shelves=shelves)
    # The interior, as seen by a camera: absolute heights for the small objects' surfaces.
    levels = [plinth + t] + shelves
    tops = levels + [H - t]
    surfaces, headroom = [], {}
    for i, z in enumerate(levels):
        sid = "inside_bottom" if i == 0 else f"shelf_{i}"
        surfaces.append(Surface(sid, Pose(_mm(t / 2), 0, _mm(z)), _mm(D - t - 0.04),
                                _mm(W - 2 * t - 0.04), "in"))
        headroom[sid] = _mm(tops[i + 1] - (t if i + 1 < len(levels) else 0) - z)
    open_above = set()
    if not wall and not tall:
        surfaces.append(Surface("top", Pose(0, 0, H), _mm(D - 0.04), _mm(W - 0.04)))
        headroom["top"] = math.inf
        open_above.add("top")
    door_h = _mm(H - plinth - 0.01)
    handle_z = _mm(min(door_h * ctx.u(0.55, 0.8), 1.05 - plinth) if not wall else door_h * ctx.u(0.12, 0.3))
    door_color = color if ctx.chance(0.7) else ctx.pick(PAINTS)
    vertical = ctx.chance(0.8)
    parts = []
    if two:
        dw = _mm(W / 2 - 0.004)
        parts.append(_hinged_door(ctx, f"{oid}_door_left", "left door", D / 2, W / 2, dw, door_h,
                                  plinth + 0.005, +1, door_color, dt, handle_z, vertical))
        parts.append(_hinged_door(ctx, f"{oid}_door_right", "right door", D / 2, -W / 2, dw,
                                  door_h, plinth + 0.005, -1, door_color, dt, handle_z, vertical))
    else:
        side = ctx.pick([+1, -1])
        parts.append(_hinged_door(ctx, f"{oid}_door", "door", D / 2, side * W / 2, _mm(W - 0.006),
                                  door_h, plinth + 0.005, side, door_color, dt, handle_z, vertical))
    names = {"cupboard": "cupboard", "wardrobe": "wardrobe", "sideboard": "sideboard",
             "cabinet": "wall cabinet"}
    obj = LargeArticulatedObject(
        id=oid, type=kind, name=ctx.ids.name(f"{ctx.room_name} {names[kind]}"), pose=Pose(),
        model=Model(v), affordances=["container", "openable"], surfaces=surfaces, parts=parts,
        description=f"{'tall ' if tall else ''}{names[kind]}, {len(parts)} door{'s' if two else ''}")
    front = D / 2 + dt + 0.002
    views = [View("face", (front, 0.0, lift + min(H / 2, 1.0)))]
    views += _surface_views(_lifted(surfaces, lift), headroom, D / 2, cfg, open_above)
    reach = [tuple(_handle_point(p, lift)) for p in parts]
    piece = Piece(obj, "free" if not wall and ctx.chance(cfg.free_standing_probability) else "wall",
                  front_parking(ctx, oid, front, W), views=views, reach=reach, headroom=headroom,
                  lift=lift)
    return piece


def _lifted(surfaces: list[Surface], lift: float) -> list[Surface]:
    return [replace(s, pose=replace(s.pose, z=s.pose.z + lift)) for s in surfaces]


def _handle_point(part: Part, lift: float = 0.0) -> np.ndarray:
    o = part.joint.origin
    h = part.handles[0].pose
    return np.array([o.x + h.x, o.y + h.y, lift + o.z + h.z])


def drawer_unit(ctx: _Ctx, kind: str = "drawers") -> Piece:
    """1-4 drawers of different heights (prismatic parts sliding out along +x, a bar handle
    each); a surface on top when the unit is low."""
    cfg = ctx.cfg
    D, W = _mm(ctx.u(0.4, 0.55)), _mm(ctx.u(0.4, 0.9))
    n = ctx.i(*cfg.drawers)
    H = _mm(ctx.u(max(0.45, 0.18 * n + 0.2), 1.1))
    plinth, t = _mm(ctx.u(0.03, 0.08)), 0.018
    color = ctx.pick(PAINTS + WOODS)
    oid = ctx.ids.new("drawers" if kind == "drawers" else kind)
    v = _carcass(D, W, H, color, t, plinth)
    room = H - plinth - t - 0.01
    w = ctx.rng.uniform(0.6, 1.6, n)
    heights = [_mm(x) for x in room * w / w.sum()]
    parts, z = [], plinth + 0.005
    front_t = _mm(ctx.u(0.018, 0.025))
    hcolor = ctx.pick([(0.75, 0.75, 0.78), (0.2, 0.2, 0.2), (0.8, 0.65, 0.3)])
    for i, dh in enumerate(heights):
        pid = f"{oid}_drawer_{i + 1}"
        fh = dh - 0.006
        tray_d = D - 0.06
        model = [box(front_t, W - 0.008, fh, 0, 0, fh / 2, color=color, name="face"),
                 box(tray_d, W - 0.06, 0.012, -tray_d / 2 - front_t / 2, 0, 0.03, color=color),
                 box(tray_d, 0.012, fh * 0.6, -tray_d / 2 - front_t / 2, W / 2 - 0.04, fh * 0.3 + 0.03, color=color),
                 box(tray_d, 0.012, fh * 0.6, -tray_d / 2 - front_t / 2, -W / 2 + 0.04, fh * 0.3 + 0.03, color=color)]
        standoff = _mm(ctx.u(0.025, 0.04))
        handle = Handle(f"{pid}_handle", Pose(_mm(front_t / 2 + standoff), 0.0,
                                              _mm(fh * ctx.u(0.5, 0.8)), -math.pi / 2, 0, 0),
                        radius=_mm(ctx.u(0.006, 0.01)), length=_mm(min(W * ctx.u(0.2, 0.6), fh * 3 + 0.1)),
                        standoff=standoff, color=hcolor)
        joint = Joint("prismatic", origin=Pose(_mm(D / 2 + front_t / 2 + 0.002), 0.0, _mm(z)),
                      axis=(1.0, 0.0, 0.0), lower=0.0, upper=_mm(D * 0.75), state=0.0)
        parts.append(Part(pid, "drawer", joint, name=f"drawer {i + 1} from the bottom",
                          model=Model(model), handles=[handle]))
        z += dh
    surfaces, headroom, open_above = [], {}, set()
    if H <= 1.1:
        surfaces.append(Surface("top", Pose(0, 0, H), _mm(D - 0.04), _mm(W - 0.04)))
        headroom["top"], open_above = math.inf, {"top"}
    names = {"drawers": "chest of drawers", "bedside": "bedside drawers"}
    obj = LargeArticulatedObject(
        id=oid, type="drawers", name=ctx.ids.name(f"{ctx.room_name} {names.get(kind, kind)}"),
        pose=Pose(), model=Model(v), affordances=["container", "openable"], surfaces=surfaces,
        parts=parts, description=f"{n} drawer{'s' if n > 1 else ''}")
    front = D / 2 + front_t + 0.002
    views = [View("face", (front, 0.0, min(H / 2, 1.0)))]
    views += _surface_views(surfaces, headroom, D / 2, cfg, open_above)
    return Piece(obj, "free" if ctx.chance(cfg.free_standing_probability) else "wall",
                 front_parking(ctx, oid, front, W), views=views,
                 reach=[tuple(_handle_point(p)) for p in parts], headroom=headroom)


def fridge(ctx: _Ctx) -> Piece:
    """A fridge: one full-height door or a fridge door over a freezer door, hinged on the
    same side (left or right), shelves inside."""
    cfg = ctx.cfg
    D, W, H = _mm(ctx.u(0.58, 0.7)), _mm(ctx.u(0.55, 0.75)), _mm(ctx.u(1.4, 1.9))
    color, material = ctx.pick([(STEEL, "matte"), (WHITE, "matte"), (STEEL, "shiny"),
                                ((0.2, 0.2, 0.22), "matte"), ((0.85, 0.2, 0.18), "matte")])
    oid = ctx.ids.new("fridge")
    plinth, t = 0.04, 0.02
    two = ctx.chance(0.5)
    split = _mm(ctx.u(0.55, 0.8)) if two else plinth
    shelves = _shelf_levels(ctx, split + t, H - t, ctx.i(2, 3), 0.22)
    v = _carcass(D, W, H, color, t, plinth, shelves=shelves)
    if two:
        v.append(box(D - t - 0.01, W - 2 * t, t, -0.005 + t / 2, 0, split - t / 2, color=color,
                     name="divider"))
    levels = [split if two else plinth + t] + shelves     # the divider's top, or the bottom board's
    tops = levels + [H - t]
    surfaces, headroom = [], {}
    for i, z in enumerate(levels):
        sid = f"shelf_{i + 1}"
        surfaces.append(Surface(sid, Pose(_mm(t / 2), 0, _mm(z)), _mm(D - t - 0.06),
                                _mm(W - 2 * t - 0.04), "in"))
        headroom[sid] = _mm(tops[i + 1] - t - z)
    side = ctx.pick([+1, -1])
    dt = _mm(ctx.u(0.03, 0.05))
    parts = []
    main_h = _mm(H - split - 0.01)
    parts.append(_hinged_door(ctx, f"{oid}_door", "fridge door", D / 2, side * W / 2, _mm(W - 0.006),
                              main_h, split + 0.005, side, color, dt, _mm(min(main_h * 0.5, 1.05 - split)), True))
    if two:
        parts.append(_hinged_door(ctx, f"{oid}_freezer_door", "freezer door", D / 2, side * W / 2,
                                  _mm(W - 0.006), _mm(split - plinth - 0.01), plinth + 0.005, side,
                                  color, dt, _mm((split - plinth) * 0.75), True))
    for p in parts:
        p.model.visuals[0].material = material
    obj = LargeArticulatedObject(
        id=oid, type="fridge", name=ctx.ids.name(f"{ctx.room_name} fridge"), pose=Pose(),
        model=Model(v), affordances=["container", "openable"], surfaces=surfaces, parts=parts,
        description="fridge-freezer" if two else "fridge")
    front = D / 2 + dt + 0.002
    views = [View("face", (front, 0.0, 1.0))]
    views += _surface_views(surfaces, headroom, D / 2, cfg, set())
    return Piece(obj, "wall", front_parking(ctx, oid, front, W), views=views,
                 reach=[tuple(_handle_point(p)) for p in parts], headroom=headroom)


def appliance(ctx: _Ctx, kind: str, n_knobs: int) -> Piece:
    """An oven (a door hinged at the bottom, a knob panel above it), a cooker (an oven with a
    hob on top) or a hob (a counter unit with a hob on top and a side-hinged door; its knobs
    on the top or on a front panel).

    The front is flush (body, door and panel in one plane: the door and the panel sit in a
    recess of the body as deep as the door is thick) or stepped (the door stands out of the
    body and panel, or the panel stands out further than the door)."""
    cfg = ctx.cfg
    D, W, H = _mm(ctx.u(0.55, 0.65)), _mm(ctx.u(0.5, 0.9)), _mm(ctx.u(0.85, 0.95))
    oid = ctx.ids.new(kind)
    color, material = ctx.pick([(STEEL, "matte"), (WHITE, "matte"), (DARK, "matte"),
                                (STEEL, "shiny"), ((0.85, 0.84, 0.8), "matte")])
    flush = ctx.chance(cfg.flush_front_probability)
    top_knobs = kind == "hob" and ctx.chance(cfg.top_knobs_probability)
    t = _mm(ctx.u(0.02, 0.035))                 # door (and flush panel) thickness
    panel_h = 0.0 if top_knobs else _mm(ctx.u(0.1, 0.16))
    z0 = _mm(ctx.u(0.06, 0.12))                 # the door's bottom edge
    # an oven whose knob panel is below its door, knobs at 0.25-0.35 m (z0: the panel's
    # bottom edge then), or one raised in a tall unit, knobs up to 1.4 m
    # (drawn from the knob designs' generator: the rest of the home stays as it was)
    drng = ctx.design_rng or ctx.rng
    panel_low = kind == "oven" and bool(panel_h) and drng.random() < cfg.low_panel_probability
    if panel_low:
        z0 = _mm(float(drng.uniform(0.18, 0.26)))
    lift = (_mm(float(drng.uniform(0.3, 0.5))) if kind == "oven" and not panel_low
            and drng.random() < cfg.raised_oven_probability else 0.0)
    panel_zc = z0 + panel_h / 2 if panel_low else H - panel_h / 2
    door_z0 = _mm(z0 + panel_h + 0.01) if panel_low else z0
    front = D / 2
    panel_color = ctx.pick([DARK, color, BLACK])
    v: list[Visual] = []
    if flush:
        v.append(box(D - t, W, H, -t / 2, 0, H / 2, color=color, material=material, name="body"))
        v.append(box(t, W, z0, front - t / 2, 0, z0 / 2, color=color, material=material,
                     name="plinth"))
        if panel_h:
            v.append(box(t, W, panel_h, front - t / 2, 0, panel_zc, color=panel_color,
                         name="panel"))
        knob_x, door_x, face_x = front, front - t / 2, front
    else:
        v.append(box(D, W, H, 0, 0, H / 2, color=color, material=material, name="body"))
        door_x = front + 0.002 + t / 2
        if ctx.chance(0.5) and panel_h:         # the panel stands out further than the door
            out = _mm(t + ctx.u(0.015, 0.04))
        else:                                   # the door stands out; a thin panel plate
            out = 0.004
        if panel_h:
            v.append(box(out, W, panel_h, front + out / 2, 0, panel_zc, color=panel_color,
                         name="panel"))
        knob_x = front + (out if panel_h else 0.0)
        face_x = max(front + 0.002 + t, knob_x)
    hob_h = 0.0
    if kind in ("cooker", "hob"):
        hob_h = 0.008
        v.append(box(D - 0.02, W - 0.02, hob_h, 0, 0, H + hob_h / 2, color=BLACK, name="hob"))
        for x, y in [(x, y) for x in (-0.14, 0.06) for y in (-W / 4, W / 4)][:ctx.i(2, 4)]:
            v.append(cyl(_mm(ctx.u(0.06, 0.09)), 0.003, x, y, H + hob_h + 0.0015,
                         color=(0.3, 0.3, 0.32), name="burner"))
    door_top = H - 0.01 if panel_low else H - panel_h - 0.01
    if kind in ("oven", "cooker"):
        door_h = _mm(door_top - door_z0)
        door_color, door_mat = ctx.pick([(DARK, "shiny"), (BLACK, "glass"), (color, material),
                                         (DARK, "matte")])
        if ctx.chance(cfg.mesh_probability):
            face = Visual("mesh", file=ctx.meshes.add("oven-door", _oven_door_mesh(t, W - 0.01, door_h)),
                          color=door_color, material=door_mat, name="face")
        else:
            face = box(t, W - 0.01, door_h, 0, 0, door_h / 2, color=door_color, material=door_mat,
                       name="face")
        standoff = _mm(ctx.u(0.025, 0.045))
        handle = Handle(f"{oid}_door_handle",
                        Pose(_mm(t / 2 + standoff), 0.0, _mm(door_h - ctx.u(0.04, 0.08)), -math.pi / 2, 0, 0),
                        radius=_mm(ctx.u(0.008, 0.012)), length=_mm(W * ctx.u(0.5, 0.8)),
                        standoff=standoff)
        door = Part(f"{oid}_door", "door",
                    Joint("revolute", origin=Pose(_mm(door_x), 0.0, door_z0), axis=(0.0, 1.0, 0.0),
                          lower=0.0, upper=_deg(math.radians(ctx.u(85, 95))), state=0.0),
                    name="oven door", model=Model([face]), handles=[handle])
    else:
        side = ctx.pick([+1, -1])
        door = _hinged_door(ctx, f"{oid}_door", "door", door_x - t / 2 - 0.002, side * W / 2,
                            _mm(W - 0.006), _mm(door_top - door_z0), door_z0, side, color, t,
                            _mm((door_top - door_z0) * 0.8))
        door.model.visuals[0].material = material
    # Knobs in a row, centred: on the front panel, or on the top near the front edge.
    span = W - 0.12
    ky = [_mm(span / 2 - span * (i + 0.5) / n_knobs) for i in range(n_knobs)]
    pitch = span / n_knobs
    max_r = min(pitch / 2.4, (panel_h / 2 - 0.01) if panel_h else 0.03)
    if top_knobs:
        kx, kz = _mm(front - ctx.u(0.05, 0.08)), _mm(H + hob_h)
        knobs = _knobs(ctx, oid, n_knobs, lambda i: Pose(kx, ky[i], kz, 0, 0, math.pi / 2), max_r,
                       pitch)
        knob_view = View("knobs", (kx, 0.0, kz), (0.0, 0.0, 1.0), max_angle=math.radians(62))
    else:
        kx, kz = _mm(knob_x), _mm(panel_zc)
        knobs = _knobs(ctx, oid, n_knobs, lambda i: _rot_pose(_R_FRONT, kx, ky[i], kz), max_r,
                       pitch)
        knob_view = View("knobs", (kx, 0.0, kz), (1.0, 0.0, 0.0), max_angle=math.radians(55))
    if lift:
        # the whole oven on a cabinet of ``lift``
        v = [replace(x, pose=replace(x.pose, z=_mm(x.pose.z + lift))) for x in v]
        v.append(box(D, W, lift, 0, 0, lift / 2, color=color, material=material, name="cabinet"))
        door.joint.origin = replace(door.joint.origin, z=_mm(door.joint.origin.z + lift))
        for k in knobs:
            k.pose = replace(k.pose, z=_mm(k.pose.z + lift))
        knob_view = replace(knob_view, point=(knob_view.point[0], 0.0, _mm(knob_view.point[2] + lift)))
    names = {"oven": "oven", "cooker": "cooker", "hob": "hob"}
    obj = LargeArticulatedObject(
        id=oid, type=kind, name=ctx.ids.name(f"{ctx.room_name} {names[kind]}"), pose=Pose(),
        model=Model(v), affordances=["appliance", "openable"], parts=[door], knobs=knobs,
        description=f"{'flush' if flush else 'stepped'} front, {n_knobs} knobs "
                    f"{'on top' if top_knobs else 'on the front panel'}"
                    f"{' below the door' if panel_low else ''}{' raised on a cabinet' if lift else ''}")
    views = [View("face", (face_x, 0.0, lift + H / 2)), knob_view]
    reach = [(k.pose.x, k.pose.y, k.pose.z) for k in knobs] + [tuple(_handle_point(door))]
    return Piece(obj, "wall", front_parking(ctx, oid, face_x, W), views=views, reach=reach)


def _oven_door_mesh(t: float, width: float, height: float):
    """An oven door: a slab with a window frame standing 5 mm proud around the glass."""
    slab = box_mesh((0.0, 0.0, height / 2), (t, width, height))
    b = 0.06
    r = 0.005
    frame = [box_mesh((t / 2 + r / 2, 0.0, b / 2 + 0.04), (r, width - 0.02, b)),
             box_mesh((t / 2 + r / 2, 0.0, height - b / 2 - 0.1), (r, width - 0.02, b)),
             box_mesh((t / 2 + r / 2, width / 2 - b / 2 - 0.01, height / 2 - 0.03), (r, b, height - 0.26)),
             box_mesh((t / 2 + r / 2, -width / 2 + b / 2 + 0.01, height / 2 - 0.03), (r, b, height - 0.26))]
    return merge(slab, *frame)


def chair(ctx: _Ctx) -> Piece:
    """A chair (not static: never a landmark), its model from the home's library."""
    design = f"chair_design_{ctx.i(1, 3)}"
    if design not in ctx.library:
        c = ctx.pick(WOODS + PAINTS)
        s, hseat = _mm(ctx.u(0.4, 0.48)), _mm(ctx.u(0.42, 0.48))
        ctx.library[design] = Model([
            box(s, s, 0.03, 0, 0, hseat, color=c, name="seat"),
            box(0.03, s, _mm(ctx.u(0.35, 0.5)), -s / 2 + 0.015, 0, hseat + 0.2, color=c, name="back"),
            *[box(0.03, 0.03, hseat - 0.015, sx * (s / 2 - 0.03), sy * (s / 2 - 0.03),
                  (hseat - 0.015) / 2, color=c, name="leg") for sx in (-1, 1) for sy in (-1, 1)]])
    oid = ctx.ids.new("chair")
    obj = LargeObject(id=oid, type="chair", name=ctx.ids.name(f"{ctx.room_name} chair"), pose=Pose(),
                      model=Model(ref=design), static=False, affordances=["seat"])
    d = _mm(ctx.u(0.6, 0.8))
    return Piece(obj, "free", [ParkingPosition(f"{oid}_back", Pose.planar(-d, 0.0, 0.0)),
                               ParkingPosition(f"{oid}_front", Pose.planar(d, 0.0, math.pi))])


