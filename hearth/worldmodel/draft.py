"""A drafted world: the semantic draft of hearth/perception/semantic_map.py as a world file.

``draft_world(draft)`` turns rooms and labelled objects into an ``Apartment`` with draft ids
(``kitchen_1``, ``cupboard_2``, ``cupboard_2_door_1``...) that a person renames
(``rename``). Each room is the draft's best rectangle (the format's rooms are rectangles with
a pose). Each object is a box model (its closed outline) with its parts (doors hinged on the
edge away from their handle, drawers, an oven's door hinged at the bottom), handles and knobs
where they were seen, surfaces at its horizontal levels, and parking positions proposed in
front of it (around a table) and kept only where the generator would keep them
(``hearth.worldmodel.homegen``: inside the room by the robot's radius, clear of every footprint, the
camera sees its face and the arm reaches its handles and knobs). A knob's states are not seen:
it gets the placeholder states ``off`` / ``on`` and is listed in ``unlabelled`` for a person to
fill in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.nodes import (
    Apartment, Handle, Joint, Knob, KnobState, LargeArticulatedObject, LargeObject, Model,
    ParkingPosition, Part, Room, Surface, Visual,
)
from hearth.worldmodel.pose import Pose

#: Types with doors or drawers (LargeArticulatedObject), and appliances.
ARTICULATED = ("cupboard", "wardrobe", "sideboard", "cabinet", "drawers", "fridge", "oven",
               "cooker", "hob")
APPLIANCES = ("oven", "cooker", "hob", "fridge")
#: Room names from what a room holds (the first rule that matches).
ROOM_RULES = (("kitchen", ("oven", "cooker", "hob", "fridge")), ("bedroom", ("wardrobe",)),
              ("dining room", ("sideboard",)), ("living room", ("bookshelf",)))

_R_FRONT = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])   # knob z out of +x


@dataclass
class DraftResult:
    """The drafted apartment and what could not be labelled (node id or 'object at x, y':
    why), one line each."""
    apartment: Apartment
    unlabelled: list = field(default_factory=list)


class _Ids:
    def __init__(self):
        self.count: dict[str, int] = {}

    def new(self, word: str) -> str:
        word = word.replace(" ", "_")
        self.count[word] = self.count.get(word, 0) + 1
        return f"{word}_{self.count[word]}"


def _room_name(types: list[str]) -> str:
    for name, wanted in ROOM_RULES:
        if any(t in wanted for t in types):
            return name
    return "room"


def draft_world(draft, home_id: str = "draft_home", parking: bool = True) -> DraftResult:
    """The apartment of a labelled ``hearth.perception.semantic_map.Draft`` (map frame = world
    frame). Objects labelled ``none`` (clutter, not furniture) are left out and listed."""
    ids = _Ids()
    unlabelled: list[str] = []
    rooms: list[Room] = []
    for r, rd in enumerate(draft.rooms):
        objs = [o for o in draft.objects if o.room == r]
        name = _room_name([o.type for o in objs])
        room = Room(ids.new(name), name, pose=Pose(_mm(rd.x), _mm(rd.y), 0, 0, 0, _rad(rd.yaw)),
                    bounds=(_mm(-rd.size_x / 2), _mm(-rd.size_y / 2), _mm(rd.size_x / 2),
                            _mm(rd.size_y / 2)))
        T_room_world = np.linalg.inv(room.pose.matrix())
        for o in objs:
            if o.type in ("", "none"):
                unlabelled.append(f"object at x={o.x:.2f} y={o.y:.2f} in {room.id}: not "
                                  f"furniture ({o.confidence:.2f}), left out")
                continue
            room.objects.append(_object(o, ids, T_room_world, unlabelled))
        rooms.append(room)
    for o, why in draft.unlabelled:
        unlabelled.append(f"object at x={o.x:.2f} y={o.y:.2f}: {why}")
    apartment = Apartment(id=home_id, name="Drafted home", rooms=rooms)
    if parking:
        for room in rooms:
            for obj in room.objects:
                propose_parking(room, obj)
            # the format wants a parking position for every large object: one with none is
            # left out of the file and listed (its box, so a person can add it)
            for obj in [o for o in room.objects if not o.parking]:
                room.objects.remove(obj)
                sx, sy, sz = obj.model.visuals[0].size
                unlabelled.append(f"{obj.id} ({obj.type}, {sx:.2f} x {sy:.2f} x {sz:.2f} m at "
                                  f"x={obj.pose.x:.2f} y={obj.pose.y:.2f} in {room.id}): no "
                                  "parking position passes the checks; left out")
    return DraftResult(apartment, unlabelled)


def _mm(v: float) -> float:
    return round(float(v), 4)


def _rad(v: float) -> float:
    return round(math.remainder(float(v), 2 * math.pi), 5)


def _object(o, ids: _Ids, T_room_world: np.ndarray, unlabelled: list) -> LargeObject:
    oid = ids.new(o.type)
    c = T_room_world @ np.array([o.x, o.y, 0.0, 1.0])
    yaw = o.yaw + math.atan2(T_room_world[1, 0], T_room_world[0, 0])
    h = o.z1 - o.z0
    body = Visual("box", Pose(0.0, 0.0, _mm(o.z0 + h / 2)),
                  size=(_mm(o.size_x), _mm(o.size_y), _mm(h)), color=(0.7, 0.7, 0.7), name="body")
    common = dict(id=oid, type=o.type, pose=Pose(_mm(c[0]), _mm(c[1]), 0, 0, 0, _rad(yaw)),
                  name=f"{o.type} {oid.rsplit('_', 1)[1]}", model=Model([body]),
                  description=f"drafted {o.type} ({o.confidence:.2f})",
                  static=o.type != "chair", surfaces=_surfaces(o))
    if o.type not in ARTICULATED:
        aff = ["supporting_surface"] if o.type in ("table", "bookshelf") else ["seat"]
        return LargeObject(**common, affordances=aff)
    obj = LargeArticulatedObject(**common, affordances=(["appliance", "openable"]
                                                        if o.type in APPLIANCES[:3]
                                                        else ["container", "openable"]))
    front = o.size_x / 2
    for i, p in enumerate(o.parts):
        obj.parts.append(_part(oid, i + 1, p, front, o))
    if not obj.parts:
        unlabelled.append(f"{oid}: no handle seen, so no door or drawer drafted")
    for i, k in enumerate(f for f in o.fixtures if f.kind == "knob" and f.side in (0, 4)
                          and o.type in APPLIANCES[:3]):
        obj.knobs.append(_knob(f"{oid}_knob_{i + 1}", k, o))
    if obj.knobs:
        unlabelled.append(f"{oid}: {len(obj.knobs)} knobs with placeholder states off/on "
                          "(their states are not seen)")
    return obj


def _surfaces(o) -> list[Surface]:
    """A table's top and a bookshelf's levels (horizontal levels the camera saw)."""
    if o.type == "table":
        z = o.levels[-1] if o.levels else o.z1
        return [Surface("top", Pose(0, 0, _mm(z)), _mm(max(o.size_x - 0.04, 0.05)),
                        _mm(max(o.size_y - 0.04, 0.05)))]
    if o.type == "bookshelf":
        levels = [z for z in o.levels if z > o.z0 + 0.02] or [o.z1]
        return [Surface("top" if abs(z - o.z1) < 0.03 else f"shelf_{i + 1}", Pose(0, 0, _mm(z)),
                        _mm(max(o.size_x - 0.05, 0.05)), _mm(max(o.size_y - 0.05, 0.05)))
                for i, z in enumerate(levels)]
    return []


def _part(oid: str, n: int, p, front: float, o) -> Part:
    t = 0.02
    hd = p.handle
    standoff = max(0.015, min(0.07, hd.depth))      # face to bar axis
    width, height = p.y1 - p.y0, max(p.z1 - p.z0, 0.05)
    roll = 0.0 if (hd is not None and hd.vertical) else -math.pi / 2
    if p.kind == "drawer":
        pid = f"{oid}_drawer_{n}"
        joint = Joint("prismatic", Pose(_mm(front - t / 2), _mm((p.y0 + p.y1) / 2), _mm(p.z0)),
                      (1.0, 0.0, 0.0), 0.0, _mm(0.75 * o.size_x), 0.0)
        face = Visual("box", Pose(0, 0, _mm(height / 2)), size=(t, _mm(width), _mm(height)),
                      name="face")
        hp = Pose(_mm(t / 2 + standoff), _mm(hd.u - (p.y0 + p.y1) / 2), _mm(hd.v - p.z0), roll)
        name = f"drawer {n} from the bottom"
    elif p.hinge == "bottom":
        pid = f"{oid}_door"
        joint = Joint("revolute", Pose(_mm(front - t / 2), 0.0, _mm(p.z0)), (0.0, 1.0, 0.0),
                      0.0, _mm(math.radians(90)), 0.0)
        face = Visual("box", Pose(0, 0, _mm(height / 2)), size=(t, _mm(width), _mm(height)),
                      name="face")
        hp = Pose(_mm(t / 2 + standoff), _mm(hd.u), _mm(hd.v - p.z0), roll)
        name = "oven door"
    else:
        side = 1 if p.hinge == "+y" else -1          # the hinge on the +y or -y edge
        hinge_y = p.y1 if side > 0 else p.y0
        pid = f"{oid}_door_{n}"
        joint = Joint("revolute", Pose(_mm(front - t / 2), _mm(hinge_y), _mm(p.z0)),
                      (0.0, 0.0, float(side)), 0.0, _mm(math.radians(100)), 0.0)
        face = Visual("box", Pose(0, _mm(-side * width / 2), _mm(height / 2)),
                      size=(t, _mm(width), _mm(height)), name="face")
        hp = Pose(_mm(t / 2 + standoff), _mm(hd.u - hinge_y), _mm(hd.v - p.z0), roll)
        name = f"door {n}"
    handle = Handle(f"{pid}_handle", hp, radius=_mm(max(0.005, min(0.015, hd.width / 4))),
                    length=_mm(max(0.05, hd.length)), standoff=_mm(standoff))
    return Part(pid, p.kind, joint, name=name, model=Model([face]), handles=[handle])


def _knob(kid: str, k, o) -> Knob:
    r = _mm(max(0.01, min(0.04, k.width / 2)))
    if k.side == 4:
        pose = Pose(_mm(k.v), _mm(k.u), _mm(k.position_map[2]), 0, 0, math.pi / 2)
    else:
        T = np.eye(4)
        T[:3, :3] = _R_FRONT
        T[:3, 3] = (_mm(o.size_x / 2 + k.depth), _mm(k.u), _mm(k.v))
        pose = Pose.from_matrix(T)
        pose = Pose(*(round(v, 5) for v in pose.as_tuple()))
    return Knob(kid, pose, [KnobState("off", 0.0), KnobState("on", round(math.pi / 2, 5))],
                "off", radius=r, depth=_mm(max(0.01, min(0.05, k.length / 2))))


# -- parking positions --------------------------------------------------------------------------

def propose_parking(room: Room, obj: LargeObject, config=None) -> None:
    """Parking positions of ``obj`` (room frame footprints of every object in ``room``),
    kept as the home generator keeps them (see the module docstring); sets ``parking`` and
    ``default_parking``."""
    from hearth.worldmodel.homegen_config import HomeConfig
    from hearth.worldmodel.homegen_pieces import View, sees
    from hearth.worldmodel.homegen_geometry import disc_clear
    cfg = config or HomeConfig()
    body = obj.model.visuals[0]
    sx, sy, sz = body.size
    z_top = body.pose.z + sz / 2
    T_ro = obj.pose.matrix()
    hulls = [_footprint(o) for o in room.objects]
    x0, y0, x1, y1 = room.bounds
    r = cfg.robot_radius
    if obj.type in ("table",):
        cands = []
        for d in (0.55, 0.7, 0.85):
            cands += [("south", 0.0, -(sy / 2 + d)), ("north", 0.0, sy / 2 + d),
                      ("west", -(sx / 2 + d), 0.0), ("east", sx / 2 + d, 0.0)]
        views = [View("top", (0.0, 0.0, z_top))]
        reach = [(0.0, 0.0, z_top)]
    elif obj.type == "chair":
        cands = [("front", sx / 2 + d, 0.0) for d in (0.6, 0.8)]
        views, reach = [], []
    else:
        lo = cfg.parking_distance[0]
        spread = min(max(sy / 2 * 0.8, 0.25), 0.6)
        cands = [(name, sx / 2 + d, y) for d in (lo, lo + 0.15, lo + 0.3, lo + 0.45)
                 for name, y in (("front", 0.0), ("left", spread), ("right", -spread))]
        views = [View("face", (sx / 2, 0.0, body.pose.z - sz / 2 + min(sz / 2, 1.0)))]
        reach = _reach_points(obj)
    keep: dict[str, ParkingPosition] = {}
    for name, x, y in cands:
        pid = f"{obj.id}_{name}"
        if pid in keep:
            continue
        yaw = math.atan2(-y, -x) if obj.type != "chair" else math.pi
        pose = Pose.planar(_mm(x), _mm(y), round(yaw, 5))
        if not all(sees(cfg, pose, v) for v in views):
            continue
        if any(math.hypot(p[0] - x, p[1] - y) > cfg.reach for p in reach):
            continue
        q = T_ro @ np.array([x, y, 0.0, 1.0])
        if not (x0 + r + 0.01 <= q[0] <= x1 - r - 0.01 and y0 + r + 0.01 <= q[1] <= y1 - r - 0.01):
            continue
        if not all(disc_clear((q[0], q[1]), h, r + 0.02) for h in hulls):
            continue
        keep[pid] = ParkingPosition(pid, pose)
    obj.parking = list(keep.values())
    obj.default_parking = obj.parking[0].id if obj.parking else ""


def _reach_points(obj) -> list[tuple]:
    from hearth.worldmodel.geometry import part_T
    out = []
    if isinstance(obj, LargeArticulatedObject):
        for p in obj.parts:
            for h in p.handles:
                out.append(tuple((part_T(p, 0.0) @ np.append(h.pose.position, 1.0))[:3]))
        out += [tuple(k.pose.position) for k in obj.knobs]
    return out


def _footprint(obj) -> np.ndarray:
    """(4, 2) room-frame corners of an object's body box."""
    sx, sy, _ = obj.model.visuals[0].size
    c, s = math.cos(obj.pose.yaw), math.sin(obj.pose.yaw)
    R = np.array([[c, -s], [s, c]])
    return (np.array([[-sx / 2, -sy / 2], [sx / 2, -sy / 2], [sx / 2, sy / 2],
                      [-sx / 2, sy / 2]]) @ R.T + (obj.pose.x, obj.pose.y))


