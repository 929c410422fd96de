"""The in-memory semantic map: queries, updates with history, change notifications.

``World`` wraps an ``Apartment`` tree and keeps indexes (id -> node, id -> parent, word ->
ids). Every update goes through a method here so that history is recorded, indexes stay
right and subscribers hear about it. All methods are thread-safe.
"""
from __future__ import annotations

import copy
import re
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Optional

import numpy as np

from hearth.util.subscribers import Subscribers
from hearth.worldmodel.errors import UnknownNode, WorldError
from hearth.worldmodel.nodes import (
    Apartment, HistoryEntry, Knob, LargeObject, ParkingPosition,
    Part, Room, SearchStat, SmallObject,
)
from hearth.worldmodel.frames import joint_T, knob_T, planar_of
from hearth.worldmodel.pose import Pose, transform_points
from hearth.worldmodel.validate import LIMIT_EPS, all_parts, coord_problem, iter_nodes

STOPWORDS = frozenset({"the", "a", "an", "my", "me", "of", "please", "some", "your", "our", "this",
                       "that", "is", "where", "find", "bring", "get"})


def tokens(text: str) -> list[str]:
    """Lower-case word tokens with a plural 's' removed ("cups" -> "cup")."""
    out = []
    for t in re.findall(r"[a-z0-9]+", text.lower()):
        if len(t) > 3 and t.endswith("s") and not t.endswith("ss"):
            t = t[:-1]
        out.append(t)
    return out



def _check_pose(pose: Pose, node_id: str) -> None:
    """Refuse a pose a saved map could not hold (NaN, infinite, beyond the map's bounds), at
    the update that brings it rather than at the next save."""
    for name, value in pose.as_dict().items():
        why = coord_problem(float(value))
        if why is not None:
            raise WorldError(f"pose {name}: {why}", node=node_id)


def _check_number(value: float, what: str, node_id: str) -> float:
    why = coord_problem(float(value))
    if why is not None:
        raise WorldError(f"{what}: {why}", node=node_id)
    return float(value)


@dataclass(frozen=True)
class MapChange:
    """What subscribers receive for every update."""
    time: float
    node: str
    field: str
    old: Any
    new: Any
    source: str


@dataclass(frozen=True)
class SurfaceLevel:
    """One supporting surface of a large object in the world frame: ``T_world_surface`` has
    its origin at the centre of the top face, +z up; ``relation`` is on or in. ``part``: the
    part that carries it (a drawer's floor, which moves with the drawer), None for the
    object's own."""
    place: str
    surface: str
    T_world_surface: np.ndarray
    relation: str
    size_x: float
    size_y: float
    part: Optional[str] = None

    @property
    def name(self) -> str:
        """``place/surface``, the form perception's detection takes."""
        return f"{self.place}/{self.surface}"


@dataclass(frozen=True)
class Match:
    node: Any
    score: float


#: Words fit two nodes "about equally" when their ``World.find`` scores differ by less than
#: this. A score counts the words a node holds (1 each: every match holds them all), less
#: 0.01 for each other word of its description, plus 0.5 for a small object; between two
#: nodes of one kind that both hold every word only the 0.01s differ, and a fuller
#: description does not make a node the one a person meant ("mug": a blue mug described in
#: three words and a navy mug in four). Half a word: anything short of a word more decides
#: nothing.
AMBIGUITY_MARGIN = 0.5


def best_matches(matches: list[Match]) -> list[Match]:
    """The matches that fit about as well as the best (``AMBIGUITY_MARGIN``), best first:
    one when the words decide, several when the person must be asked which."""
    if not matches:
        return []
    top = matches[0].score
    return [m for m in matches if m.score > top - AMBIGUITY_MARGIN]


