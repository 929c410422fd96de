"""Skills that read and write the semantic map (no robot, no perception)."""
from __future__ import annotations


import numpy as np
import py_trees

from hearth.skills.base import Port, Skill
from hearth.skills.values import as_pose
from hearth.worldmodel.nodes import SmallObject
from hearth.worldmodel.pose import Pose
from hearth.worldmodel.search import SearchWeights, search_order
from hearth.worldmodel.world import best_matches

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
                self.report(f"I don't know any \"{words}\" in this home", words=words)
                return S.FAILURE
            best = [m.node for m in best_matches(matches)]
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
    """Order the places to search for an object by the HOBBIT cost (hearth/worldmodel/search.py)."""

    NAME = "PlanSearch"
    DESCRIPTION = "order the places to search for an object, likeliest and nearest first"
    INPUTS = (Port("object_id", "node_id"),
              Port("user_room", "string", required=False, default=None),
              Port("learned", "boolean", required=False, default=True),
              Port("max_places", "integer", required=False, default=100),
              Port("exclude", "list", required=False, default=None),
              Port("among", "list", required=False, default=None,
                   description="only these places (the first plan): planning again from "
                               "where the robot is reorders them, never swaps one out"))
    OUTPUTS = (Port("places", "list", required=False), Port("count", "integer", required=False),
               Port("first", "dict", required=False, description="the cheapest place"))

    def update(self) -> S:
        oid = self.input("object_id")
        exclude = tuple(place_id(p) for p in (self.input("exclude") or ()))
        places = search_order(self.world, oid, robot_pose(self.robot),
                              user_room=self.input("user_room") or None,
                              weights=SearchWeights(), learned=bool(self.input("learned")),
                              exclude=exclude)
        among = self.input("among")
        if among is not None:
            # The budget is the places of the first plan: a re-plan from another position
            # may change their order, but must not push one of them out for a place the
            # first plan ranked below the budget (it would never be looked at).
            keep = {place_id(p) for p in among}
            places = [p for p in places if p.place in keep]
        places = places[: int(self.input("max_places") or len(places))]
        self.set_output("places", [p.as_dict() for p in places])
        self.set_output("count", len(places))
        if places:
            self.set_output("first", places[0].as_dict())
        self.feedback_message = ("search order: " + ", ".join(p.place for p in places)
                                 if places else "no place left to search")
        return S.SUCCESS if places else S.FAILURE


def place_id(place) -> str:
    """The large object id of a search place (a dict with ``place``) or an id."""
    return str(place["place"]) if isinstance(place, dict) else str(place)


class PlaceSurfaces(Skill):
    """The surface levels of a place to look at one after the other (every shelf of a
    bookshelf, inside a cupboard after opening): the level the map believes the object on
    first, then the others highest first. A place without surfaces is one level, its top; a
    proposed place (with its own point to look at) is one level, that point."""

    NAME = "PlaceSurfaces"
    DESCRIPTION = "list the surface levels of a place to look at"
    INPUTS = (Port("place", "any", required=False, default=None,
                   description="a search place or a large object id (default: the object's "
                               "place in the map)"),
              Port("object_id", "node_id", required=False, default=None),
              Port("above", "number", required=False, default=0.05,
                   description="metres above a surface's centre to aim at"))
    OUTPUTS = (Port("levels", "list", required=False,
                    description="{place, surface, relation, look_at: [x, y, z]} each"),
               Port("count", "integer", required=False))

    def update(self) -> S:
        place = self.input("place")
        if place is None:
            oid = self.input("object_id")
            parent = self.world.parent(oid) if oid else None
            if parent is None:
                self.feedback_message = "PlaceSurfaces: no place given and the object has none"
                return S.FAILURE
            place = parent.id
        pid = place_id(place)
        if isinstance(place, dict) and place.get("look_at") is not None:
            levels = [dict(place=pid, surface=None, relation=place.get("relation", "on"),
                           look_at=[float(v) for v in place["look_at"]][:3])]
        else:
            up = float(self.input("above"))
            found = self.world.surfaces_of(pid)
            oid = self.input("object_id")
            if oid and found and self.world.parent(oid) is not None \
                    and self.world.parent(oid).id == pid:
                believed = self.world.surface_near(pid, self.world.T_world(oid)[:3, 3])
                found.sort(key=lambda lv: lv.surface != believed.surface)
            levels = [dict(place=pid, surface=lv.name, relation=lv.relation,
                           look_at=[round(float(v), 4) for v in
                                    (lv.T_world_surface @ np.array([0.0, 0.0, up, 1.0]))[:3]])
                      for lv in found]
            if not levels:
                levels = [dict(place=pid, surface=None, relation="on",
                               look_at=[round(float(v), 4) for v in self.world.aim_point(pid, "top")])]
        self.set_output("levels", levels)
        self.set_output("count", len(levels))
        self.feedback_message = f"{pid}: " + ", ".join(lv["surface"] or "top" for lv in levels)
        return S.SUCCESS


