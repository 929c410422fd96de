"""Semantic checks the schema cannot express. Each problem names file and line."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Iterator, Optional

from worldmodel.errors import WorldError
from worldmodel.nodes import Apartment, Knob, LargeArticulatedObject, Model, Part

#: Joint values are compared with this slack so that a state written as the limit itself
#: after a float round trip is not rejected.
LIMIT_EPS = 1e-9


def iter_nodes(apartment: Apartment) -> Iterator[tuple[object, Optional[object]]]:
    """Every node with an id, with its parent node, depth first."""
    for room in apartment.rooms:
        yield room, apartment
        for s in room.switches:
            yield s, room
        for o in room.objects:
            yield o, room
            if isinstance(o, LargeArticulatedObject):
                for h in o.handles:
                    yield h, o
                for k in o.knobs:
                    yield k, o
                for p in o.parts:
                    yield from _iter_part(p, o)
            for c in o.children:
                yield c, o


def _iter_part(part: Part, parent) -> Iterator[tuple[object, object]]:
    yield part, parent
    for h in part.handles:
        yield h, part
    for k in part.knobs:
        yield k, part
    for c in part.parts:
        yield from _iter_part(c, part)


def semantic_problems(apartment: Apartment, name: str, base_dir: Optional[Path]) -> list[WorldError]:
    problems: list[WorldError] = []

    def bad(msg: str, node) -> None:
        problems.append(WorldError(msg, file=name, line=getattr(node, "line", None) or 0))

    seen: dict[str, object] = {}
    for node, _parent in iter_nodes(apartment):
        if node.id in seen:
            first = seen[node.id]
            bad(f"duplicate id {node.id!r} (first used at line {getattr(first, 'line', '?')})", node)
        else:
            seen[node.id] = node
    for mid in apartment.library:
        if mid in seen:
            bad(f"library model id {mid!r} is also a node id", apartment)

    def check_model(model: Model, owner) -> None:
        if model.ref is not None and model.ref not in apartment.library:
            bad(f"{owner.id}: model ref {model.ref!r} is not in the library", model)
        for v in model.visuals:
            if v.shape == "box" and min(v.size) <= 0:
                bad(f"{owner.id}: box size must be positive", v)
            if v.shape in ("cylinder", "sphere") and v.radius <= 0:
                bad(f"{owner.id}: {v.shape} radius must be positive", v)
            if v.shape == "cylinder" and v.length <= 0:
                bad(f"{owner.id}: cylinder length must be positive", v)
            if v.shape == "mesh":
                if not v.file:
                    bad(f"{owner.id}: mesh needs a file", v)
                elif base_dir is not None and not (base_dir / v.file).exists():
                    bad(f"{owner.id}: mesh file {v.file!r} not found next to the world file", v)

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
            check_model(node.model, node)
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
            check_model(node.model, node)
        elif kind == "Knob":
            check_knob(node)
        elif kind == "SmallObject":
            check_model(node.model, node)
            for d in node.default_positions:
                if d.parent not in seen:
                    bad(f"{node.id}: default position names unknown parent {d.parent!r}", d)
        elif kind == "Room":
            if node.bounds is not None:
                x0, y0, x1, y1 = node.bounds
                if x0 >= x1 or y0 >= y1:
                    bad(f"room {node.id!r}: bounds must be xmin ymin xmax ymax", node)
    return problems