# -- renaming -----------------------------------------------------------------------------------

#: Attributes that name another node.
_REFERENCES = ("default", "parent", "object", "place", "node", "ref")


def rename(data: bytes, old: str, new: str, name: str = "<world>") -> tuple[bytes, int]:
    """World XML with the node ``old`` renamed ``new`` and every reference to it updated:
    ids and references equal to ``old``, and those starting with ``old_`` (a draft's parts,
    handles, knobs and parking positions carry their object's id), get ``new`` instead.
    Returns the new XML and how many attributes changed; WorldError when ``old`` is no node's
    id or ``new`` is already one."""
    import re
    from lxml import etree
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-]*", new or ""):
        raise WorldError(f"{new!r} is not a valid id (letters, digits, _ . -; not starting with "
                         "a digit)", file=name, line=0)
    root = etree.fromstring(data, etree.XMLParser(resolve_entities=False, no_network=True,
                                                  remove_blank_text=False))
    ids = {el.get("id") for el in root.iter() if isinstance(el.tag, str) and el.get("id")}
    if old not in ids:
        raise WorldError(f"no node with id {old!r}", file=name, line=0)
    if new in ids:
        raise WorldError(f"a node with id {new!r} is already there", file=name, line=0)

    def renamed(v: str) -> Optional[str]:
        if v == old:
            return new
        if v.startswith(old + "_"):
            return new + v[len(old):]
        return None

    changed = 0
    for el in root.iter():
        if not isinstance(el.tag, str):
            continue
        for attr in ("id",) + _REFERENCES:
            v = el.get(attr)
            if v is not None and (nv := renamed(v)) is not None:
                el.set(attr, nv)
                changed += 1
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8"), changed


