"""Driving the robot base."""
from __future__ import annotations

import math

import py_trees

from hearth.robot.adapter import DoneAction
from hearth.skills.actions import RobotActionSkill
from hearth.skills.base import Port, Skill
from hearth.skills.values import as_pose
from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.viewing import (ARM_REACH, KNOB_VIEW_DISTANCE, knob_view_pose, reach_point,
                                       reach_pose)
from hearth.worldmodel.search import travel


#: ``parking: another``: the nearest parking position other than the one the robot is at.
ANOTHER = "another"
#: ``parking: nearest``: the parking position nearest the robot (it may be already there), or
#: with ``near`` given, nearest that pose (an object to grasp at the far end of a long table).
NEAREST = "nearest"
#: ``parking: knobs``: straight in front of the node's knob panel, facing it, the robot centre
#: ``distance`` (default KNOB_VIEW_DISTANCE) from its knobs (knobs on top: on the parking side,
#: nearer, looking down); another view of knobs the parking positions left unread
#: (hearth.worldmodel.viewing.knob_view_pose).
KNOBS = "knobs"
#: ``parking: reach``: within the arm's reach of ``target`` (a handle, a door or drawer: its
#: handle, a knob): staying where the robot is when it is already, else the parking position
#: nearest to it, else free floor in front of it (hearth.worldmodel.viewing.reach_pose).
REACH = "reach"
#: Metres kept from the arm's full reach for the base's localisation error.
REACH_MARGIN = 0.15
#: The distances (m) ``parking: knobs`` accepts.
KNOB_DISTANCES = (0.3, 3.0)
#: A robot closer than this (m) to a parking position is at it.
AT_PARKING_M = 0.15


def _knob_distance(distance) -> float:
    """The metres of ``parking: knobs``: ``distance``, or KNOB_VIEW_DISTANCE when not given
    (ValueError outside KNOB_DISTANCES)."""
    if distance is None:
        return KNOB_VIEW_DISTANCE
    lo, hi = KNOB_DISTANCES
    if not lo <= float(distance) <= hi:
        raise ValueError(f"distance {distance}: the knobs are viewed from {lo:g} to {hi:g} m")
    return float(distance)


def parkings_by_distance(world, robot, target: str, beyond: float = -1.0, near=None) -> list:
    """``(metres of path from the robot, id, world pose)`` of ``target``'s parking positions
    further than ``beyond`` (straight line) from the robot, nearest first; with ``near`` (a
    pose, as ``as_pose`` takes it), the metres from it instead of from the robot."""
    here = as_pose(near) if near is not None else robot.base_pose()
    # Metres of path on the map's occupancy grid (docs/navigation.md); a parking position no
    # path reaches is left out while another is reachable (else the drive says why not).
    length_to, _on_grid = travel(world, here)
    found = [(length_to(pose.x, pose.y), p.id, pose) for p, pose in world.parking_positions(target)
             if math.hypot(pose.x - here.x, pose.y - here.y) > beyond]
    reachable = [f for f in found if math.isfinite(f[0])]
    if not reachable:
        reachable = [(math.hypot(pose.x - here.x, pose.y - here.y), pid, pose)
                     for _d, pid, pose in found]
    return sorted(reachable, key=lambda f: f[:2])


