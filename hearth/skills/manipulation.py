"""Arm actions through the robot adapter; the map follows what was done."""
from __future__ import annotations

import math

from hearth.robot.adapter import EMPTY_GRASP
from hearth.skills.actions import RobotActionSkill
from hearth.skills.base import Port
from hearth.skills.values import as_pose
from hearth.worldmodel.containers import sliding_open_state
from hearth.worldmodel.nodes import Part


class OpenArticulated(RobotActionSkill):
    """Open a door or drawer by its handle to ``target`` (rad or m; default: 90 degrees, a
    sliding door or a drawer holding surfaces all the way, another drawer 80 % of its travel:
    ``containers.sliding_open_state``; within the joint's limits) and write
    the new state to the map."""

    NAME = "OpenArticulated"
    AUTONOMY = 2
    DESCRIPTION = "open a door or drawer by its handle"
    INPUTS = (Port("part", "any", description="part id, or {part, handle}"),
              Port("handle", "node_id", required=False, default=None),
              Port("target", "number", required=False, default=None))
    OUTPUTS = (Port("state", "number", required=False),)

    def _ids(self):
        part = self.input("part")
        handle = self.input("handle")
        if isinstance(part, dict):
            handle = handle or part.get("handle")
            part = part["part"]
        node = self.world.get(part)
        if not isinstance(node, Part):
            raise ValueError(f"{part} is not a door or drawer")
        if handle is None:
            handle = node.handles[0].id if node.handles else None
        return node, handle

    def _target(self, node: Part) -> float:
        t = self.input("target")
        j = node.joint
        if t is None:
            # a sliding door all the way (its half uncovered), a drawer to look into too
            t = math.radians(90) if j.type == "revolute" else sliding_open_state(node)
        return min(max(float(t), j.lower), j.upper)

    def start(self):
        node, handle = self._ids()
        self._part, self._goal = node.id, self._target(node)
        return self.robot.open_articulated(node.id, handle, self._goal)

    def describe(self) -> str:
        return f"opening {getattr(self, '_part', '')}"

    def succeeded(self, action) -> None:
        self.world.set_joint_state(self._part, self._goal, source=self.NAME)
        self.set_output("state", self._goal)


class CloseArticulated(OpenArticulated):
    NAME = "CloseArticulated"
    DESCRIPTION = "close a door or drawer by its handle"

    def _target(self, node: Part) -> float:
        return node.joint.lower

    def start(self):
        node, handle = self._ids()
        self._part, self._goal = node.id, self._target(node)
        return self.robot.close_articulated(node.id, handle, self._goal)

    def describe(self) -> str:
        return f"closing {getattr(self, '_part', '')}"


class Grasp(RobotActionSkill):
    """Grasp a small object at its (observed) world pose. ``empty`` says whether a failed
    grasp came back with nothing in the gripper (the robot's reason starts with
    ``EMPTY_GRASP``): the object was not where it was seen."""

    NAME = "Grasp"
    AUTONOMY = 3
    DESCRIPTION = "grasp a small object"
    INPUTS = (Port("object_id", "node_id"),
              Port("pose", "pose", required=False, default=None,
                   description="observed world pose; default: the map's"))
    OUTPUTS = (Port("empty", "boolean", required=False,
                    description="the gripper closed on nothing (set when the grasp ends)"),)

    def succeeded(self, action) -> None:
        self.set_output("empty", False)

    def failed(self, action) -> None:
        self.set_output("empty", str(getattr(action, "reason", "")).startswith(EMPTY_GRASP))

    def start(self):
        oid = self.input("object_id")
        pose = self.input("pose")
        self._oid = oid
        pose = as_pose(pose) if pose is not None else self.world.world_pose(oid)
        return self.robot.grasp(oid, pose)

    def describe(self) -> str:
        return f"grasping {getattr(self, '_oid', '')}"


class HandOver(RobotActionSkill):
    """Hand the held object to the user."""

    NAME = "HandOver"
    AUTONOMY = 3
    DESCRIPTION = "hand the held object to the user"
    INPUTS = ()
    OUTPUTS = ()

    def start(self):
        return self.robot.hand_over()

    def describe(self) -> str:
        return "handing over"

    def succeeded(self, action) -> None:
        """The user puts what they were handed down on the surface nearest the robot
        (``World.handover_spot``; the simulator does the same in its truth): the map says so,
        and the next search for it starts there."""
        oid = getattr(action, "result", None)
        if not isinstance(oid, str) or oid not in self.world:
            return
        base = self.robot.base_pose() if hasattr(self.robot, "base_pose") else None
        spot = self.world.handover_spot(base.x, base.y) if base is not None else None
        if spot is not None:
            place, pose, relation = spot
            self.world.move_object(oid, place, pose, relation=relation, source=self.NAME)