# -- the picture --------------------------------------------------------------------------------

def draw_draft(world, points_map: np.ndarray, colors: np.ndarray, px_per_m: int = 80,
               margin_m: float = 0.4) -> np.ndarray:
    """An RGB picture of the draft over the fused map from above (world x right, y up): the
    map's points under the ceiling in their colours, each room's rectangle, each object's box
    with its id and an arrow to its front, handles (blue) and knobs (red)."""
    import cv2
    from hearth.worldmodel.frames import room_corners
    from hearth.worldmodel.geometry import part_T
    P = np.asarray(points_map, float)
    C = np.asarray(colors, float)
    keep = P[:, 2] < 2.2
    P, C = P[keep], C[keep]
    corners = [room_corners(r) for r in world.rooms if r.bounds is not None]
    pts = np.vstack(corners + [P[:, :2]]) if len(P) else np.vstack(corners)
    x0, y0 = pts.min(0) - margin_m
    x1, y1 = pts.max(0) + margin_m
    W, H = int((x1 - x0) * px_per_m) + 1, int((y1 - y0) * px_per_m) + 1
    img = np.full((H, W, 3), 255, np.uint8)
    if len(P):
        order = np.argsort(P[:, 2])                  # the highest point of a pixel on top
        u = ((P[order, 0] - x0) * px_per_m).astype(int)
        v = ((y1 - P[order, 1]) * px_per_m).astype(int)
        img[v.clip(0, H - 1), u.clip(0, W - 1)] = (C[order] * 255).clip(0, 255).astype(np.uint8)

    def px(x, y):
        return int(round((x - x0) * px_per_m)), int(round((y1 - y) * px_per_m))

    for room, cs in zip(world.rooms, corners):
        cv2.polylines(img, [np.array([px(*c) for c in cs], np.int32)], True, (20, 20, 200), 2,
                      cv2.LINE_AA)
        c = cs.mean(0)
        cv2.putText(img, room.id, px(c[0], c[1]), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (20, 20, 200), 1,
                    cv2.LINE_AA)
    for room in world.rooms:
        T_wr = room.pose.matrix()
        for o in room.objects:
            T_wo = T_wr @ o.pose.matrix()
            fp = _footprint(o)
            fp_w = (T_wr[:2, :2] @ fp.T).T + T_wr[:2, 3]
            cv2.polylines(img, [np.array([px(*p) for p in fp_w], np.int32)], True, (0, 140, 0), 2,
                          cv2.LINE_AA)
            c = T_wo[:2, 3]
            sx = o.model.visuals[0].size[0]
            tip = T_wo[:2, 3] + T_wo[:2, 0] * (sx / 2 + 0.25)
            cv2.arrowedLine(img, px(*c), px(*tip), (0, 140, 0), 1, cv2.LINE_AA, tipLength=0.2)
            cv2.putText(img, o.id, px(c[0] - 0.3, c[1]), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (0, 90, 0), 1, cv2.LINE_AA)
            if isinstance(o, LargeArticulatedObject):
                for p in o.parts:
                    for h in p.handles:
                        q = T_wo @ part_T(p, 0.0) @ np.append(h.pose.position, 1.0)
                        cv2.circle(img, px(q[0], q[1]), 3, (30, 60, 230), -1)
                for k in o.knobs:
                    q = T_wo @ np.append(k.pose.position, 1.0)
                    cv2.circle(img, px(q[0], q[1]), 3, (220, 30, 30), -1)
    return img