class NavigateTo(RobotActionSkill):
    """Drive to a base pose, or to a map node's parking position (its default, or ``parking``).

    ``target``: a node id, a pose (x, y, yaw) or a search place (a mapping with x, y, yaw).
    """

    NAME = "NavigateTo"
    AUTONOMY = 1
    DESCRIPTION = "drive the base to a pose or to a node's parking position"
    INPUTS = (Port("target", "any", description="node id, pose, or search place"),
              Port("parking", "string", required=False, default=None,
                   description="parking position id (default: the node's default), "
                               "'another': the nearest one the robot is not at (a second "
                               "view of the same thing), or 'nearest': the nearest one "
                               "(back within reach of the node from a view further away), or "
                               "'knobs': straight in front of its knob panel, facing it, or "
                               "'reach': within the arm's reach of the target (a handle, door, "
                               "drawer or knob; no drive when it is already)"),
              Port("near", "pose", required=False, default=None,
                   description="with parking 'nearest': the one nearest this pose (world) "
                               "instead of the robot: where an object to grasp was seen, so "
                               "that the arm reaches it on a long table"),
              Port("distance", "number", required=False, default=None,
                   description="with parking 'knobs': metres from the knobs (0.3-3; default "
                               "1.0)"))
    OUTPUTS = (Port("pose", "pose", required=False, description="the goal pose (world, x/y/yaw)"),)

    def start(self):
        target = self.input("target")
        parking = self.input("parking")
        if parking == REACH and isinstance(target, dict) and target.get("part"):
            target = str(target.get("handle") or target["part"])    # {part, handle}
        if isinstance(target, str):
            if parking == ANOTHER:
                parking, goal = self._another(target)
            elif parking == NEAREST:
                parking, goal = self._nearest(target, self.input("near"))
            elif parking == REACH:
                goal = self._within_reach(target)
                if goal is None:
                    self._what, self._goal = f"within reach of {target}", self.robot.base_pose()
                    return DoneAction("navigate_to", result=self._goal)
            elif parking == KNOBS:
                goal = knob_view_pose(self.world, target,
                                      _knob_distance(self.input("distance")))
                if goal is None:
                    raise ValueError(f"{target} has no free pose in front of its knobs")
            elif parking:
                goal = self.world.parking_pose(target, parking)
            else:
                goal = self.world.parking_positions(target)[0][1]
            self._what = f"to {target}" + (f" ({parking})" if parking else "")
        else:
            if isinstance(target, dict) and target.get("parking") and target.get("place"):
                self._what = f"to {target['place']} ({target['parking']})"
            else:
                self._what = "to pose"
            goal = as_pose(target)
        self._goal = goal
        return self.robot.navigate_to(goal)

    def _within_reach(self, target: str):
        """None when the believed base is within the arm's reach of ``target`` already, else
        the pose to drive to (ValueError when no free pose reaches it)."""
        reach = float(getattr(self.robot, "reach", ARM_REACH)) - REACH_MARGIN
        point = reach_point(self.world, target)
        here = self.robot.base_pose()
        if math.hypot(point[0] - here.x, point[1] - here.y) <= reach:
            return None
        goal = reach_pose(self.world, target, reach)
        if goal is None:
            raise ValueError(f"no free floor within reach ({reach:.2f} m) of {target}")
        return goal

    def _another(self, target: str):
        """The parking position of ``target`` nearest to the robot among those more than
        ``AT_PARKING_M`` from where it stands (ValueError when there is none)."""
        found = self._by_distance(target, beyond=AT_PARKING_M)
        if not found:
            raise ValueError(f"{target} has no other parking position than the one the robot is at")
        return found[0][1], found[0][2]

    def _nearest(self, target: str, near=None):
        """The parking position of ``target`` nearest to the robot, or to ``near`` when given
        (ValueError when it has none)."""
        found = self._by_distance(target, near=near)
        if not found:
            raise ValueError(f"{target} has no parking position")
        return found[0][1], found[0][2]

    def _by_distance(self, target: str, beyond: float = -1.0, near=None):
        return parkings_by_distance(self.world, self.robot, target, beyond, near)

    def describe(self) -> str:
        return f"navigating {getattr(self, '_what', '')}".strip()

    def succeeded(self, action) -> None:
        self.set_output("pose", self._goal)


class OtherParkings(Skill):
    """The parking positions of a node other than the one the robot is at, nearest first: a
    mission visits them one after the other (``for_each ... until: success``) to look at
    the node from every side it can, each once (missions/subtrees/knobs.yaml)."""

    NAME = "OtherParkings"
    DESCRIPTION = "list a node's parking positions other than the robot's, nearest first"
    INPUTS = (Port("target", "node_id"),)
    OUTPUTS = (Port("places", "list", required=False,
                    description="parking position ids, nearest first"),)

    def update(self) -> py_trees.common.Status:
        target = self.input("target")
        try:
            places = [pid for _, pid, _ in parkings_by_distance(self.world, self.robot, target,
                                                                 beyond=AT_PARKING_M)]
        except (WorldError, KeyError, ValueError) as err:   # not a node of the map
            said = str(err).strip("'\"")
            self.feedback_message = said if str(target) in said else f"{target}: {said}"
            return py_trees.common.Status.FAILURE
        self.set_output("places", places)
        if not places:
            self.feedback_message = f"{target} has no other parking position"
            return py_trees.common.Status.FAILURE
        self.feedback_message = ", ".join(places)
        return py_trees.common.Status.SUCCESS
