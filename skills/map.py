"""Skills that read and write the semantic map (no robot, no perception)."""
from __future__ import annotations

import math

import numpy as np
import py_trees

from skills.base import Port, Skill
from skills.values import as_pose
from worldmodel.nodes import LargeArticulatedObject, SmallObject
from worldmodel.pose import Pose
from worldmodel.search import SearchWeights, search_order

S = py_trees.common.Status


def robot_pose(robot) -> Pose:
    """The robot's believed base pose (x, y, yaw), or the origin when it has none."""
    fn = getattr(robot, "base_pose", None) or getattr(robot, "pose", None)
    return as_pose(fn()) if callable(fn) else Pose()


class ResolveObject(Skill):
    """Find the object a person named ("blue cup", "my pill box") in the map.

    Fails with a clarifying question listing the candidates when several objects match
    equally well, and says so when nothing matches.
    """

    NAME = "ResolveObject"
    DESCRIPTION = "find the small object named by words in the map"
    INPUTS = (Port("object", "string", description="words or an id"),)
    OUTPUTS = (Port("object_id", "node_id", required=False),
               Port("parent_id", "node_id", required=False),
               Port("room", "node_id", required=False, description="the room's id"),
               Port("room_name", "string", required=False),
               Port("label", "string", required=False))

    def update(self) -> S:
        words = str(self.input("object"))
        if words in self.world and isinstance(self.world.get(words), SmallObject):
            best = [self.world.get(words)]
        else:
            matches = [m for m in self.world.find(words) if isinstance(m.node, SmallObject)]
            if not matches:
                self.feedback_message = f"I don't know any {words!r} in this home"
                return S.FAILURE
            top = matches[0].score
            best = [m.node for m in matches if math.isclose(m.score, top)]
        if len(best) > 1:
            labels = [f"the {self.world.label(n.id)} {self.world.describe_location(n.id)}"
                      for n in best]
            self.feedback_message = f"which {words} do you mean: " + " or ".join(labels) + "?"
            return S.FAILURE
        node = best[0]
        parent = self.world.parent(node.id)
        self.set_output("object_id", node.id)
        self.set_output("parent_id", parent.id if parent is not None else None)
        room = self.world.room_of(node.id)
        self.set_output("room", room.id)
        self.set_output("room_name", room.name)
        self.set_output("label", self.world.label(node.id))
        self.feedback_message = f"{node.id} is believed {self.world.describe_location(node.id)}"
        return S.SUCCESS


class PlanSearch(Skill):
    """Order the places to search for an object by the HOBBIT cost (worldmodel/search.py)."""

    NAME = "PlanSearch"
    DESCRIPTION = "order the places to search for an object, likeliest and nearest first"
    INPUTS = (Port("object_id", "node_id"),
              Port("user_room", "string", required=False, default=None),
              Port("learned", "boolean", required=False, default=True),
              Port("max_places", "integer", required=False, default=6),
              Port("exclude", "list", required=False, default=None))
    OUTPUTS = (Port("places", "list", required=False), Port("count", "integer", required=False))

    def update(self) -> S:
        oid = self.input("object_id")
        places = search_order(self.world, oid, robot_pose(self.robot),
                              user_room=self.input("user_room") or None,
                              weights=SearchWeights(), learned=bool(self.input("learned")),
                              exclude=tuple(self.input("exclude") or ()))
        places = places[: int(self.input("max_places") or len(places))]
        self.set_output("places", [p.as_dict() for p in places])
        self.set_output("count", len(places))
        self.feedback_message = "search order: " + ", ".join(p.place for p in places)
        return S.SUCCESS if places else S.FAILURE


class RecordSearch(Skill):
    """Count a search for an object at a place (learned search order)."""

    NAME = "RecordSearch"
    DESCRIPTION = "remember whether an object was found at a place"
    INPUTS = (Port("object_id", "node_id"), Port("place", "any"),
              Port("found", "boolean", required=False, default=False))
    OUTPUTS = ()

    def update(self) -> S:
        place = self.input("place")
        place_id = place["place"] if isinstance(place, dict) else str(place)
        found = bool(self.input("found"))
        self.world.record_search(self.input("object_id"), place_id, found, source=self.NAME)
        self.feedback_message = f"{'found' if found else 'not found'} at {place_id}"
        return S.SUCCESS


class UpdateObjectLocation(Skill):
    """Write where an object was seen: its new parent and its pose (world frame in,
    parent frame in the map). Nothing changes when it is where the map said."""

    NAME = "UpdateObjectLocation"
    DESCRIPTION = "write an object's observed place and pose into the map"
    INPUTS = (Port("object_id", "node_id"), Port("place", "any"),
              Port("pose", "pose", description="observed pose in the world frame"),
              Port("relation", "string", required=False, default=None))
    OUTPUTS = (Port("location", "string", required=False),)

    def update(self) -> S:
        oid = self.input("object_id")
        place = self.input("place")
        place_id = place["place"] if isinstance(place, dict) else str(place)
        relation = self.input("relation") or (place.get("relation") if isinstance(place, dict) else None) or "on"
        T_world_obj = as_pose(self.input("pose")).matrix()
        T_world_parent = self.world.T_world(place_id)
        pose_parent = Pose.from_matrix(np.linalg.inv(T_world_parent) @ T_world_obj)
        self.world.move_object(oid, place_id, pose_parent, relation=relation, source=self.NAME)
        where = self.world.describe_location(oid)
        self.set_output("location", where)
        self.feedback_message = f"{oid} is {where}"
        return S.SUCCESS


class DescribeLocation(Skill):
    """Words for where an object is, from the map: "the blue cup was on the kitchen table"."""

    NAME = "DescribeLocation"
    DESCRIPTION = "say in words where an object is"
    INPUTS = (Port("object_id", "node_id"),
              Port("template", "string", required=False,
                   default="the {label} was {location} in the {room}"))
    OUTPUTS = (Port("text", "string", required=False),)

    def update(self) -> S:
        oid = self.input("object_id")
        text = str(self.input("template")).format(
            label=self.world.label(oid), location=self.world.describe_location(oid),
            room=self.world.room_of(oid).name)
        self.set_output("text", text)
        self.feedback_message = text
        return S.SUCCESS


class ClosedParts(Skill):
    """The closed doors and drawers (with handles) of a place that must be opened to look in.

    Outputs an empty list for places without any (a table)."""

    NAME = "ClosedParts"
    DESCRIPTION = "list a container's closed doors and drawers"
    INPUTS = (Port("place", "any"),
              Port("open_threshold", "number", required=False, default=0.35,
                   description="a door counts as open above this (rad or m)"))
    OUTPUTS = (Port("parts", "list", required=False), Port("count", "integer", required=False))

    def update(self) -> S:
        place = self.input("place")
        place_id = place["place"] if isinstance(place, dict) else str(place)
        node = self.world.get(place_id)
        out = []
        if isinstance(node, LargeArticulatedObject) and "container" in node.affordances:
            thr = float(self.input("open_threshold"))
            for p in node.parts:
                if p.type == "door" and p.handles and p.joint.state < thr:
                    out.append({"part": p.id, "handle": p.handles[0].id})
        self.set_output("parts", out)
        self.set_output("count", len(out))
        self.feedback_message = (f"{place_id}: " + (", ".join(p["part"] for p in out) + " closed"
                                                    if out else "nothing to open"))
        return S.SUCCESS
