"""Small skills the named missions need to glue the other skills together (issue 8).

Each one reads the map or formats words; none holds an algorithm:

- ``LocateUser``: the room the user is in (the robot adapter's ``user_room()`` when it has one,
  else the mission's default) and where to bring things to them.
- ``PlaceOfPose``: the large object an observed world pose lies on or in (the object's new
  parent; the cup may sit on another table than the one searched from).
- ``KnobsOn`` / ``ExpectKnobsOff``: which of an appliance's knobs the map says are on;
  the check after turning them off, failing with the knobs still on.
- ``Remember``: append an item to a list key (places searched, notes on what went wrong).
- ``DescribeCorrection``: a localisation correction in words.
"""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import py_trees

from hearth.skills.base import Port, Skill, words
from hearth.skills.values import as_pose
from hearth.worldmodel.nodes import Knob

S = py_trees.common.Status


class LocateUser(Skill):
    """Where the user is: ``robot.user_room()`` / ``robot.user_place()`` when the adapter
    knows (a presence sensor), else the given defaults. ``room`` is "" when unknown (no
    room penalty in the search order)."""

    NAME = "LocateUser"
    DESCRIPTION = "find which room the user is in"
    INPUTS = (Port("room", "string", required=False, default=""),
              Port("place", "node_id", required=False, default=""))
    OUTPUTS = (Port("room", "string", required=False), Port("place", "node_id", required=False))

    def update(self) -> S:
        room = self.input("room") or ""
        place = self.input("place") or ""
        for attr, name in (("user_room", "room"), ("user_place", "place")):
            fn = getattr(self.robot, attr, None)
            value = fn() if callable(fn) else None
            if value:
                room, place = (value, place) if name == "room" else (room, value)
        if room and self.world is not None:
            # Accept a room id or its name; the search cost compares room ids.
            for r in self.world.rooms:
                if room in (r.id, r.name):
                    room = r.id
        if not place and room and self.world is not None:
            inside = [o for o in self.world.large_objects()
                      if self.world.room_of(o.id).id == room and o.parking]
            place = inside[0].id if inside else ""
        self.set_output("room", room)
        self.set_output("place", place)
        self.feedback_message = f"the user is in the {room}" if room else "user's room unknown"
        return S.SUCCESS


class PlaceOfPose(Skill):
    """The large object an observed world pose is on or in (``World.support_at``). Fails when
    none is near."""

    NAME = "PlaceOfPose"
    DESCRIPTION = "find the furniture an observed object stands on or in"
    INPUTS = (Port("pose", "pose", description="world pose of the object"),
              Port("margin", "number", required=False, default=0.05),
              Port("max_distance", "number", required=False, default=0.5))
    OUTPUTS = (Port("place", "node_id", required=False),
               Port("relation", "string", required=False))

    def update(self) -> S:
        p = as_pose(self.input("pose"))
        found = self.world.support_at((p.x, p.y, p.z), float(self.input("margin")),
                                      float(self.input("max_distance")))
        if found is None:
            self.feedback_message = f"nothing to hold an object near {p.x:.2f}, {p.y:.2f}"
            return S.FAILURE
        obj = found[0]
        level = self.world.surface_near(obj.id, (p.x, p.y, p.z))
        relation = level.relation if level is not None else "on"
        self.set_output("place", obj.id)
        self.set_output("relation", relation)
        self.feedback_message = f"{relation} the {self.world.label(obj.id)}"
        return S.SUCCESS


def knobs_on(world, object_id: str) -> list[Knob]:
    return [k for k in world.knobs(object_id) if k.state != k.off]


