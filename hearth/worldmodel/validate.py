"""Semantic checks the schema cannot express, and the checks ``save_world`` runs on a map held
in memory (where there is no schema to lean on). Each problem names file and line, or, for a
map in memory (``name=None``), the node.

The numeric bounds here are the schema's (``hearth/worldmodel/schema/world.xsd``); a test holds the
two to the same values. docs/world-format.md, "Limits", documents them.
"""
from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Iterator, Optional

from hearth.util.files import file_inside
from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.outline import (outline_contains, outline_distance, outline_problem,
                                       room_outline)
from hearth.worldmodel.nodes import (
    HANDLE_KINDS, KNOB_TURNS, Apartment, Knob, LargeArticulatedObject, Model, Part, Visual,
)
from hearth.worldmodel.pose import Pose

#: Joint values are compared with this slack so that a state written as the limit itself
#: after a float round trip is not rejected.
LIMIT_EPS = 1e-9

#: Every coordinate, length and angle in a map (metres or radians) is finite and within
#: +-MAX_COORD. A home is tens of metres across; 10 km leaves room for any map origin while
#: keeping a stray 1e308 (which makes a drive take forever) out.
MAX_COORD = 1e4
#: Learned search counts (``searchStats``) stay below this.
MAX_COUNT = 10**9
#: Longest attribute value or element text, in characters.
MAX_TEXT_CHARS = 4096
#: Most rooms, and most nodes with an id (rooms, objects, parts, handles, knobs, switches).
MAX_ROOMS = 1_000
MAX_NODES = 100_000
#: Most-fold symmetry a knob's shape may declare (the schema's knobSymmetry).
MAX_KNOB_SYMMETRY = 12
#: Two states of a symmetric knob closer than this modulo its symmetry look the same.
KNOB_STATE_SEPARATION = math.radians(1.0)

# XML 1.0 can hold these characters and no others (control characters, lone surrogates and
# U+FFFE/U+FFFF cannot be written, so a name holding one can never be saved).
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def iter_nodes(apartment: Apartment) -> Iterator[tuple[object, Optional[object]]]:
    """Every node with an id, with its parent node, depth first."""
    for room in apartment.rooms:
        yield room, apartment
        for s in room.switches:
            yield s, room
        for c in room.chargers:
            yield c, room
        for d in room.doorways:
            yield d, room
        for o in room.objects:
            yield o, room
            if isinstance(o, LargeArticulatedObject):
                yield from _iter_fittings(o)
            for c in o.children:
                yield c, o


def _iter_fittings(node) -> Iterator[tuple[object, object]]:
    """The handles, knobs and parts (depth first) of an articulated object or of a part."""
    for child in (*node.handles, *node.knobs, *node.parts):
        yield child, node
        if isinstance(child, Part):
            yield from _iter_fittings(child)


def file_references(apartment: Apartment) -> Iterator[tuple[str, object, str]]:
    """Every file a world refers to, as (owner id, holder, attribute): ``getattr(holder,
    attribute)`` is the path relative to the world's folder. Mesh visuals of the library's
    models, of every node's model and of every knob's base, grip and marker; room point
    clouds. The one list of a world's files: bundling a world for another process (a suite
    worker, a saved scenario) and writing a generated home's meshes both go through it, so a
    file kind added here travels everywhere."""
    for mid, model in apartment.library.items():
        for v in model.visuals:
            if v.shape == "mesh" and v.file:
                yield mid, v, "file"
    for node, _ in iter_nodes(apartment):
        for role in ("model", "base", "grip", "marker"):
            model = getattr(node, role, None)
            for v in (model.visuals if isinstance(model, Model) else ()):
                if v.shape == "mesh" and v.file:
                    yield node.id, v, "file"
        if getattr(node, "kind", "") == "Room" and node.pointcloud:
            yield node.id, node, "pointcloud"


# -- numbers and text ------------------------------------------------------------------------

