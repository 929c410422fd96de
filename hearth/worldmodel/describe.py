"""Text and JSON views of the map for people: the hierarchy with states, and find results."""
from __future__ import annotations

import math
from typing import Optional

from hearth.worldmodel.nodes import (
    Charger, Handle, Knob, LargeArticulatedObject, LargeObject, Part, Room, SmallObject, Switch,
)


def _state(node) -> str:
    if isinstance(node, Part):
        j = node.joint
        if j.type == "revolute":
            return f"{node.type}, {math.degrees(j.state):.0f} deg open"
        if j.type == "prismatic":
            return f"{node.type}, {j.state * 100:.1f} cm open"
        return node.type
    if isinstance(node, Knob):
        return f"knob, state {node.state} ({math.degrees(node.angle):.0f} deg)"
    if isinstance(node, Handle):
        return "handle"
    if isinstance(node, Charger):
        return "charger"
    if isinstance(node, Switch):
        return f"{node.type} switch, {'on' if node.on else 'off'}"
    if isinstance(node, SmallObject):
        words = " ".join(w for w in (node.color, node.type) if w)
        return f"{words}, {node.relation}"
    if isinstance(node, LargeObject):
        extra = "" if node.static else ", movable"
        return f"{node.type}{extra}, parking {', '.join(p.id for p in node.parking)}"
    if isinstance(node, Room):
        return "room"
    return ""


def hierarchy_lines(world, node_id: Optional[str] = None) -> list[str]:
    """The map as an indented tree, one node a line: ``id  (what, state)``."""
    lines: list[str] = []

    def walk(node, depth: int) -> None:
        name = f" \"{node.name}\"" if getattr(node, "name", "") else ""
        lines.append(f"{'  ' * depth}{node.id}{name}  ({_state(node)})")
        for child in _children(node):
            walk(child, depth + 1)

    if node_id is None:
        a = world.apartment
        lines.append(f"{a.id} \"{a.name}\"  (apartment, {len(a.rooms)} rooms)")
        for room in a.rooms:
            walk(room, 1)
    else:
        walk(world.get(node_id), 0)
    return lines


def _children(node) -> list:
    if isinstance(node, Room):
        return [*node.switches, *node.chargers, *node.objects]
    if isinstance(node, LargeArticulatedObject):
        return [*node.handles, *node.knobs, *node.parts, *node.children]
    if isinstance(node, LargeObject):
        return list(node.children)
    if isinstance(node, Part):
        return [*node.handles, *node.knobs, *node.parts]
    return []


def find_report(world, words: str) -> dict:
    """The best match for ``words``, its parent chain, room and parking positions, and the
    other candidates. Empty ``match`` when nothing matches; when several nodes match
    equally well ("cup" with a red and a blue cup), ``match`` is None too and ``ambiguous``
    lists them, as the command layer asks "which cup do you mean"."""
    import math
    matches = world.find(words)
    if not matches:
        return {"query": words, "match": None, "candidates": []}
    top = [m for m in matches if math.isclose(m.score, matches[0].score)]
    if len(top) > 1:
        return {"query": words, "match": None,
                "ambiguous": [{"id": m.node.id, "label": world.label(m.node.id),
                               "location": world.describe_location(m.node.id)} for m in top],
                "candidates": [{"id": m.node.id, "label": world.label(m.node.id),
                                "score": round(m.score, 3)} for m in matches[:10]]}
    best = matches[0].node
    chain = world.chain(best.id)
    parent = world.parent(best.id)
    room = world.room_of(best.id)
    parking = []
    try:
        for p, pose in world.parking_positions(best.id):
            parking.append({"id": p.id, "x": round(pose.x, 4), "y": round(pose.y, 4),
                            "yaw": round(pose.yaw, 4)})
    except Exception:  # a room or switch has no parking positions
        parking = []
    wp = world.world_pose(best.id)
    return {
        "query": words,
        "match": {"id": best.id, "kind": best.kind, "label": world.label(best.id),
                  "world_pose": {k: round(v, 4) for k, v in wp.as_dict().items()}},
        "parent": None if parent is None else {"id": parent.id, "kind": parent.kind,
                                               "label": world.label(parent.id)},
        "room": {"id": room.id, "name": room.name},
        "chain": [n.id for n in chain],
        "location": world.describe_location(best.id),
        "parking_positions": parking,
        "candidates": [{"id": m.node.id, "label": world.label(m.node.id), "score": round(m.score, 3)}
                       for m in matches[1:10]],
    }