class KnobsOn(Skill):
    """The knobs of an appliance that the map says are on (read them first with ReadKnobs)."""

    NAME = "KnobsOn"
    DESCRIPTION = "list an appliance's knobs that are on"
    INPUTS = (Port("object", "node_id"),)
    OUTPUTS = (Port("knobs", "list", required=False), Port("count", "integer", required=False))

    def update(self) -> S:
        oid = self.input("object")
        on = knobs_on(self.world, oid)
        self.set_output("knobs", [k.id for k in on])
        self.set_output("count", len(on))
        self.feedback_message = (", ".join(f"{k.id} {k.state}" for k in on) + " on" if on
                                 else f"every knob of the {self.world.label(oid)} is off")
        return S.SUCCESS


class ExpectKnobsOff(Skill):
    """Succeed when every knob of the appliance (or just ``knob``) is off in the map and was
    read (none of them in ``unread``, ReadKnobs' ``unknown``: a knob the last reading could
    not read is not known to be off, whatever the map still says); else fail naming the knobs
    still on or unread."""

    NAME = "ExpectKnobsOff"
    DESCRIPTION = "check that an appliance's knobs are off"
    INPUTS = (Port("object", "node_id"),
              Port("knob", "node_id", required=False, default=None),
              Port("unread", "list", required=False, default=None,
                   description="knobs the last reading could not read"))
    OUTPUTS = ()

    def update(self) -> S:
        oid, knob = self.input("object"), self.input("knob")
        unread = [k for k in (self.input("unread") or []) if knob in (None, k)]
        if unread:
            self.feedback_message = ", ".join(f"{k} could not be read" for k in unread)
            return S.FAILURE
        on = [k for k in knobs_on(self.world, oid) if knob in (None, k.id)]
        if on:
            self.feedback_message = ", ".join(f"{k.id} is still {k.state}" for k in on)
            return S.FAILURE
        self.feedback_message = f"{knob or 'every knob'} off"
        return S.SUCCESS


class Remember(Skill):
    """Append ``item`` to a list (bind ``list`` and ``result`` to the same key)."""

    NAME = "Remember"
    DESCRIPTION = "append an item to a list on the blackboard"
    INPUTS = (Port("item", "any"), Port("list", "list", required=False, default=None))
    OUTPUTS = (Port("result", "list", required=False),)

    def update(self) -> S:
        items = list(self.input("list") or [])
        items.append(self.input("item"))
        self.set_output("result", items)
        self.feedback_message = f"{len(items)} remembered"
        return S.SUCCESS


class SetValue(Skill):
    """Write a value to a key (like BehaviorTree.CPP's SetBlackboard): start a list afresh before
    a loop collects into it."""

    NAME = "SetValue"
    DESCRIPTION = "write a value to a blackboard key"
    INPUTS = (Port("value", "any", required=False, default=None),)
    OUTPUTS = (Port("output", "any", required=False),)

    def update(self) -> S:
        self.set_output("output", self.input("value"))
        self.feedback_message = "set"
        return S.SUCCESS


class Wait(Skill):
    """Wait ``seconds`` of clock time (simulated or wall), then succeed: BehaviorTree.CPP's
    ``Delay`` and ``Sleep`` on import."""

    NAME = "Wait"
    DESCRIPTION = "wait a number of seconds"
    INPUTS = (Port("seconds", "number", description="how long, in seconds of clock time"),)

    def initialise(self) -> None:
        self._until = None

    def update(self) -> S:
        now = self.clock.now() if self.clock is not None else time.monotonic()
        if self._until is None:
            self._until = now + float(self.input("seconds"))
        left = self._until - now
        if left > 0:
            self.feedback_message = f"{left:.1f} s to wait"
            return S.RUNNING
        self.feedback_message = "waited"
        return S.SUCCESS


class DescribeCorrection(Skill):
    """A localisation correction {dx, dy, dyaw} in words: "4.2 cm and 1.0 degrees"."""

    NAME = "DescribeCorrection"
    DESCRIPTION = "say a localisation correction in words"
    INPUTS = (Port("correction", "dict"),)
    OUTPUTS = (Port("text", "string", required=False),)

    def update(self) -> S:
        c = self.input("correction") or {}
        text = (f"{math.hypot(c.get('dx', 0.0), c.get('dy', 0.0)) * 100:.1f} cm and "
                f"{abs(math.degrees(c.get('dyaw', 0.0))):.1f} degrees")
        self.set_output("text", text)
        self.feedback_message = text
        return S.SUCCESS