class RecordSearch(Skill):
    """Count a search for an object at a place (learned search order)."""

    NAME = "RecordSearch"
    DESCRIPTION = "remember whether an object was found at a place"
    INPUTS = (Port("object_id", "node_id"), Port("place", "any"),
              Port("found", "boolean", required=False, default=False))
    OUTPUTS = ()

    def update(self) -> S:
        place = self.input("place")
        pid = place_id(place)
        found = bool(self.input("found"))
        self.world.record_search(self.input("object_id"), pid, found, source=self.NAME)
        self.feedback_message = f"{'found' if found else 'not found'} at {pid}"
        return S.SUCCESS


class UpdateObjectLocation(Skill):
    """Write where an object was seen: its new parent and its pose (world frame in,
    parent frame in the map; seen in an open drawer, the drawer's frame: the map has it "in"
    the drawer and it moves with it)."""

    NAME = "UpdateObjectLocation"
    DESCRIPTION = "write an object's observed place and pose into the map"
    INPUTS = (Port("object_id", "node_id"), Port("place", "any"),
              Port("pose", "pose", description="observed pose in the world frame"),
              Port("relation", "string", required=False, default=None))
    OUTPUTS = (Port("location", "string", required=False),)

    def update(self) -> S:
        oid = self.input("object_id")
        place = self.input("place")
        pid = place_id(place)
        relation = self.input("relation") or (place.get("relation") if isinstance(place, dict) else None) or "on"
        T_world_obj = as_pose(self.input("pose")).matrix()
        # Seen on a part's surface (in an open drawer): the map keeps it in that part's frame,
        # so it moves with the drawer when the drawer is closed.
        level = self.world.surface_near(pid, T_world_obj[:3, 3])
        part = ""
        if level is not None and level.part:
            q = np.linalg.inv(level.T_world_surface) @ T_world_obj[:, 3]
            if abs(q[0]) <= level.size_x / 2 + 0.05 and abs(q[1]) <= level.size_y / 2 + 0.05:
                part = level.part
        T_world_parent = self.world.T_world(part or pid)
        pose_parent = Pose.from_matrix(np.linalg.inv(T_world_parent) @ T_world_obj)
        self.world.move_object(oid, pid, pose_parent, relation=relation, source=self.NAME,
                               part=part)
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


class Uncovered(Skill):
    """Succeed unless, by the map, a sliding door of the object's furniture stands in front
    of it (``containers.covering_door``; objects "in" their furniture only). Looking in at an
    angle through the half a search slid open, a camera can see an object behind the other
    half, where no arm reaches: the search then slides the halves and looks again."""

    NAME = "Uncovered"
    DESCRIPTION = "check that no sliding door stands in front of an object"
    INPUTS = (Port("object_id", "node_id"),)
    OUTPUTS = ()

    def update(self) -> S:
        from hearth.worldmodel.containers import covering_door
        oid = self.input("object_id")
        door = covering_door(self.world, oid) if self.world.get(oid).relation == "in" else None
        if door is not None:
            self.feedback_message = f"{oid} is behind {door}"
            return S.FAILURE
        self.feedback_message = f"no sliding door in front of {oid}"
        return S.SUCCESS


class ClosedParts(Skill):
    """The closed doors and drawers (with handles) of a place that must be opened to look in
    (hearth/worldmodel/containers.py): closed hinged doors, drawers that hold surfaces, and
    of sliding doors sharing a track the one that uncovers where the object is believed;
    the track's other doors are ``other_half``, to open (after closing the first) for a
    second look.

    Outputs empty lists for places without any (a table)."""

    NAME = "ClosedParts"
    DESCRIPTION = "list a container's closed doors and drawers"
    INPUTS = (Port("place", "any"),
              Port("object_id", "node_id", required=False, default=None,
                   description="the object looked for (a sliding door uncovering where it is "
                               "believed is opened first)"),
              Port("open_threshold", "number", required=False, default=0.35,
                   description="a door counts as open above this (rad)"))
    OUTPUTS = (Port("parts", "list", required=False), Port("count", "integer", required=False),
               Port("other_half", "list", required=False,
                    description="sliding doors to open after closing the first of their track"))

    def update(self) -> S:
        from hearth.worldmodel.containers import openings
        place = self.input("place")
        pid = place_id(place)
        found = openings(self.world, pid, self.input("object_id"),
                         float(self.input("open_threshold")))
        out = found.first
        self.set_output("parts", out)
        self.set_output("count", len(out))
        self.set_output("other_half", found.then)
        self.feedback_message = (f"{pid}: " + (", ".join(p["part"] for p in out) + " closed"
                                                    if out else "nothing to open"))
        return S.SUCCESS