class World:
    def __init__(self, apartment: Apartment, path=None, base_dir=None, clock=None):
        self.apartment = apartment
        self.path = path
        self.base_dir = base_dir
        self.clock = clock
        self.lock = threading.RLock()
        self._subscribers: Subscribers[Callable[[MapChange], None]] = Subscribers()
        self._reindex()

    # -- indexes ------------------------------------------------------------------------
    def _reindex(self) -> None:
        self._nodes: dict[str, Any] = {}
        self._parent: dict[str, Any] = {}
        self._words: dict[str, set[str]] = {}
        self._nwords: dict[str, int] = {}
        for node, parent in iter_nodes(self.apartment):
            self._add_index(node, parent)

    def _add_index(self, node, parent) -> None:
        self._nodes[node.id] = node
        self._parent[node.id] = parent
        words = self._node_words(node)
        self._nwords[node.id] = len(words)
        for w in words:
            self._words.setdefault(w, set()).add(node.id)

    def _drop_words(self, node) -> None:
        for w in self._node_words(node):
            ids = self._words.get(w)
            if ids is not None:
                ids.discard(node.id)

    @staticmethod
    def _node_words(node) -> set[str]:
        parts = getattr(node, "words", None)
        if parts is None:
            parts = [getattr(node, "type", ""), getattr(node, "name", ""), node.id]
        ws: set[str] = set()
        for p in parts:
            ws.update(tokens(p or ""))
            if p and " " not in p:
                ws.add(p.lower())
        return ws

    # -- basic access -------------------------------------------------------------------
    def now(self) -> float:
        return self.clock.wall() if self.clock is not None else time.time()

    def copy(self) -> "World":
        """A deep copy (for a simulator's truth, or a scenario). Subscribers are not copied."""
        with self.lock:
            return World(copy.deepcopy(self.apartment), path=self.path, base_dir=self.base_dir,
                         clock=self.clock)

    def __eq__(self, other) -> bool:
        return isinstance(other, World) and self.apartment == other.apartment

    def get(self, node_id: str):
        try:
            return self._nodes[node_id]
        except KeyError:
            raise UnknownNode("no such node in the map", node=node_id) from None

    def __contains__(self, node_id: str) -> bool:
        return node_id in self._nodes

    def ids(self) -> list[str]:
        return list(self._nodes)

    def nodes(self, kind: Optional[str] = None) -> list:
        return [n for n in self._nodes.values() if kind is None or n.kind == kind]

    @property
    def rooms(self) -> list[Room]:
        return self.apartment.rooms

    def large_objects(self) -> list[LargeObject]:
        return [n for n in self._nodes.values() if isinstance(n, LargeObject)]

    def small_objects(self) -> list[SmallObject]:
        return [n for n in self._nodes.values() if isinstance(n, SmallObject)]

    def knobs(self, node_id: Optional[str] = None) -> list[Knob]:
        if node_id is None:
            return self.nodes("Knob")
        return [n for n in self.descendants(node_id) if isinstance(n, Knob)]

    def parent(self, node_id: str):
        self.get(node_id)
        p = self._parent[node_id]
        return None if isinstance(p, Apartment) else p

    def chain(self, node_id: str) -> list:
        """The node and its ancestors up to (not including) the apartment."""
        out = [self.get(node_id)]
        while True:
            p = self._parent[out[-1].id]
            if isinstance(p, Apartment) or p is None:
                return out
            out.append(p)

    def room_of(self, node_id: str) -> Room:
        for n in self.chain(node_id):
            if isinstance(n, Room):
                return n
        raise UnknownNode("node is in no room", node=node_id)  # pragma: no cover

    def large_object_of(self, node_id: str) -> LargeObject:
        """The large object a node belongs to (itself if it is one)."""
        for n in self.chain(node_id):
            if isinstance(n, LargeObject):
                return n
        raise WorldError("node belongs to no large object", node=node_id)

    def descendants(self, node_id: str) -> list:
        root = self.get(node_id)
        out = []
        for n, p in iter_nodes(self.apartment):
            if p is not None and not isinstance(p, Apartment):
                if any(a is root for a in self.chain(n.id)[1:]):
                    out.append(n)
        return out

    def children_of(self, node_id: str) -> list:
        node = self.get(node_id)
        return [n for n in self._nodes.values() if self._parent.get(n.id) is node]

    # -- queries ------------------------------------------------------------------------
    def find(self, words: str, kinds: Optional[Iterable[str]] = None) -> list[Match]:
        """Nodes whose type, name, description, colour or id contain every word of ``words``.

        "blue cup" matches a cup described as blue. Stop words ("the", "my") are ignored.
        Best matches first: small objects before large ones, then fewer extra words.
        """
        toks = [t for t in tokens(words) if t not in STOPWORDS]
        if not toks:
            return []
        with self.lock:
            sets = sorted((self._words.get(t, set()) for t in toks), key=len)
            hit = sets[0].intersection(*sets[1:]) if sets else set()
            kinds = set(kinds) if kinds else None
            out = []
            for nid in hit:
                node = self._nodes[nid]
                if kinds and node.kind not in kinds:
                    continue
                extra = self._nwords[nid] - len(toks)
                score = len(toks) - 0.01 * extra + (0.5 if isinstance(node, SmallObject) else 0)
                out.append(Match(node, score))
        out.sort(key=lambda m: (-m.score, m.node.id))
        return out

    def parking_positions(self, node_id: str) -> list[tuple[ParkingPosition, Pose]]:
        """(parking position, world base pose x/y/yaw) for the large object a node belongs
        to, the default first."""
        obj = self.large_object_of(node_id)
        T = self.T_world(obj.id)
        out = []
        for p in obj.parking:
            out.append((p, Pose.planar(*planar_of(T @ p.pose.matrix()))))
        out.sort(key=lambda item: item[0].id != obj.default_parking)
        return out

    def chargers(self) -> list:
        """The map's charging stations (``Charger`` nodes), in file order."""
        return self.nodes("Charger")

    def dock_pose(self, charger_id: str) -> Pose:
        """The world base pose (x, y, yaw) the robot docks at on charger ``charger_id``."""
        node = self.get(charger_id)
        if getattr(node, "kind", "") != "Charger":
            raise UnknownNode("not a charger", node=charger_id)
        return Pose.planar(*planar_of(self.T_world(charger_id) @ node.dock.matrix()))

    def parking_pose(self, object_id: str, parking_id: str) -> Pose:
        for p, pose in self.parking_positions(object_id):
            if p.id == parking_id:
                return pose
        raise UnknownNode(f"no parking position {parking_id!r}", node=object_id)

    def local_T(self, node) -> np.ndarray:
        """``T_parent_node`` including joint motion for parts."""
        if isinstance(node, Part):
            return joint_T(node.joint)
        if isinstance(node, Knob):
            return knob_T(node)
        return node.pose.matrix()

    def T_world(self, node_id: str) -> np.ndarray:
        """``T_world_node``: maps points in the node's frame to the world frame, through
        the parent chain including joint states (a door at 30 degrees moves its handle; a
        small object in a drawer moves with the drawer)."""
        with self.lock:
            node = self.get(node_id)
            if isinstance(node, SmallObject) and node.part:
                return self.T_world(node.part) @ node.pose.matrix()
            T = np.eye(4)
            for n in reversed(self.chain(node_id)):
                T = T @ self.local_T(n)
            return T

    def world_pose(self, node_id: str) -> Pose:
        return Pose.from_matrix(self.T_world(node_id))

    def landmarks(self) -> list[LargeObject]:
        """Large objects that do not move (static), usable for localisation."""
        return [o for o in self.large_objects() if o.static]

    def bounds_world(self, node_id: str) -> np.ndarray:
        """(2, 3) axis-aligned world bounds [min, max] of a node's geometry (with children)."""
        from hearth.worldmodel.geometry import node_mesh
        mesh = node_mesh(self, node_id)
        pts = np.asarray(mesh.vertices)
        if len(pts) == 0:
            p = self.T_world(node_id)[:3, 3]
            return np.stack([p, p])
        return np.stack([pts.min(0), pts.max(0)])

    def in_frustum(self, T_world_camera: np.ndarray, intrinsics, max_range: float = 4.0,
                   kinds: Iterable[str] = ("LargeObject", "LargeArticulatedObject", "SmallObject"),
                   min_visible: float = 0.0) -> list[str]:
        """Ids of nodes whose world bounds fall (partly) in the camera frustum.

        ``intrinsics`` has fx, fy, cx, cy, width, height (pixels); the camera frame is
        x right, y down, z forward (OpenCV). A node counts when any corner of its bounds, or
        its centre, projects inside the image in front of the camera within ``max_range``.
        """
        T_camera_world = np.linalg.inv(T_world_camera)
        out = []
        for node in self.nodes():
            if node.kind not in kinds:
                continue
            b = self.bounds_world(node.id)
            corners = np.array([[x, y, z] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]]
                               + [b.mean(0)])
            pc = transform_points(T_camera_world, corners)
            z = pc[:, 2]
            ok = (z > 0.05) & (z < max_range)
            if not ok.any():
                continue
            u = intrinsics.fx * pc[ok, 0] / z[ok] + intrinsics.cx
            v = intrinsics.fy * pc[ok, 1] / z[ok] + intrinsics.cy
            inside = (u >= 0) & (u < intrinsics.width) & (v >= 0) & (v < intrinsics.height)
            if inside.mean() > min_visible if min_visible > 0 else inside.any():
                out.append(node.id)
        return out

    def aim_point(self, node_id: str, focus: str = "centre") -> np.ndarray:
        """The world point (metres) to point a camera at for a node: the centre of its world
        bounds; with ``focus="top"`` the centre of their top face; with ``focus="knobs"`` the
        mean of its knobs (when it has any)."""
        if focus == "knobs" and self.knobs(node_id):
            return np.mean([self.T_world(k.id)[:3, 3] for k in self.knobs(node_id)], axis=0)
        lo, hi = self.bounds_world(node_id)
        c = (lo + hi) / 2
        if focus == "top":
            c[2] = hi[2]
        return c

    def surfaces_of(self, node_id: str) -> list["SurfaceLevel"]:
        """The supporting surfaces of the large object a node belongs to, in the world frame,
        highest first."""
        obj = self.large_object_of(node_id)
        T = self.T_world(obj.id)
        out = [SurfaceLevel(obj.id, s.id, T @ s.pose.matrix(), s.relation, s.size_x, s.size_y)
               for s in obj.surfaces]
        for part in all_parts(obj):
            if part.surfaces:
                Tp = self.T_world(part.id)
                out += [SurfaceLevel(obj.id, s.id, Tp @ s.pose.matrix(), s.relation, s.size_x,
                                     s.size_y, part.id) for s in part.surfaces]
        out.sort(key=lambda lv: (-lv.T_world_surface[2, 3], lv.surface))
        return out

    def surface_near(self, node_id: str, point) -> Optional["SurfaceLevel"]:
        """The surface of a large object nearest a world point (metres) by height, among those
        whose extent (grown by 5 cm) holds the point's x, y; else the nearest by height."""
        levels = self.surfaces_of(node_id)
        if not levels:
            return None
        p = np.asarray(point, dtype=float)[:3]

        def key(lv):
            local = np.linalg.inv(lv.T_world_surface) @ np.append(p, 1.0)
            inside = abs(local[0]) <= lv.size_x / 2 + 0.05 and abs(local[1]) <= lv.size_y / 2 + 0.05
            # Objects stand on a surface: one just above it is on it, one below is not.
            return (not inside, abs(local[2]) if local[2] >= -0.02 else 1.0 + abs(local[2]))
        return min(levels, key=key)

    def handover_spot(self, x: float, y: float, max_distance: float = 1.2,
                      inset: float = 0.08) -> Optional[tuple[str, Pose, str]]:
        """Where an object handed over at the robot base (world x, y) is put down: the point
        of the nearest open surface (relation "on", 0.3-1.3 m high) closest to the base,
        ``inset`` metres inside its edge, within ``max_distance`` of the base. Returns
        (large object id, pose in its frame, relation) or None."""
        best = None
        for obj in self.large_objects():
            for lv in self.surfaces_of(obj.id):
                h = lv.T_world_surface[2, 3]
                if lv.relation != "on" or not 0.3 <= h <= 1.3:
                    continue
                T_inv = np.linalg.inv(lv.T_world_surface)
                q = T_inv[:2, :2] @ (x, y) + T_inv[:2, 3]
                hx, hy = max(lv.size_x / 2 - inset, 0.0), max(lv.size_y / 2 - inset, 0.0)
                spot = np.array([np.clip(q[0], -hx, hx), np.clip(q[1], -hy, hy), 0.0, 1.0])
                d = float(np.hypot(*(q - spot[:2])))
                if d <= max_distance and (best is None or d < best[0]):
                    p_world = lv.T_world_surface @ spot
                    best = (d, obj.id, p_world, lv.relation)
        if best is None:
            return None
        _, oid, p_world, relation = best
        local = np.linalg.inv(self.T_world(oid)) @ p_world
        return oid, Pose(float(local[0]), float(local[1]), float(local[2])), relation

    def support_at(self, point, margin: float = 0.05,
                   max_distance: float = 0.5) -> Optional[tuple[LargeObject, float]]:
        """The large object that can hold small objects and that a world point (metres) is
        on or in: the one whose world bounds, grown by ``margin``, contain the point (the
        smallest first), else the nearest by distance to its bounds within
        ``max_distance``. Returns (object, distance) or None."""
        point = np.asarray(point, dtype=float)[:3]
        best = None
        for obj in self.large_objects():
            if not holds_small_objects(obj):
                continue
            lo, hi = self.bounds_world(obj.id)
            gap = np.maximum(0.0, np.maximum(lo - margin - point, point - hi - margin))
            key = (float(np.linalg.norm(gap)), float(np.prod(hi - lo)))
            if best is None or key < best[0]:
                best = (key, obj)
        if best is None or best[0][0] > max_distance:
            return None
        return best[1], best[0][0]

    def compact_history(self, max_entries: int) -> int:
        """Keep the newest ``max_entries`` history entries; returns how many were dropped."""
        with self.lock:
            extra = len(self.apartment.history) - max(0, int(max_entries))
            if extra > 0:
                del self.apartment.history[:extra]
            return max(extra, 0)

    def history(self, node_id: Optional[str] = None) -> list[HistoryEntry]:
        with self.lock:
            return [h for h in self.apartment.history if node_id is None or h.node == node_id]

    def describe_location(self, node_id: str) -> str:
        """Words for where a small object is: "on the kitchen table"."""
        node = self.get(node_id)
        parent = self.parent(node_id)
        if isinstance(node, SmallObject) and parent is not None:
            pname = parent.name or parent.type
            if node.part and node.part in self:
                part = self.get(node.part)
                words = part.name or part.type
                # "in drawer 3 from the bottom of ...", "in the top drawer of ..."
                the = "" if any(ch.isdigit() for ch in words) else "the "
                return f"{node.relation} {the}{words} of the {pname}"
            return f"{node.relation} the {pname}"
        room = self.room_of(node_id)
        return f"in the {room.name}"

    def label(self, node_id: str) -> str:
        """A short name people use: "blue cup", "kitchen table"."""
        n = self.get(node_id)
        if getattr(n, "name", ""):
            return n.name
        if isinstance(n, SmallObject) and n.color:
            return f"{n.color} {n.type}"
        return getattr(n, "type", n.id)

    # -- updates ------------------------------------------------------------------------
    def subscribe(self, callback: Callable[[MapChange], None]) -> Callable[[], None]:
        """Call ``callback(MapChange)`` after every update; returns an unsubscribe function."""
        return self._subscribers.add(callback)

    def _record(self, node_id: str, field: str, old: Any, new: Any, source: str) -> MapChange:
        t = self.now()
        self.apartment.history.append(HistoryEntry(t, node_id, field, _text(old), _text(new), source))
        return MapChange(t, node_id, field, old, new, source)

    def _notify(self, changes: list[MapChange]) -> None:
        for ch in changes:
            for cb in self._subscribers:
                cb(ch)

    def move_object(self, object_id: str, new_parent: str, pose: Pose, relation: str = "on",
                    source: str = "", part: str = "") -> None:
        """Move a small object to ``new_parent`` (a large object) at ``pose`` (in the new
        parent's frame; with ``part``, a part of the new parent such as a drawer, in that
        part's frame: the object then moves with the part)."""
        if relation not in ("on", "in", "under"):
            raise WorldError(f"relation must be on, in or under, not {relation!r}", node=object_id)
        with self.lock:
            obj = self.get(object_id)
            if not isinstance(obj, SmallObject):
                raise WorldError("only small objects can be moved", node=object_id)
            _check_pose(pose, object_id)
            target = self.get(new_parent)
            if not isinstance(target, LargeObject):
                raise WorldError(f"new parent {new_parent!r} is not a large object", node=object_id)
            if part and part not in {p.id for p in all_parts(target)}:
                raise WorldError(f"{part!r} is not a part of {new_parent!r}", node=object_id)
            old_parent = self._parent[object_id]
            changes = []
            if old_parent is not target:
                old_parent.children.remove(obj)
                target.children.append(obj)
                self._parent[object_id] = target
                changes.append(self._record(object_id, "parent", old_parent.id, target.id, source))
            if obj.relation != relation:
                changes.append(self._record(object_id, "relation", obj.relation, relation, source))
                obj.relation = relation
            if obj.part != part:
                changes.append(self._record(object_id, "part", obj.part, part, source))
                obj.part = part
            changes.append(self._record(object_id, "pose", obj.pose, pose, source))
            obj.pose = pose
        self._notify(changes)

    def set_joint_state(self, part_id: str, value: float, source: str = "") -> None:
        """Set a part's joint state (radians for revolute, metres for prismatic)."""
        with self.lock:
            part = self.get(part_id)
            if not isinstance(part, Part):
                raise WorldError("not a part with a joint", node=part_id)
            j = part.joint
            if j.type == "fixed":
                raise WorldError("a fixed joint has no state", node=part_id)
            value = _check_number(value, "joint state", part_id)
            if not (j.lower - LIMIT_EPS <= value <= j.upper + LIMIT_EPS):
                raise WorldError(f"joint state {value} outside limits [{j.lower}, {j.upper}]",
                                 node=part_id)
            ch = self._record(part_id, "joint.state", j.state, float(value), source)
            j.state = float(value)
        self._notify([ch])

    def set_knob_state(self, knob_id: str, state: str, angle: Optional[float] = None,
                       source: str = "") -> None:
        """Set a knob's discrete state (and its angle; default: the state's angle)."""
        with self.lock:
            knob = self.get(knob_id)
            if not isinstance(knob, Knob):
                raise WorldError("not a knob", node=knob_id)
            try:
                a = (knob.state_angle(state) if angle is None
                     else _check_number(angle, "knob angle", knob_id))
            except KeyError:
                raise WorldError(f"unknown knob state {state!r}; states: "
                                 f"{[s.name for s in knob.states]}", node=knob_id) from None
            changes = []
            if knob.state != state:
                changes.append(self._record(knob_id, "knob.state", knob.state, state, source))
            if knob.angle != a:
                changes.append(self._record(knob_id, "knob.angle", knob.angle, a, source))
            knob.state, knob.angle = state, a
        self._notify(changes)

    def set_pose(self, node_id: str, pose: Pose, source: str = "") -> None:
        """Set any node's pose relative to its parent (e.g. a registered large object)."""
        with self.lock:
            node = self.get(node_id)
            if not hasattr(node, "pose") or isinstance(node, Part):
                raise WorldError("node has no pose of its own", node=node_id)
            _check_pose(pose, node_id)
            ch = self._record(node_id, "pose", node.pose, pose, source)
            node.pose = pose
        self._notify([ch])

    def add_small_object(self, obj: SmallObject, parent_id: str, source: str = "") -> None:
        with self.lock:
            if obj.id in self._nodes:
                raise WorldError("id already used", node=obj.id)
            _check_pose(obj.pose, obj.id)
            parent = self.get(parent_id)
            if not isinstance(parent, LargeObject):
                raise WorldError(f"parent {parent_id!r} is not a large object", node=obj.id)
            parent.children.append(obj)
            self._add_index(obj, parent)
            ch = self._record(obj.id, "added", "", parent_id, source)
        self._notify([ch])

    def remove_small_object(self, object_id: str, source: str = "") -> None:
        with self.lock:
            obj = self.get(object_id)
            if not isinstance(obj, SmallObject):
                raise WorldError("only small objects can be removed", node=object_id)
            parent = self._parent[object_id]
            parent.children.remove(obj)
            self._drop_words(obj)
            del self._nodes[object_id]
            del self._parent[object_id]
            ch = self._record(object_id, "removed", parent.id, "", source)
        self._notify([ch])

    def record_search(self, object_key: str, place: str, found: bool, source: str = "") -> None:
        """Count a search for ``object_key`` (an object id or type) at ``place`` (a large
        object id); the learned probability is found / searched."""
        with self.lock:
            stat = next((s for s in self.apartment.search_stats
                         if s.object == object_key and s.place == place), None)
            if stat is None:
                stat = SearchStat(object_key, place)
                self.apartment.search_stats.append(stat)
            stat.searched += 1
            stat.found += int(found)
            ch = MapChange(self.now(), place, "search", object_key, bool(found), source)
        self._notify([ch])

    def search_stats(self, object_key: str) -> dict[str, SearchStat]:
        with self.lock:
            return {s.place: s for s in self.apartment.search_stats if s.object == object_key}


def holds_small_objects(obj) -> bool:
    """Whether a large object can hold small objects: surfaces of its own or of its parts (a
    drawer's floor), or some it holds now."""
    return bool(obj.surfaces or obj.children or any(p.surfaces for p in all_parts(obj)))


def _text(v: Any) -> str:
    if isinstance(v, Pose):
        return " ".join(repr(round(x, 6)) for x in v.as_tuple())
    if isinstance(v, float):
        return repr(v)
    return "" if v is None else str(v)