__all__ = ["LocateUser", "PlaceOfPose", "KnobsOn", "ExpectKnobsOff",
           "Remember", "SetValue", "Wait", "DescribeCorrection", "LookAt", "ProposedPlaces", "PlaceId", "LookAtLandmark"]


def look_target(world, target: Any, focus: str = "centre"):
    """The world point (metres) to aim the camera at for ``target``: a node id or search place
    (``World.aim_point``), a point (x, y, z) or a pose mapping. None when there is nothing to
    aim at."""
    if isinstance(target, dict) and "place" not in target and "z" in target:
        return np.array([float(target["x"]), float(target["y"]), float(target["z"])])
    if isinstance(target, dict):
        for k in ("look_at", "target"):
            if target.get(k) is not None:
                return np.asarray(target[k], dtype=float)[:3]
        target = target.get("place") or target.get("part") or target.get("id")
    if isinstance(target, str):
        return world.aim_point(target, focus) if target in world else None
    if isinstance(target, (list, tuple)) and len(target) == 3:
        return np.asarray(target, dtype=float)
    if all(hasattr(target, a) for a in ("x", "y", "z")):      # a Pose
        return np.array([target.x, target.y, target.z], dtype=float)
    return None


def _xyz(point) -> str:
    return "(" + ", ".join(f"{c:.2f}" for c in point) + ") m"


class LookAt(Skill):
    """Turn the head so the camera looks at a node (or a point): ``robot.look_at``. Succeeds
    without moving when there is nothing to aim at (a search place without a target)."""

    NAME = "LookAt"
    DESCRIPTION = "point the camera at a node or a point"
    INPUTS = (Port("target", "any", description="node id, search place, or point (x, y, z)"),
              Port("focus", "string", required=False, default="centre",
                   description="centre, top, or knobs"))
    OUTPUTS = ()

    def update(self) -> S:
        point = look_target(self.world, self.input("target"), str(self.input("focus")))
        if point is None:
            self.feedback_message = "nothing to look at; head left as it is"
            return S.SUCCESS
        action = self.robot.look_at(point)
        # Head moves are instant requests in the adapter protocol (a DoneAction).
        status = action.status() if hasattr(action, "status") else "succeeded"
        if status == "failed":
            self.report(f"could not look at {_xyz(point)}: {action.reason}", point=point.round(3))
            return S.FAILURE
        self.report(f"looking at {_xyz(point)}", point=point.round(3))
        return S.SUCCESS


