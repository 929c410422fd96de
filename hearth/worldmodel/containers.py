"""What a search opens to look inside a piece of furniture: doors, drawers, sliding doors.

- A hinged door (type ``door``, revolute, with a handle) that is closed is opened.
- A drawer (prismatic, not on a track) whose part carries a surface (small objects stand in
  it) and that is less than half open is opened: the search then looks in from above.
- Sliding doors that share a track (``Part.track``) exclude each other: sliding one open
  slides it over the other, so opening both only swaps the halves. Of a track's closed doors
  the one whose closed span covers the place looked at (where the map believes the object,
  when it believes it here) is opened first; each of the others is opened after it is
  closed, for a second look (``Openings.then``).

Only containers (affordance ``container``) are opened; the demo's and the generator's
cupboards, drawer units, fridges and wardrobes are.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hearth.worldmodel.nodes import LargeArticulatedObject, Part, SmallObject
from hearth.worldmodel.validate import all_parts

#: A door counts as open above this (radians from its lower limit).
DOOR_OPEN_RAD = 0.35
#: A drawer or sliding door counts as open above this fraction of its travel.
SLIDE_OPEN_FRACTION = 0.5


@dataclass
class Openings:
    """``first``: the parts to open before looking; ``then``: sliding doors to open one at a
    time after closing the one of their track that was opened, to look again. Each is a
    list of {part, handle} mappings."""
    first: list = field(default_factory=list)
    then: list = field(default_factory=list)

    @property
    def count(self) -> int:
        return len(self.first) + len(self.then)


def is_open(part: Part, door_open_rad: float = DOOR_OPEN_RAD) -> bool:
    """Whether a door, drawer or sliding door stands open enough to look or reach in."""
    j = part.joint
    if j.type == "revolute":
        return j.state - j.lower >= door_open_rad
    travel = j.upper - j.lower
    return travel > 0 and (j.state - j.lower) >= SLIDE_OPEN_FRACTION * travel


def _entry(part: Part) -> dict:
    return {"part": part.id, "handle": part.handles[0].id if part.handles else None}


def openings(world, place_id: str, object_id: Optional[str] = None,
             door_open_rad: float = DOOR_OPEN_RAD) -> Openings:
    """What to open at a place to look for ``object_id`` (module docstring)."""
    node = world.get(place_id)
    out = Openings()
    if not isinstance(node, LargeArticulatedObject) or "container" not in node.affordances:
        return out
    tracks: dict[str, list[Part]] = {}
    for p in all_parts(node):
        if p.track:
            tracks.setdefault(p.track, []).append(p)
        elif p.type == "door" and p.handles and p.joint.type == "revolute":
            if not is_open(p, door_open_rad):
                out.first.append(_entry(p))
        elif p.joint.type == "prismatic" and p.surfaces and p.handles:
            if not is_open(p):
                out.first.append(_entry(p))
    point = _believed_point(world, place_id, object_id)
    for doors in tracks.values():
        if any(is_open(d) for d in doors):
            continue        # one half is open already: the search looks through it
        doors = sorted(doors, key=lambda d: -_covers(world, node, d, point))
        out.first.append(_entry(doors[0]))
        out.then.extend(_entry(d) for d in doors[1:])
    return out


def closed_to_open(place) -> int:
    """How many doors and drawers a search of ``place`` opens (and closes), without a map:
    the closed hinged doors with handles, the closed drawers holding surfaces, every closed
    sliding door. (Before issue 43 only hinged doors were counted, whatever the object.)"""
    if "container" not in getattr(place, "affordances", ()):
        # as before: a door with a handle costs its opening even where the search would not
        # open it (a fridge the map does not call a container)
        return sum(1 for p in getattr(place, "parts", ()) if p.type == "door" and p.handles
                   and p.joint.state - p.joint.lower < DOOR_OPEN_RAD)
    n = 0
    for p in all_parts(place):
        if p.track:
            n += not is_open(p)
        elif p.type == "door" and p.handles and p.joint.type == "revolute":
            n += not is_open(p)
        elif p.joint.type == "prismatic" and p.surfaces and p.handles:
            n += not is_open(p)
    return n


def _believed_point(world, place_id: str, object_id: Optional[str]):
    """The world point where the map believes the object, when it believes it at this place."""
    if not object_id or object_id not in world:
        return None
    obj = world.get(object_id)
    parent = world.parent(object_id)
    if not isinstance(obj, SmallObject) or parent is None or parent.id != place_id:
        return None
    return world.T_world(object_id)[:3, 3]


def _covers(world, obj, door: Part, point) -> float:
    """1 when the door's span along its slide (object frame) holds the point, else minus
    the point's distance from that span (0 without a point: the doors keep the file's
    order)."""
    if point is None:
        return 0.0
    from hearth.worldmodel.geometry import node_mesh
    T_obj_world = np.linalg.inv(world.T_world(obj.id))
    pts = np.asarray(node_mesh(world, door.id).vertices)
    if not len(pts):
        return 0.0
    local = pts @ T_obj_world[:3, :3].T + T_obj_world[:3, 3]
    q = T_obj_world[:3, :3] @ point + T_obj_world[:3, 3]
    axis = np.abs(np.asarray(door.joint.axis, dtype=float))
    # the slide axis in the object frame (the joint origin may turn it)
    R = door.joint.origin.matrix()[:3, :3]
    a = int(np.argmax(np.abs(R @ axis)))
    lo, hi = local[:, a].min(), local[:, a].max()
    if lo <= q[a] <= hi:
        return 1.0
    return -float(min(abs(q[a] - lo), abs(q[a] - hi)))


def sliding_open_state(part: Part) -> float:
    """Where a search slides a door or drawer to: a sliding door all the way (its half is
    then uncovered), a drawer that holds surfaces all the way too (a person pulls a drawer
    out to look in: at 80 % of its travel a small object at the back of the tray stays under
    the carcass top, hidden from every view; issue 43), another drawer 80 % of its travel
    (OpenArticulated's default)."""
    j = part.joint
    if part.track or part.surfaces:
        return j.upper
    return j.lower + 0.8 * (j.upper - j.lower)


def search_states(world, object_id: str) -> dict:
    """Part id -> joint state of the object's furniture as a search opens it to see the
    object where it stands: hinged doors a quarter turn, the drawer it is in open, of
    sliding doors on one track the one covering it slid open (the others closed)."""
    parent = world.parent(object_id)
    states: dict = {}
    if not isinstance(parent, LargeArticulatedObject):
        return states
    obj = world.get(object_id)
    point = world.T_world(object_id)[:3, 3]
    tracks: dict[str, list[Part]] = {}
    for p in all_parts(parent):
        if p.track:
            tracks.setdefault(p.track, []).append(p)
        elif p.joint.type == "revolute":
            states[p.id] = min(float(np.radians(90)), p.joint.upper)
        elif p.id == getattr(obj, "part", ""):
            states[p.id] = sliding_open_state(p)
    for doors in tracks.values():
        best = max(doors, key=lambda d: _covers(world, parent, d, point))
        for d in doors:
            states[d.id] = sliding_open_state(d) if d is best else d.joint.lower
    return states


def covering_door(world, object_id: str) -> Optional[str]:
    """The sliding door (on a track) of the object's furniture that stands in front of it
    now, by the door's span along its slide (object frame); None when none does."""
    parent = world.parent(object_id)
    if not isinstance(parent, LargeArticulatedObject):
        return None
    point = world.T_world(object_id)[:3, 3]
    for p in all_parts(parent):
        if p.track and _covers(world, parent, p, point) > 0:
            return p.id
    return None


def headroom(part: Part, surface) -> float:
    """Free height (m) above a part's surface with the part closed: up to the top of the
    part's own model (a drawer's front and sides) less 1 cm; infinity for a part without
    a model above the surface."""
    tops = []
    for v in part.model.visuals:
        if v.shape == "box":
            tops.append(v.pose.z + v.size[2] / 2)
        elif v.shape == "cylinder":
            tops.append(v.pose.z + v.length / 2)
    above = [t for t in tops if t > surface.pose.z + 1e-6]
    return max(above) - surface.pose.z - 0.01 if above else float("inf")
