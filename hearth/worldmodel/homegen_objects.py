"""Small objects of generated homes: kinds and their models (cups, bowls, bottles, ...), and
their placement on, in and under the furniture placed (``small_objects``)."""
from __future__ import annotations

import math
from typing import Optional

from hearth.worldmodel.homegen_palette import CLOSE_HUES, COLOURS, STEEL
from hearth.worldmodel.homegen_pieces import box, _Ctx, cyl, _deg, _level_compose, _mm, Piece
from hearth.worldmodel.nodes import DefaultPosition, GraspPoint, Model, SmallObject, Surface
from hearth.worldmodel.pose import Pose


# -- small objects ------------------------------------------------------------------------------

#: kind -> (type words, builder(ctx, rgb) -> (visuals, height, radius), where it goes)
def _cup(ctx, rgb, mug=False):
    r = _mm(ctx.u(0.042, 0.05) if mug else ctx.u(0.034, 0.044))
    h = _mm(ctx.u(0.095, 0.12) if mug else ctx.u(0.075, 0.1))
    return [cyl(r, h, z=h / 2, color=rgb, name="body"),
            box(0.035 if mug else 0.03, 0.012, h * 0.6, r + 0.014, 0, h / 2, color=rgb,
                name="handle")], h, r + 0.03


def _bowl(ctx, rgb):
    r, h = _mm(ctx.u(0.06, 0.09)), _mm(ctx.u(0.045, 0.07))
    return [cyl(r, h, z=h / 2, color=rgb, name="body")], h, r


def _bottle(ctx, rgb):
    r, h = _mm(ctx.u(0.028, 0.038)), _mm(ctx.u(0.15, 0.22))
    return [cyl(r, h, z=h / 2, color=rgb, name="body"),
            cyl(0.013, 0.05, z=h + 0.025, color=rgb, name="neck"),
            cyl(0.015, 0.015, z=h + 0.057, color=(0.9, 0.9, 0.9), name="cap")], h + 0.065, r


def _box(ctx, rgb):
    sx, sy, sz = _mm(ctx.u(0.06, 0.13)), _mm(ctx.u(0.05, 0.1)), _mm(ctx.u(0.05, 0.16))
    return [box(sx, sy, sz, z=sz / 2, color=rgb, name="body")], sz, math.hypot(sx, sy) / 2


def _pill_box(ctx, rgb):
    sx, sy, sz = _mm(ctx.u(0.05, 0.07)), _mm(ctx.u(0.09, 0.13)), _mm(ctx.u(0.025, 0.035))
    label = ctx.pick([c for n, c in COLOURS.items() if c != rgb and n not in ("white", "black")])
    return [box(sx, sy, sz, z=sz / 2, color=rgb, name="body"),
            box(sx + 0.002, sy * 0.4, 0.002, z=sz + 0.001, color=label, name="label")], sz, math.hypot(sx, sy) / 2


def _book(ctx, rgb):
    w, l, th = _mm(ctx.u(0.13, 0.18)), _mm(ctx.u(0.19, 0.25)), _mm(ctx.u(0.02, 0.045))
    if ctx.chance(0.5):        # standing, spine out
        return [box(l * 0.75, th, w * 1.3, z=w * 0.65, color=rgb, name="body")], w * 1.3, math.hypot(l * 0.75, th) / 2
    return [box(w, l, th, z=th / 2, color=rgb, name="body")], th, math.hypot(w, l) / 2


def _can(ctx, rgb):
    r, h = 0.033, _mm(ctx.u(0.1, 0.125))
    return [cyl(r, h, z=h / 2, color=rgb, name="body"),
            cyl(0.03, 0.004, z=h + 0.002, color=STEEL, name="lid")], h + 0.004, r


def _jar(ctx, rgb):
    r, h = _mm(ctx.u(0.04, 0.05)), _mm(ctx.u(0.09, 0.14))
    return [cyl(r, h, z=h / 2, color=(0.8, 0.85, 0.85), material="glass", name="body"),
            cyl(r + 0.003, 0.02, z=h + 0.01, color=rgb, name="lid")], h + 0.02, r