class ProposedPlaces(Skill):
    """Search places (the dicts PlanSearch writes) from ProposeSearchPositions' base poses:
    each pose gets the table top it faces as the point to look at, and the map's large
    object nearest that table as the place (its new parent if the object turns up there)."""

    NAME = "ProposedPlaces"
    DESCRIPTION = "turn proposed search positions into search places"
    INPUTS = (Port("positions", "list", description="base poses (world)"),
              Port("tables", "list", required=False, default=None,
                   description="table tops {x, y, height, half_extents}"))
    OUTPUTS = (Port("places", "list", required=False), Port("count", "integer", required=False))

    def _nearest_place(self, x: float, y: float) -> str | None:
        best = None
        for obj in self.world.large_objects():
            if not (obj.surfaces or obj.children):
                continue
            lo, hi = self.world.bounds_world(obj.id)
            gap = np.maximum(0.0, np.maximum(lo[:2] - [x, y], [x, y] - hi[:2]))
            d = float(np.linalg.norm(gap))
            if best is None or d < best[0]:
                best = (d, obj.id)
        return best[1] if best else None

    def update(self) -> S:
        tables = self.input("tables") or []
        out = []
        for pose in self.input("positions") or []:
            p = as_pose(pose)
            ahead = np.array([p.x + 0.6 * math.cos(p.yaw), p.y + 0.6 * math.sin(p.yaw), 0.75])
            if tables:
                t = min(tables, key=lambda t: math.hypot(t["x"] - ahead[0], t["y"] - ahead[1]))
                ahead = np.array([t["x"], t["y"], t.get("height", 0.75)])
            place = self._nearest_place(float(ahead[0]), float(ahead[1]))
            if place is None:
                continue
            out.append({"place": place, "x": p.x, "y": p.y, "yaw": p.yaw,
                        "look_at": [round(float(v), 3) for v in ahead], "proposed": True})
        self.set_output("places", out)
        self.set_output("count", len(out))
        self.feedback_message = (f"{len(out)} new places: " + ", ".join(o["place"] for o in out)
                                 if out else "no new place to search")
        return S.SUCCESS if out else S.FAILURE


class PlaceId(Skill):
    """The map id of a search place (a node id, or a dict with ``place``), for skills that
    take a node id (RegisterArticulated)."""

    NAME = "PlaceId"
    DESCRIPTION = "the node id of a search place"
    INPUTS = (Port("place", "any"),)
    OUTPUTS = (Port("id", "node_id", required=False),)

    def update(self) -> S:
        place = self.input("place")
        pid = place.get("place") if isinstance(place, dict) else place
        if not isinstance(pid, str) or pid not in self.world:
            self.report(f"not a place in the map: {words(place)}", place=place)
            return S.FAILURE
        self.set_output("id", pid)
        self.feedback_message = pid
        return S.SUCCESS


class LookAtLandmark(Skill):
    """Point the camera at the ``index``-th nearest landmark (a static large object, map
    order by distance from the believed base pose), so a localisation fix that found too
    little overlap can be tried on another one. Only landmarks in the room the robot is in
    (the localisation fix registers no other). ``seen``: RefineLocalisation's ``views``
    output; the landmarks the views have shown least come first (nearest first among
    them), so each look adds a landmark no view has shown while there is one, and then
    looks again at one shown once."""

    NAME = "LookAtLandmark"
    DESCRIPTION = "point the camera at a nearby landmark"
    INPUTS = (Port("index", "integer", required=False, default=0),
              Port("max_distance", "number", required=False, default=3.5),
              Port("seen", "list", required=False, default=None,
                   description="views whose landmarks to pass over (RefineLocalisation views)"))
    OUTPUTS = (Port("landmark", "node_id", required=False),)

    def update(self) -> S:
        from hearth.skills.map import robot_pose
        base = robot_pose(self.robot)
        from hearth.worldmodel.frames import room_at
        near = []
        shown: dict[str, int] = {}
        for v in self.input("seen") or []:
            for oid in (v.get("landmarks") or ()) if isinstance(v, dict) else ():
                shown[oid] = shown.get(oid, 0) + 1
        room = room_at(self.world, base.x, base.y)
        for obj in self.world.landmarks():
            if room is not None and self.world.room_of(obj.id).id != room.id:
                continue
            c = self.world.T_world(obj.id)[:2, 3]
            d = math.hypot(c[0] - base.x, c[1] - base.y)
            if d <= float(self.input("max_distance")):
                near.append((shown.get(obj.id, 0), d, obj.id))
        near.sort()
        i = int(self.input("index"))
        if i >= len(near):
            self.feedback_message = f"no landmark number {i + 1} within reach of the camera"
            return S.FAILURE
        oid = near[i][-1]
        self.robot.look_at(look_target(self.world, oid))
        self.set_output("landmark", oid)
        self.feedback_message = f"looking at the {self.world.label(oid)}"
        return S.SUCCESS
