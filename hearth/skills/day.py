"""Skills of a robot's day (docs/day.md): the charger, and finding the user.

Recharging: ``NearestCharger`` -> ``NavigateTo`` its dock pose -> ``Dock`` -> ``WaitCharged``
-> ``Undock``. Finding the user: ``UserRooms`` (rooms, likeliest first) -> per room
``GoToRoom`` and ``LookForUser`` (which counts where the user was found, in the map).
"""
from __future__ import annotations

import math

import py_trees

from hearth.skills.actions import RobotActionSkill
from hearth.skills.base import Port, Skill
from hearth.worldmodel.people import USER, rooms_by_user_likelihood, room_visit_pose

S = py_trees.common.Status


class NearestCharger(Skill):
    """The map's charger nearest the robot and its dock pose. Fails when the map has none."""

    NAME = "NearestCharger"
    DESCRIPTION = "find the charger nearest the robot"
    OUTPUTS = (Port("charger", "node_id", required=False),
               Port("pose", "pose", required=False, description="its dock pose (world)"))

    def update(self) -> S:
        here = self.robot.base_pose()
        found = sorted((math.hypot(p.x - here.x, p.y - here.y), c.id, p)
                       for c in self.world.chargers() for p in [self.world.dock_pose(c.id)])
        if not found:
            self.feedback_message = "the map has no charger"
            return S.FAILURE
        dist, cid, pose = found[0]
        self.set_output("charger", cid)
        self.set_output("pose", pose)
        self.feedback_message = f"{cid}, {dist:.1f} m away"
        return S.SUCCESS


class RestPlace(Skill):
    """Where to rest (hearth/worldmodel/rest.py): the place given, else from the map: a
    declared rest place in the user's room (affordance ``rest``), else the free floor
    nearest the user's room; while the user is away a place with affordance ``rest_away``,
    else the nearest charger's dock, else free floor. Fails only when the map has neither."""

    NAME = "RestPlace"
    DESCRIPTION = "choose where to rest, near the user or out of the way"
    INPUTS = (Port("place", "string", required=False, default="",
                   description="a large object to rest at (given: used as it is)"),
              Port("room", "string", required=False, default="",
                   description="the user's room (default: the room the robot is in)"),
              Port("away", "boolean", required=False, default=False,
                   description="out of the way (the user is out) instead of near the user"))
    OUTPUTS = (Port("target", "any", required=False,
                    description="a node id (its parking position) or a world base pose"),
               Port("words", "string", required=False, description="the place in words"))

    def update(self) -> S:
        from hearth.skills.map import robot_pose
        from hearth.worldmodel.rest import rest_place
        given = self.input("place") or ""
        if given:
            self.set_output("target", given)
            self.set_output("words", f"the {self.world.label(given)}"
                            if self.world is not None and given in self.world
                            else given)
            self.feedback_message = f"resting at {given} (given)"
            return S.SUCCESS
        room = self.input("room") or ""
        if room:
            room = next((r.id for r in self.world.rooms if room in (r.id, r.name)), room)
            if room not in self.world:
                room = ""
        found = rest_place(self.world, room or None, away=bool(self.input("away")),
                           robot_pose=robot_pose(self.robot))
        if found is None:
            self.feedback_message = "the map has no rest place and no free floor"
            return S.FAILURE
        target = found.target
        if not isinstance(target, str):     # a base pose, as a search place gives one
            target = {"x": target.x, "y": target.y, "yaw": target.yaw}
        self.set_output("target", target)
        self.set_output("words", found.words)
        self.feedback_message = f"resting at {found.words} ({found.how})"
        return S.SUCCESS


class Dock(RobotActionSkill):
    """Back onto the charger the robot stands at (its dock pose)."""

    NAME = "Dock"
    AUTONOMY = 1
    DESCRIPTION = "dock on the charger in front of which the robot stands"
    OUTPUTS = (Port("charger", "node_id", required=False),)

    def start(self):
        return self.robot.dock()

    def describe(self) -> str:
        return "docking"

    def succeeded(self, action) -> None:
        self.set_output("charger", action.result)