def _remote(ctx, rgb):
    return [box(0.05, 0.17, 0.022, z=0.011, color=rgb, name="body")], 0.022, 0.09


SMALL_KINDS = {
    "cup": (lambda c, rgb: _cup(c, rgb), "ceramic cup"),
    "mug": (lambda c, rgb: _cup(c, rgb, mug=True), "large mug"),
    "bowl": (_bowl, "bowl"),
    "bottle": (_bottle, "plastic bottle"),
    "box": (_box, "cardboard box"),
    "pill box": (_pill_box, "weekly pill box"),
    "book": (_book, "book"),
    "can": (_can, "tin can"),
    "jar": (_jar, "glass jar"),
    "remote": (_remote, "remote control"),
}


def _tokens(text: str) -> set[str]:
    from hearth.worldmodel.world import tokens
    return set(tokens(text))


class _SmallPlacer:
    """Puts small objects on free spots of the home's surfaces."""

    def __init__(self, ctx: _Ctx, pieces: list[Piece]):
        self.ctx = ctx
        self.pieces = pieces
        self.words: list[tuple[set, set]] = []      # (query words, all words) per object
        self.spots: dict[tuple[str, str], list[tuple[float, float, float]]] = {}

    def slots(self, want: str) -> list[tuple[Piece, Surface]]:
        """Surfaces of one kind: table (tops of tables), shelf_low (open shelves up to
        0.5 m), shelf (other open shelves), closed (inside closed doors), top (tops of
        cupboards and drawers), under (tables tall enough to put something under)."""
        cfg = self.ctx.cfg
        out = []
        for pc in self.pieces:
            o = pc.obj
            for s in o.surfaces:
                z = s.pose.z + pc.lift
                if z > cfg.max_object_height or not pc.parking:
                    continue
                if want == "table" and o.type == "table" and s.id == "top":
                    out.append((pc, s))
                elif want == "shelf_low" and o.type == "bookshelf" and s.id != "top" and z <= 0.5:
                    out.append((pc, s))
                elif want == "shelf" and o.type == "bookshelf" and z > 0.5:
                    out.append((pc, s))
                elif want == "closed" and s.relation == "in":
                    out.append((pc, s))
                elif want == "top" and o.type != "table" and s.id == "top":
                    out.append((pc, s))
            if want == "under" and o.type == "table" and o.surfaces[0].pose.z >= 0.6 \
                    and o.surfaces[0].size_x >= 0.5 and o.surfaces[0].size_y >= 0.5:
                s = o.surfaces[0]
                out.append((pc, Surface("under", Pose(0, 0, 0), _mm(s.size_x - 0.2),
                                        _mm(s.size_y - 0.2), "under")))
        return out

    def colour_for(self, kind: str, avoid: Optional[str] = None) -> Optional[str]:
        names = [n for n in COLOURS if n != avoid]
        order = self.ctx.rng.permutation(len(names))
        for i in order:
            if self._unique(names[i], kind):
                return names[i]
        return None

    def _unique(self, colour: str, kind: str) -> bool:
        q = _tokens(f"{colour} {kind}")
        allw = q | _tokens(SMALL_KINDS[kind][1]) | _tokens(f"{colour}_{kind}".replace(" ", "_"))
        for q2, all2 in self.words:
            if q <= all2 or q2 <= allw:
                return False
        return True

    def place(self, kind: str, colour: str, where: str) -> Optional[SmallObject]:
        ctx = self.ctx
        slots = self.slots(where)
        if not slots:
            return None
        rgb = COLOURS[colour]
        make, desc = SMALL_KINDS[kind]
        visuals, height, radius = make(ctx, rgb)
        for _ in range(30):
            pc, s = slots[int(ctx.rng.integers(len(slots)))]
            head = pc.headroom.get(s.id, pc.obj.surfaces[0].pose.z - 0.05 if s.relation == "under" else math.inf)
            if height > head - 0.03:
                continue
            hx, hy = s.size_x / 2 - radius - 0.02, s.size_y / 2 - radius - 0.02
            if hx <= 0 or hy <= 0:
                continue
            # inside and on shelves, near the front half where a camera sees in
            lo_x = 0.0 if s.relation == "in" or pc.obj.type == "bookshelf" else -hx
            if s.relation == "under":          # under a table: near an edge, seen from a side
                lx = ctx.u(-hx, hx)
                ly = ctx.pick([-1, 1]) * ctx.u(hy * 0.5, hy)
            else:
                lx, ly = ctx.u(lo_x, hx), ctx.u(-hy, hy)
            key = (pc.obj.id, s.id)
            taken = self.spots.get(key, [])
            if any(math.hypot(lx - x, ly - y) < radius + r + 0.04 for x, y, r in taken):
                continue
            if s.relation == "under":
                pc.obj.surfaces.append(s)
                pc.headroom["under"] = pc.obj.surfaces[0].pose.z - 0.05
            self.spots.setdefault(key, []).append((lx, ly, radius))
            yaw = _deg(ctx.u(-math.pi, math.pi))
            pose = _level_compose(s.pose, Pose(_mm(lx), _mm(ly), 0.0, 0, 0, yaw))
            type_id = kind.replace(" ", "_")
            oid = ctx.ids.exact(f"{colour}_{type_id}")
            grasp = GraspPoint(Pose(0, 0, _mm(min(height * 0.55, 0.1))))
            obj = SmallObject(id=oid, type=kind, pose=pose, relation=s.relation, color=colour,
                              description=f"{colour} {desc}", grasp_points=[grasp],
                              default_positions=[DefaultPosition(pc.obj.id, s.relation, pose)],
                              model=Model(visuals))
            pc.obj.children.append(obj)
            q = _tokens(f"{colour} {kind}")
            self.words.append((q, q | _tokens(desc) | _tokens(oid)))
            return obj
        return None