def _is_real(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def coord_problem(v) -> Optional[str]:
    """Why ``v`` is not a coordinate, length or angle a map may hold (None: it is one)."""
    if not _is_real(v):
        return f"{v!r} is not a finite number"
    if abs(v) > MAX_COORD:
        return f"{v!r} is beyond +-{MAX_COORD:g}"
    return None


def positive_problem(v) -> Optional[str]:
    """Why ``v`` is not a size (positive, finite, at most MAX_COORD)."""
    why = coord_problem(v)
    if why is None and v <= 0:
        why = f"{v!r} is not positive"
    return why


def text_problem(v) -> Optional[str]:
    """Why a string cannot be stored in a world file (None: it can)."""
    if not isinstance(v, str):
        return f"{v!r} is not text"
    if len(v) > MAX_TEXT_CHARS:
        return f"is {len(v)} characters long (at most {MAX_TEXT_CHARS})"
    m = _NOT_XML.search(v)
    if m:
        return f"holds character {m.group()!r}, which XML cannot store"
    return None


def _coord(what, v, owner: str):
    why = coord_problem(v)
    if why:
        yield f"{owner}: {what} {why}"


def _positive(what, v, owner: str):
    why = positive_problem(v)
    if why:
        yield f"{owner}: {what} {why}"


def _pose(what, p, owner: str):
    if not isinstance(p, Pose):
        yield f"{owner}: {what} is not a Pose"
        return
    for k, v in p.as_dict().items():
        yield from _coord(f"{what} {k}", v, owner)


def _rgb(what, c, owner: str):
    if not (isinstance(c, (tuple, list)) and len(c) == 3
            and all(_is_real(x) and 0 <= x <= 1 for x in c)):
        yield f"{owner}: {what} {c!r} is not three numbers in 0..1"


def _text(what, v, owner: str, optional: bool = True):
    if v is None and optional:
        return
    why = text_problem(v)
    if why:
        yield f"{owner}: {what} {why}"


def _visual(v: Visual, owner: str):
    yield from _pose(f"{v.shape} pose", v.pose, owner)
    yield from _rgb(f"{v.shape} color", v.color, owner)
    yield from _text(f"{v.shape} name", v.name, owner)
    if v.shape == "box":
        if not (isinstance(v.size, (tuple, list)) and len(v.size) == 3):
            yield f"{owner}: box size {v.size!r} is not three numbers"
        else:
            for axis, s in zip("xyz", v.size):
                yield from _positive(f"box size {axis}", s, owner)
    if v.shape in ("cylinder", "sphere"):
        yield from _positive(f"{v.shape} radius", v.radius, owner)
    if v.shape == "cylinder":
        yield from _positive("cylinder length", v.length, owner)
    if v.shape == "mesh":
        scale = v.scale if isinstance(v.scale, (tuple, list)) else (v.scale,)
        if len(scale) not in (1, 3):
            yield f"{owner}: mesh scale {v.scale!r} is not one or three numbers"
        for axis, s in zip("xyz" if len(scale) == 3 else "s", scale):
            yield from _positive(f"mesh scale {axis}" if len(scale) == 3 else "mesh scale", s, owner)
        yield from _text("mesh file", v.file, owner)


def _model(m: Model, owner: str):
    yield from _text("model ref", m.ref, owner)
    for v in m.visuals:
        yield from _visual(v, owner)


def _node_value_problems(node) -> Iterator[str]:
    """Every number or string of one map node that a world file cannot hold.

    The schema says the same for a file; this says it for a map built or changed in memory,
    before ``save_world`` writes it, naming the node.
    """
    why = text_problem(node.id)
    if why:
        yield f"node id {node.id!r} {why}"
        return
    nid = node.id
    for attr in ("type", "name", "description", "default_parking", "pointcloud", "off_state",
                 "state"):
        if hasattr(node, attr):
            yield from _text(attr, getattr(node, attr), nid)
    if hasattr(node, "pose"):
        yield from _pose("pose", node.pose, nid)
    if hasattr(node, "model"):
        yield from _model(node.model, nid)
    kind = node.kind
    if kind == "Room" and node.bounds is not None:
        for i, v in enumerate(node.bounds):
            yield from _coord(f"bounds[{i}]", v, nid)
    if kind == "Room" and node.outline is not None:
        for i, (x, y) in enumerate(node.outline):
            yield from _coord(f"outline corner {i} x", x, nid)
            yield from _coord(f"outline corner {i} y", y, nid)
    elif kind == "Doorway":
        yield from _positive("width", node.width, nid)
        yield from _positive("depth", node.depth, nid)
        yield from _text("to", node.to, nid)
    elif kind == "Charger":
        yield from _pose("dock pose", node.dock, nid)
    elif kind in ("LargeObject", "LargeArticulatedObject"):
        for p in node.parking:
            yield from _text("parking position id", p.id, nid, optional=False)
            yield from _pose(f"parking position {p.id}", p.pose, nid)
        yield from _surface_values(node.surfaces, nid)
        for a in node.affordances:
            if not isinstance(a, str) or not a or a.split() != [a]:
                yield f"{nid}: affordance {a!r} is not one word"
            else:
                yield from _text("affordance", a, nid)
    elif kind == "Part":
        j = node.joint
        yield from _text("track", node.track, nid)
        yield from _surface_values(node.surfaces, nid)
        yield from _pose("joint origin", j.origin, nid)
        for what in ("lower", "upper", "state"):
            yield from _coord(f"joint {what}", getattr(j, what), nid)
        for axis, v in zip("xyz", j.axis):
            yield from _coord(f"joint axis {axis}", v, nid)
    elif kind == "Handle":
        for what in ("radius", "length", "standoff"):
            yield from _positive(what, getattr(node, what), nid)
        yield from _rgb("color", node.color, nid)
    elif kind == "Knob":
        yield from _coord("angle", node.angle, nid)
        for what in ("radius", "depth"):
            yield from _positive(what, getattr(node, what), nid)
        yield from _rgb("color", node.color, nid)
        yield from _rgb("markerColor", node.marker_color, nid)
        for s in node.states:
            yield from _text("state name", s.name, nid, optional=False)
            yield from _coord(f"state {s.name!r} angle", s.angle, nid)
        for role in ("base", "grip", "marker"):
            m = getattr(node, role)
            if m is not None and not isinstance(m, Model):
                yield f"{nid}: {role} is not a Model"
            elif m is not None:
                yield from _model(m, nid)
        sym = node.symmetry
        if isinstance(sym, bool) or not isinstance(sym, int) or not 1 <= sym <= MAX_KNOB_SYMMETRY:
            yield f"{nid}: symmetry {sym!r} is not a whole number in 1..{MAX_KNOB_SYMMETRY}"
        if node.turns not in KNOB_TURNS:
            yield f"{nid}: turns {node.turns!r} is not one of {', '.join(KNOB_TURNS)}"
        if not isinstance(node.base_fixed, bool):
            yield f"{nid}: base_fixed {node.base_fixed!r} is not true or false"
        elif node.base_fixed and node.base is None:
            yield f"{nid}: a fixed base needs a base"
    elif kind == "SmallObject":
        yield from _text("color", node.color, nid)
        yield from _text("part", node.part, nid)
        for g in node.grasp_points:
            yield from _pose("grasp point", g.pose, nid)
        for d in node.default_positions:
            yield from _text("default position parent", d.parent, nid, optional=False)
            yield from _pose(f"default position on {d.parent}", d.pose, nid)


def _surface_values(surfaces, nid: str) -> Iterator[str]:
    for s in surfaces:
        yield from _text("surface id", s.id, nid, optional=False)
        yield from _pose(f"surface {s.id} pose", s.pose, nid)
        yield from _positive(f"surface {s.id} sizeX", s.size_x, nid)
        yield from _positive(f"surface {s.id} sizeY", s.size_y, nid)


def _apartment_value_problems(apartment: Apartment) -> Iterator[str]:
    """The same for what is not a node: the apartment's own fields, library, history, stats."""
    for what, v in (("apartment id", apartment.id), ("apartment name", apartment.name)):
        why = text_problem(v)
        if why:
            yield f"{what} {why}"
    for mid, m in apartment.library.items():
        why = text_problem(mid)
        if why:
            yield f"library model id {mid!r} {why}"
            continue
        yield from _model(m, f"library model {mid}")
    for h in apartment.history:
        if not _is_real(h.time):
            yield f"history entry of {h.node!r}: time {h.time!r} is not a finite number"
        for what in ("node", "field", "old", "new", "source"):
            why = text_problem(getattr(h, what))
            if why:
                yield f"history entry of {h.node!r}: {what} {why}"
    for s in apartment.search_stats:
        for what in ("searched", "found"):
            v = getattr(s, what)
            if not (isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= MAX_COUNT):
                yield (f"search stat {s.object!r} at {s.place!r}: {what} {v!r} is not a count "
                       f"in 0..{MAX_COUNT}")
        for what in ("object", "place"):
            why = text_problem(getattr(s, what))
            if why:
                yield f"search stat: {what} {why}"


# -- files a map names -----------------------------------------------------------------------

_ASSET_REASONS = {"not relative": "must be a path relative to the world file's folder",
                  "leaves": "leaves the world file's folder",
                  "leaves through a link": "leaves the world file's folder (through a "
                                           "symbolic link)",
                  "missing": "is not in the world file's folder",
                  "not regular": "is not a regular file"}


def asset_problem(rel, base_dir: Optional[Path], kind: str = "mesh") -> Optional[str]:
    """Why a mesh or point-cloud path may not be used (None: it may).

    Paths are relative to the world file's folder and must stay inside it (after following
    symbolic links) and name a regular file: a world file from elsewhere must not make Hearth
    read ``/etc/passwd``, block on ``/dev/zero`` or wander through ``/proc``. Without a folder
    (``parse_world`` on bytes) nothing can be checked, so no file is accepted. What the file
    holds is checked too (``hearth.worldmodel.meshfile``: format, declared counts, the files an
    ``.obj`` names, finite vertices); ``kind`` is "mesh" or "pointcloud".
    """
    if not isinstance(rel, str) or not rel:
        return "is empty"
    if base_dir is None:
        return "cannot be checked: the world was not loaded from a folder"
    full, why = file_inside(base_dir, rel)
    if why is not None:
        return _ASSET_REASONS.get(why) or f"cannot be read ({why.partition(': ')[2]})"
    base = os.path.realpath(base_dir)
    from hearth.worldmodel.meshfile import content_problem
    return content_problem(full, base, kind)


# -- the checks ------------------------------------------------------------------------------

def all_parts(node) -> Iterator[Part]:
    """Every part of an articulated object or part, depth first."""
    for p in getattr(node, "parts", ()):
        yield p
        yield from all_parts(p)


def _unique_surfaces(node, bad) -> None:
    """A surface is named by its object and its id (where an object stands, what a search
    looks at): two of one object with one id could not be told apart, whether they are the
    object's own or its parts' (a drawer's floor)."""
    seen: set[str] = set()
    for owner in (node, *all_parts(node)):
        for srf in getattr(owner, "surfaces", ()):
            if srf.id in seen:
                bad(f"{node.id}: duplicate surface id {srf.id!r}", srf)
            seen.add(srf.id)


#: Two closed sliding doors on one track that share more than this fraction of the narrower
#: one's width along the track cover the same span: neither uncovers a half of its own when
#: slid open (a bypass wardrobe's doors overlap by a few centimetres in the middle).
TRACK_OVERLAP_FRACTION = 0.5


def _rpy(pose: Pose) -> list[list[float]]:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` as rows (pose.py's convention), by hand: validating
    does not import scipy (pose.py)."""
    cr, sr = math.cos(pose.roll), math.sin(pose.roll)
    cp, sp = math.cos(pose.pitch), math.sin(pose.pitch)
    cy, sy = math.cos(pose.yaw), math.sin(pose.yaw)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def _apply(R, v) -> tuple[float, float, float]:
    return tuple(sum(R[i][k] * v[k] for k in range(3)) for i in range(3))


def _closed_span(door: Part) -> Optional[tuple[tuple, float, float]]:
    """A sliding door's slide direction in its parent's frame (unit) and the interval its
    primitive shapes (boxes, cylinders, spheres: their bounding boxes) cover along it with
    the door closed (joint at its lower limit); None when it has no primitive shape (a mesh
    is not read to validate)."""
    j = door.joint
    n = math.sqrt(sum(a * a for a in j.axis))
    if n == 0:
        return None
    R0 = _rpy(j.origin)
    axis = _apply(R0, tuple(a / n for a in j.axis))
    offset = tuple(j.lower * a / n for a in j.axis)          # the slide, in the part frame
    o = (j.origin.x, j.origin.y, j.origin.z)
    along = []
    for v in door.model.visuals:
        if v.shape == "box":
            h = tuple(s / 2 for s in v.size)
        elif v.shape == "cylinder":
            h = (v.radius, v.radius, v.length / 2)
        elif v.shape == "sphere":
            h = (v.radius,) * 3
        else:
            continue
        Rv = _rpy(v.pose)
        for corner in ((sx * h[0], sy * h[1], sz * h[2])
                       for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)):
            c = _apply(Rv, corner)
            p_part = (c[0] + v.pose.x + offset[0], c[1] + v.pose.y + offset[1],
                      c[2] + v.pose.z + offset[2])
            p = _apply(R0, p_part)
            along.append(sum(axis[i] * (p[i] + o[i]) for i in range(3)))
    return (axis, min(along), max(along)) if along else None


def _track_problems(obj, bad) -> None:
    """Doors on one track exclude each other (docs/world-format.md, "Sliding doors"): a
    track needs two or more, they slide along one line, and closed each covers a span of
    its own."""
    tracks: dict[str, list[tuple[object, Part]]] = {}

    def walk(owner) -> None:
        for p in owner.parts:
            if p.track:
                tracks.setdefault(p.track, []).append((owner, p))
            walk(p)

    walk(obj)
    for track, doors in tracks.items():
        if len(doors) == 1:
            bad(f"{obj.id}: part {doors[0][1].id!r} is the only door on track {track!r} (doors "
                f"on one track exclude each other: give the track two doors or drop it)",
                doors[0][1])
            continue
        spans = {}
        for owner, d in doors:
            if d.joint.type == "prismatic":
                span = _closed_span(d)
                if span is not None:
                    spans[d.id] = (owner, d, span)
        seen = list(spans.values())
        for i, (owner_a, a, (axis_a, lo_a, hi_a)) in enumerate(seen):
            for owner_b, b, (axis_b, lo_b, hi_b) in seen[i + 1:]:
                if owner_a is not owner_b:
                    continue            # spans in different frames: not compared
                dot = sum(x * y for x, y in zip(axis_a, axis_b))
                if abs(dot) < 0.99:
                    bad(f"{obj.id}: sliding doors {a.id!r} and {b.id!r} on track {track!r} "
                        f"slide along different lines", b)
                    continue
                if dot < 0:             # opposite slides: measure b along a's direction
                    lo_b, hi_b = -hi_b, -lo_b
                shared = min(hi_a, hi_b) - max(lo_a, lo_b)
                narrower = min(hi_a - lo_a, hi_b - lo_b)
                if shared > TRACK_OVERLAP_FRACTION * narrower:
                    bad(f"{obj.id}: sliding doors {a.id!r} and {b.id!r} on track {track!r} "
                        f"overlap by {shared:.2f} m of {narrower:.2f} m when closed (each "
                        f"must cover a span of its own)", b)


def semantic_problems(apartment: Apartment, name: Optional[str],
                      base_dir: Optional[Path]) -> list[WorldError]:
    """Every problem the schema cannot see. ``name`` is the file (problems carry its lines);
    ``None`` for a map in memory (problems name their node)."""
    problems: list[WorldError] = []

    def bad(msg: str, node) -> None:
        if len(msg) > 300:          # a problem is one line a person reads
            msg = msg[:280] + " ..."
        if name is None:
            node_id = getattr(node, "id", None)
            problems.append(WorldError(msg, node=node_id if isinstance(node_id, str) else None))
        else:
            problems.append(WorldError(msg, file=name, line=getattr(node, "line", None) or 0))

    if len(apartment.rooms) > MAX_ROOMS:
        bad(f"more than {MAX_ROOMS} rooms", apartment.rooms[MAX_ROOMS])
        return problems
    seen: dict[str, object] = {}
    for i, (node, _parent) in enumerate(iter_nodes(apartment)):
        if i == MAX_NODES:
            bad(f"more than {MAX_NODES} nodes with an id", node)
            return problems
        if node.id in seen:
            first = seen[node.id]
            bad(f"duplicate id {node.id!r} (first used at line {getattr(first, 'line', '?')})", node)
        else:
            seen[node.id] = node
    for mid in apartment.library:
        if mid in seen:
            bad(f"library model id {mid!r} is also a node id", apartment)
    room_ids = {r.id for r in apartment.rooms}

    # What the schema cannot say about the learned search statistics: a count of finds
    # within the count of searches, a place that is in this map, one entry per pair.
    pairs: set[tuple[str, str]] = set()
    for st in apartment.search_stats:
        where = f"search stat of {st.object!r} at {st.place!r}"
        if isinstance(st.found, int) and isinstance(st.searched, int) and st.found > st.searched:
            bad(f"{where}: found {st.found} times in {st.searched} searches", st)
        if isinstance(st.place, str) and st.place not in seen:
            bad(f"{where}: no node {st.place!r} in the map", st)
        if (st.object, st.place) in pairs:
            bad(f"{where}: given twice", st)
        pairs.add((st.object, st.place))

    if name is None:
        # A file went through the schema, which bounds every number and string; a map in
        # memory did not.
        for node, _parent in iter_nodes(apartment):
            for msg in _node_value_problems(node):
                bad(msg, node)
        for msg in _apartment_value_problems(apartment):
            bad(msg, apartment)
        if problems:
            return problems

    def check_model(model: Model, owner) -> None:
        if model.ref is not None and model.ref not in apartment.library:
            bad(f"{owner.id}: model ref {model.ref!r} is not in the library", model)
        check_visuals(model.visuals, owner.id)

    def check_visuals(visuals, owner: str) -> None:
        for v in visuals:
            if v.shape == "box" and min(v.size) <= 0:
                bad(f"{owner}: box size must be positive", v)
            if v.shape in ("cylinder", "sphere") and v.radius <= 0:
                bad(f"{owner}: {v.shape} radius must be positive", v)
            if v.shape == "cylinder" and v.length <= 0:
                bad(f"{owner}: cylinder length must be positive", v)
            if v.shape == "mesh":
                if not v.file:
                    bad(f"{owner}: mesh needs a file", v)
                else:
                    why = asset_problem(v.file, base_dir)
                    if why:
                        bad(f"{owner}: mesh file {v.file!r} {why}", v)

    def check_knob(k: Knob) -> None:
        names = [s.name for s in k.states]
        if len(k.states) < 2:
            bad(f"knob {k.id!r} needs at least two discrete states", k)
        if len(set(names)) != len(names):
            bad(f"knob {k.id!r} has duplicate state names", k)
        if k.state not in names:
            bad(f"knob {k.id!r}: state {k.state!r} is not one of {names}", k)
        if k.off_state and k.off_state not in names:
            bad(f"knob {k.id!r}: off state {k.off_state!r} is not one of {names}", k)
        for role in ("base", "grip", "marker"):
            model = getattr(k, role)
            if model is not None:
                check_model(model, k)
        if k.symmetry > 1:
            # a symmetric shape shows its angle modulo 360/symmetry degrees only: two states
            # that far apart could never be told apart
            period = 2 * math.pi / k.symmetry
            for i, a in enumerate(k.states):
                for b in k.states[i + 1:]:
                    d = abs(math.remainder(a.angle - b.angle, period))
                    if d < KNOB_STATE_SEPARATION:
                        bad(f"knob {k.id!r}: states {a.name!r} and {b.name!r} look the same "
                            f"(symmetry {k.symmetry}: the shape repeats every "
                            f"{360 / k.symmetry:g} degrees)", k)

    for mid, m in apartment.library.items():
        check_visuals(m.visuals, f"library model {mid}")

    for node, parent in iter_nodes(apartment):
        kind = node.kind
        if kind in ("LargeObject", "LargeArticulatedObject"):
            ids = [p.id for p in node.parking]
            if not node.parking:
                bad(f"{node.id}: needs at least one parking position", node)
            elif node.default_parking not in ids:
                bad(f"{node.id}: default parking position {node.default_parking!r} is not one "
                    f"of {ids}", node)
            if len(set(ids)) != len(ids):
                bad(f"{node.id}: duplicate parking position ids", node)
            _unique_surfaces(node, bad)
            check_model(node.model, node)
            if kind == "LargeArticulatedObject":
                _track_problems(node, bad)
        elif kind == "Part":
            j = node.joint
            if j.type != "fixed":
                if math.isclose(sum(a * a for a in j.axis), 0.0):
                    bad(f"part {node.id!r}: joint axis must not be zero", j)
                if j.lower > j.upper:
                    bad(f"part {node.id!r}: joint limits out of order (lower {j.lower} > upper "
                        f"{j.upper})", j)
                elif not (j.lower - LIMIT_EPS <= j.state <= j.upper + LIMIT_EPS):
                    bad(f"part {node.id!r}: joint state {j.state} is outside its limits "
                        f"[{j.lower}, {j.upper}]", j)
            if node.track and j.type != "prismatic":
                bad(f"part {node.id!r}: a part on a track (track {node.track!r}) slides: its "
                    f"joint must be prismatic", node)
            check_model(node.model, node)
        elif kind == "Handle":
            if node.handle_kind not in HANDLE_KINDS:
                bad(f"handle {node.id!r}: kind {node.handle_kind!r} is not one of "
                    f"{', '.join(HANDLE_KINDS)}", node)
        elif kind == "Knob":
            check_knob(node)
        elif kind == "SmallObject":
            check_model(node.model, node)
            if node.part and node.part not in {p.id for p in all_parts(parent)}:
                bad(f"{node.id}: part {node.part!r} is not a part of its parent "
                    f"{parent.id!r}", node)
            for d in node.default_positions:
                if d.parent not in seen:
                    bad(f"{node.id}: default position names unknown parent {d.parent!r}", d)
        elif kind == "Charger" and parent.bounds is not None:
            # The robot must be able to stand at the dock: inside the charger's room.
            # (planar: Pose.matrix would bring in scipy, which validating never needs)
            c, s_ = math.cos(node.pose.yaw), math.sin(node.pose.yaw)
            dx = node.pose.x + c * node.dock.x - s_ * node.dock.y
            dy = node.pose.y + s_ * node.dock.x + c * node.dock.y
            if not outline_contains(room_outline(parent), dx, dy, 1e-9):
                bad(f"charger {node.id!r}: its dock pose ({dx:.2f}, {dy:.2f}) is "
                    f"outside room {parent.id!r}", node)
        elif kind == "Doorway":
            if node.to and (node.to not in room_ids or node.to == parent.id):
                bad(f"doorway {node.id!r}: to names {node.to!r}, which is not another room",
                    node)
            if parent.bounds is not None:
                # The opening is in a wall: the passage's centre line crosses the outline.
                d = outline_distance(room_outline(parent), node.pose.x, node.pose.y)
                if d > node.depth / 2 + 1e-6:
                    bad(f"doorway {node.id!r}: its centre ({node.pose.x:.2f}, "
                        f"{node.pose.y:.2f}) is {d:.2f} m from the walls of room "
                        f"{parent.id!r}, more than half its depth ({node.depth / 2:.2f} m)",
                        node)
        elif kind == "Room":
            if node.outline is not None:
                why = outline_problem(node.outline)
                if why:
                    bad(f"room {node.id!r}: outline {why}", node)
            elif node.bounds is not None:
                x0, y0, x1, y1 = node.bounds
                if x0 >= x1 or y0 >= y1:
                    bad(f"room {node.id!r}: bounds must be xmin ymin xmax ymax", node)
            if node.pointcloud is not None:
                why = asset_problem(node.pointcloud, base_dir, "pointcloud")
                if why:
                    bad(f"room {node.id!r}: point cloud {node.pointcloud!r} {why}", node)
    return problems