class Undock(RobotActionSkill):
    """Leave the charger (succeeds at once when not docked)."""

    NAME = "Undock"
    AUTONOMY = 1
    DESCRIPTION = "drive off the charger"

    def start(self):
        return self.robot.undock()

    def describe(self) -> str:
        return "undocking"


class WaitCharged(Skill):
    """Running while the robot charges, until the battery level reaches ``level``; fails
    when it is not (or no longer) on a charger."""

    NAME = "WaitCharged"
    DESCRIPTION = "wait on the charger until the battery is charged to a level"
    INPUTS = (Port("level", "number", required=False, default=0.95,
                   description="battery level to reach (0..1)"),)
    OUTPUTS = (Port("level", "number", required=False, description="the level reached"),)

    def update(self) -> S:
        target = float(self.input("level"))
        state = self.robot.battery_state()
        if state.level >= target:
            self.set_output("level", state.level)
            self.feedback_message = f"charged: {state.level:.0%}"
            return S.SUCCESS
        if not state.docked:
            self.feedback_message = f"not on a charger ({state.level:.0%})"
            return S.FAILURE
        self.feedback_message = f"charging: {state.level:.0%} of {target:.0%}"
        return S.RUNNING

    def idle_until(self) -> float | None:
        """The clock time before which ticking this changes nothing (the level is reached),
        when the adapter can tell (a simulated battery); None otherwise. A simulated day
        jumps its clock to it instead of ticking through the charge."""
        battery = getattr(self.robot, "battery", None)
        model = getattr(battery, "model", None)
        if model is None or getattr(battery, "docked", None) is None:
            return None
        return battery.t + model.seconds_to(battery.level, float(self.input("level")))


class UserRooms(Skill):
    """The rooms to look for the user in, likeliest first (hearth.worldmodel.people), without those
    in ``skip`` (already visited by an interrupted run)."""

    NAME = "UserRooms"
    DESCRIPTION = "list the rooms to look for the user in, likeliest first"
    INPUTS = (Port("skip", "list", required=False, default=None,
                   description="room ids not to visit again"),)
    OUTPUTS = (Port("rooms", "list", required=False),)

    def update(self) -> S:
        here = self.robot.base_pose()
        rooms = rooms_by_user_likelihood(self.world, here.x, here.y, self.input("skip") or ())
        self.set_output("rooms", rooms)
        if not rooms:
            self.feedback_message = "no room left to look in"
            return S.FAILURE
        self.feedback_message = ", ".join(rooms)
        return S.SUCCESS


class GoToRoom(RobotActionSkill):
    """Drive to where the robot looks around a room (hearth.worldmodel.people.room_visit_pose);
    ``room`` is a room id or name."""

    NAME = "GoToRoom"
    AUTONOMY = 1
    DESCRIPTION = "drive into a room, to where the robot can look around it"
    INPUTS = (Port("room", "string"),)

    def start(self):
        room = str(self.input("room"))
        for r in self.world.rooms:
            if room == r.name:
                room = r.id
        self._room = room
        return self.robot.navigate_to(room_visit_pose(self.world, room))

    def describe(self) -> str:
        return f"driving to the {getattr(self, '_room', 'room')}"


class LookForUser(RobotActionSkill):
    """Look around the room the robot is in for the user (``robot.look_for_person``). Counts
    the look in the map (where the user turns up, for the next search order) and appends the
    room to ``visited`` whether the user was there or not."""

    NAME = "LookForUser"
    DESCRIPTION = "look around the room for the user"
    INPUTS = (Port("room", "string", description="the room the robot is in (id)"),
              Port("visited", "list", required=False, default=None,
                   description="rooms looked in so far"))
    OUTPUTS = (Port("found", "string", required=False, description="the room the user is in"),
               Port("visited", "list", required=False, description="visited plus this room"))

    def start(self):
        return self.robot.look_for_person()

    def describe(self) -> str:
        return f"looking for the user in the {self.input('room')}"

    def update(self) -> S:
        status = super().update()
        if status != S.RUNNING:
            room = str(self.input("room"))
            self.set_output("visited", list(self.input("visited") or []) + [room])
            self.world.record_search(USER, room, status == S.SUCCESS, source=self.NAME)
            if status == S.SUCCESS:
                self.set_output("found", room)
                self.feedback_message = f"the user is in the {room}"
        return status