def small_objects(ctx: _Ctx, pieces: list[Piece]) -> list[SmallObject]:
    """7-14 small objects: one on a table first (every home can fetch from a table), one on a
    low shelf and one inside a closed cupboard where the home has them, sometimes one under a
    table, a pair close in hue, the rest anywhere they fit."""
    cfg = ctx.cfg
    placer = _SmallPlacer(ctx, pieces)
    n = ctx.i(*cfg.small_objects)
    plan: list[tuple[str, Optional[str], str]] = [
        (ctx.pick(["cup", "mug", "bowl", "bottle"]), None, "table")]
    plan.append((ctx.pick(["book", "box", "cup", "bowl"]), None, "shelf_low"))
    plan.append((ctx.pick(["pill box", "jar", "can", "box", "bottle"]), None, "closed"))
    if ctx.chance(cfg.under_table_probability):
        plan.append((ctx.pick(["box", "bowl", "book"]), None, "under"))
    if ctx.chance(cfg.close_hue_probability):
        a, b = ctx.pick(CLOSE_HUES)
        k = ctx.pick(["cup", "mug", "bottle", "box"])
        plan += [(k, a, "table"), (k, b, ctx.pick(["table", "table", "shelf", "top"]))]
    wheres = ["table", "table", "table", "shelf", "shelf_low", "closed", "top", "top"]
    while len(plan) < n:
        plan.append((ctx.pick(list(SMALL_KINDS)), None, ctx.pick(wheres)))
    out = []
    for kind, colour, where in plan[:max(n, 3)]:
        colour = colour if colour and placer._unique(colour, kind) else placer.colour_for(kind)
        if colour is None:
            continue
        obj = placer.place(kind, colour, where)
        if obj is None and where != "table":
            obj = placer.place(kind, colour, ctx.pick(["table", "top", "shelf"]))
        if obj is not None:
            out.append(obj)
    return out


