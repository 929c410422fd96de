"""The simulated robot: a truth world, a drifting localisation, a pan/tilt RGB-D camera and
an arm whose actions change the truth, on a (simulated) clock.

- The *truth* is a ``hearth.worldmodel.World`` (same format as the belief map) that only this robot
  changes; it is rendered in its current articulation state by open3d ray casting
  (hearth/perception/render.py) with the Kinect-class noise of robot/noise.py. The ray-casting scene
  is rebuilt only when the truth's geometry changes (a door moved, an object picked up).
- Localisation: the believed base pose is the true pose composed with a body-frame error,
  ``T_believed = T_true @ T_error``. Driving to a believed goal therefore ends at
  ``T_goal @ inv(T_error)`` in truth; ``apply_correction`` replaces the error.
- The arm moves relative to the base: a pose given in the (believed) world frame to
  ``grasp`` or ``place`` is where the robot believes it is from where it believes it stands,
  ``T_true @ inv(T_believed) @ T`` in truth (``_physical``). An object seen a moment ago is
  grasped wherever the robot believes it stands; one whose pose was taken before the error
  changed (a correction applied, the base turned: the error is in the base's frame) or from
  the map is missed by as much as the error moves it.
- Battery (robot/battery.py): drains standing, more while the base drives and the arm
  moves, and charges on a charger's dock (``dock()`` at a map ``Charger``'s dock pose,
  ``undock()``; driving off a dock undocks first). A flat battery refuses to move anything.
- Driving follows the shortest path on the truth's occupancy grid (walls with their
  doorways, furniture footprints, the robot's radius: hearth/worldmodel/navigation.py); a
  goal with no path is refused with the reason ("no path to (x, y): the goal ... is inside
  the wardrobe"), and the robot stays where it is.
- Time: every action takes simulated time on the injected clock (driving: path length over
  speed plus turning, to the goal's heading and at the path's corners, over turn speed; arm motions: approach time plus joint travel over joint
  speed). Actions are evaluated lazily from the clock, so a SimClock runs as fast as the CPU
  allows; nothing here sleeps.
"""
from __future__ import annotations

import math
import threading
from typing import Callable, Iterable, Optional

import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.robot.adapter import (EMPTY_GRASP, Action, DoneAction, FailedAction, TimedAction,
                                  as_base_pose)
from hearth.robot.battery import Battery, BatteryState
from hearth.robot.clock import SimClock
from hearth.robot.errors import RobotError
from hearth.robot.noise import KinectNoise
from hearth.robot.sim import (HEAD, Frame, HeadMount, PanTiltHead, SpokenAndLogged, camera_pose,
                              render_view)
from hearth.worldmodel.nodes import LargeArticulatedObject, LargeObject, Part, SmallObject
from hearth.worldmodel.frames import room_at
from hearth.worldmodel.navigation import NoPath, nav_grid
from hearth.worldmodel.pose import Pose, wrap_angle

#: Where a held object is carried, in the base frame (in front of the robot, below the camera).
T_BASE_CARRY = Pose(0.40, 0.0, 0.85).matrix()


class SimulatedRobot(PanTiltHead, SpokenAndLogged):
    """A robot adapter (robot/adapter.py) over a simulated home.

    ``truth``: the true world (changed by the robot's actions; pass a copy to keep yours).
    ``start_pose``: true base pose (Pose or (x, y, yaw)); default the first parking position.
    ``localisation_error``: body-frame error, believed = true composed with it.
    ``stuck_knobs`` / ``locked``: knob ids that will not turn / part ids that will not open.
    Speeds in m/s and rad/s; ``reach`` (m) from the base centre to what the arm touches.
    ``renderer``: what draws the camera's frames, "hearth" (hearth/perception/render.py) or
    "mujoco" (hearth/robot/mujoco_render.py); default ``$HEARTH_SIM_RENDERER``, else "hearth"
    (an environment variable so that a suite's worker processes inherit it).
    ``battery``: a ``robot.battery.Battery`` (default: full, the default model);
    ``dock_time`` / ``undock_time`` (s); ``person_room``: the room id the user is in (the
    simulated person detector's truth, see ``look_for_person``; None: nobody home).
    """

    #: How near (m, rad) the true base pose must be to a charger's dock pose to dock.
    DOCK_TOLERANCE = (0.15, math.radians(10))
    #: Seconds a look around a room for a person takes (the head sweeps the room).
    LOOK_FOR_PERSON_S = 4.0

    def __init__(self, truth, clock=None, start_pose=None, localisation_error=Pose(),
                 intrinsics: Optional[Intrinsics] = None,
                 noise: Optional[KinectNoise] = KinectNoise(), seed: int = 0,
                 mount: HeadMount = HEAD, stuck_knobs: Iterable[str] = (),
                 locked: Iterable[str] = (), speed: float = 0.5, turn_speed: float = 1.0,
                 joint_speed: float = 0.5, drawer_speed: float = 0.15, approach_time: float = 2.0,
                 reach: float = 1.6, grasp_tolerance: float = 0.08,
                 renderer: Optional[str] = None,
                 battery: Optional[Battery] = None, dock_time: float = 5.0,
                 undock_time: float = 3.0, person_room: Optional[str] = None):
        import os
        self.truth = truth
        self.renderer = renderer or os.environ.get("HEARTH_SIM_RENDERER", "hearth")
        self.clock = clock if clock is not None else SimClock()
        self.intrinsics = intrinsics or Intrinsics.kinect()
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.mount = mount
        self.stuck_knobs = set(stuck_knobs)
        self.locked = set(locked)
        self.speed, self.turn_speed = float(speed), float(turn_speed)
        self.joint_speed, self.drawer_speed = float(joint_speed), float(drawer_speed)
        self.approach_time, self.reach = float(approach_time), float(reach)
        self.grasp_tolerance = float(grasp_tolerance)
        if start_pose is None:
            start_pose = _first_parking(truth)
        self._true = as_base_pose(start_pose)
        self._error = as_base_pose(localisation_error)
        self._pan, self._tilt = 0.0, 0.0
        self._actions: list[tuple[str, Action]] = []
        self.held: Optional[SmallObject] = None
        self.handed_over: list[str] = []
        self.said: list[str] = []
        self.log: list[dict] = []
        self.stops = 0
        self._scene = None
        self._scene_key = None
        self._dirty = True
        self._unsubscribe = truth.subscribe(self._on_truth_change)
        self.battery = battery if battery is not None else Battery(now=self.clock.now())
        # battery_state() may be asked from another thread than the one driving the robot
        # (a day's watch under hearth serve): the integration is done under this lock.
        self._battery_lock = threading.Lock()
        self.battery.t = max(self.battery.t, self.clock.now())
        self.dock_time, self.undock_time = float(dock_time), float(undock_time)
        self.person_room = person_room

    # -- ground truth (for tests, scoring and recordings; skills must not use these) -------
    def true_pose(self) -> Pose:
        self._poll()
        return self._true

    def localisation_error(self) -> Pose:
        return self._error

    def _on_truth_change(self, change) -> None:
        self._dirty = True

    # -- localisation ----------------------------------------------------------------------
    def base_pose(self) -> Pose:
        self._poll()
        return self._believed()

    def _believed(self) -> Pose:
        return _planar(self._true.matrix() @ self._error.matrix())

    def apply_correction(self, pose) -> None:
        self._poll()
        believed = as_base_pose(pose)
        self._error = _planar(np.linalg.inv(self._true.matrix()) @ believed.matrix())
        self._log("apply_correction", pose=believed.as_dict())

    def drift_odometry(self, believed) -> None:
        """Set the believed pose as dead reckoning left it (odometry drift, e.g. during a
        tour: hearth/robot/tour.py); unlike ``apply_correction`` it is not a logged action."""
        self._poll()
        self._error = _planar(np.linalg.inv(self._true.matrix()) @ as_base_pose(believed).matrix())

    # -- base and head ---------------------------------------------------------------------
    def navigate_to(self, pose) -> Action:
        self._poll()
        goal = as_base_pose(pose)
        busy = self._busy("base", "navigate_to")
        if busy:
            return busy
        goal_true = _planar(goal.matrix() @ np.linalg.inv(self._error.matrix()))
        if not self._inside_home(goal_true):
            return self._refuse("navigate_to", f"goal ({goal.x:.2f}, {goal.y:.2f}) is outside "
                                               "every room")
        flat = self._flat("navigate_to")
        if flat:
            return flat
        start = self._true
        # The base follows the shortest path on the truth's occupancy grid (walls, doorways,
        # furniture, the robot's radius: hearth/worldmodel/navigation.py); with none, it
        # does not move and says what stands in the way.
        grid = nav_grid(self.truth)
        if grid is not None:
            try:
                path = grid.path((start.x, start.y), (goal_true.x, goal_true.y))
            except NoPath as err:
                return self._refuse("navigate_to", f"no path to ({goal.x:.2f}, {goal.y:.2f}): "
                                                   f"{err.reason}", goal=goal.as_dict())
            points, straight = path.points, path.straight
        else:
            points = np.array([[start.x, start.y], [goal_true.x, goal_true.y]])
            straight = start.planar_distance(goal_true)
        legs = np.linalg.norm(np.diff(points, axis=0), axis=1)
        dist = float(legs.sum())
        # Turning: from the start heading to the goal's, plus every corner of the path.
        turn = abs(wrap_angle(goal_true.yaw - start.yaw)) + _corner_turns(points, legs)
        # Driving off a dock backs off it first (and charging stops).
        off_dock = self.undock_time if self.battery.docked is not None else 0.0
        self.battery.docked = None
        drive = dist / self.speed + turn / self.turn_speed
        duration = off_dock + drive
        cum = np.concatenate([[0.0], np.cumsum(legs)])

        def at(f: float) -> None:
            g = 0.0 if duration <= 0 else max(f * duration - off_dock, 0.0) / max(drive, 1e-9)
            self._true = _along(points, cum, start, goal_true, min(max(g, 0.0), 1.0))

        act = TimedAction("navigate_to", self.clock, duration, on_done=self._believed,
                          on_progress=at, on_cancel=at)
        return self._start("base", act, goal=goal.as_dict(), path_m=round(dist, 3),
                           straight_m=round(straight, 3))

    # -- sensing ---------------------------------------------------------------------------
    def capture(self) -> Frame:
        return self.capture_job()()

    def capture_job(self) -> Callable[[], Frame]:
        """A capture in two halves: this call takes the robot's state at this instant (poses,
        head, the scene); the function it returns renders the frame from that alone, so a
        caller serving the robot from several threads (hearth.robot.zenoh_sim) holds its lock
        for the first half only, not for the rendering."""
        self._poll()
        T_true = camera_pose(self._true, self._pan, self._tilt, self.mount)
        believed = self.base_pose()
        T_bel = camera_pose(believed, self._pan, self._tilt, self.mount)
        draw = render_view
        if self.renderer == "mujoco":
            from hearth.robot.mujoco_render import render_view as draw
        scene, now, pan, tilt, true = (self._current_scene(), self.clock.now(), self._pan,
                                       self._tilt, self._true)
        parking = self._parking_at(believed)

        def render() -> Frame:
            frame = draw(self.truth, self.intrinsics, T_true, self.rng, self.noise,
                         scene=scene, T_world_camera_believed=T_bel, timestamp=now)
            frame.pan, frame.tilt = pan, tilt
            frame.base_pose, frame.base_pose_true = believed, true
            frame.parking = parking
            return frame
        render.timestamp = now          # type: ignore[attr-defined]  (the frame's, known now)
        return render

    def _current_scene(self):
        from hearth.perception.render import Scene
        from hearth.worldmodel.geometry import scene_meshes, small_object_meshes
        held_key = None
        if self.held is not None:
            held_key = (self.held.id, self._true.as_tuple())
        if self.renderer == "mujoco":
            # The held object is not drawn by MuJoCo's scene (it is carried below the camera).
            if self._scene is None or self._dirty:
                from hearth.robot.mujoco_render import MujocoScene
                self._scene, self._dirty = MujocoScene(self.truth), False
            return self._scene
        if self._scene is None or self._dirty or held_key != self._scene_key:
            meshes = scene_meshes(self.truth)
            if self.held is not None:
                meshes += small_object_meshes(self.truth, self.held,
                                              T_world_object=self._true.matrix() @ T_BASE_CARRY)
            self._scene = Scene(meshes)
            self._scene_key, self._dirty = held_key, False
        return self._scene

    # -- arm -------------------------------------------------------------------------------
    def open_articulated(self, part_id: str, handle_id: Optional[str] = None,
                         target_state: Optional[float] = None) -> Action:
        return self._move_part("open_articulated", part_id, handle_id, target_state)

    def close_articulated(self, part_id: str, handle_id: Optional[str] = None,
                          target_state: Optional[float] = None) -> Action:
        return self._move_part("close_articulated", part_id, handle_id, target_state)

    def _move_part(self, name, part_id, handle_id, target) -> Action:
        self._poll()
        busy = self._busy("arm", name)
        if busy:
            return busy
        part = self._node(part_id)
        if not isinstance(part, Part) or part.joint.type == "fixed":
            return self._refuse(name, f"{part_id} is not a door or drawer", part=part_id)
        j = part.joint
        if handle_id is not None and handle_id not in [h.id for h in part.handles]:
            return self._refuse(name, f"{handle_id} is not a handle of {part_id}", part=part_id)
        if target is None:
            target = (j.lower if name == "close_articulated"
                      else (math.radians(90) if j.type == "revolute" else 0.8 * j.upper))
        target = float(target)
        if not (j.lower - 1e-6 <= target <= j.upper + 1e-6):
            return self._refuse(name, f"{part_id}: {target:.3f} is outside the joint's limits "
                                      f"[{j.lower:.3f}, {j.upper:.3f}]", part=part_id)
        where = handle_id or (part.handles[0].id if part.handles else part_id)
        far = self._out_of_reach(where)
        if far:
            return self._refuse(name, far, part=part_id)
        start = j.state
        rate = self.joint_speed if j.type == "revolute" else self.drawer_speed
        travel = abs(target - start) / rate
        duration = self.approach_time + travel
        fa = self.approach_time / duration if duration > 0 else 0.0

        def at(f: float) -> None:
            g = 0.0 if f <= fa else (f - fa) / max(1.0 - fa, 1e-9)
            value = start + (target - start) * min(g, 1.0)
            if abs(value - part.joint.state) > 1e-9:
                self.truth.set_joint_state(part_id, value, source="simulator")

        fail = f"{part_id} is locked" if part_id in self.locked and target > start else None
        act = TimedAction(name, self.clock, duration, on_done=lambda: target,
                          on_progress=None if fail else at, on_cancel=None if fail else at,
                          fail=fail, fail_at=fa)
        return self._start("arm", act, part=part_id, handle=handle_id, target=target)

    def turn_knob(self, knob_id: str, angle: float) -> Action:
        self._poll()
        busy = self._busy("arm", "turn_knob")
        if busy:
            return busy
        knob = self._node(knob_id)
        if getattr(knob, "kind", "") != "Knob":
            return self._refuse("turn_knob", f"{knob_id} is not a knob", knob=knob_id)
        far = self._out_of_reach(knob_id)
        if far:
            return self._refuse("turn_knob", far, knob=knob_id)
        angle = float(angle)
        start = knob.angle
        duration = self.approach_time + abs(angle - start) / self.joint_speed
        fa = self.approach_time / duration
        state = min(knob.states, key=lambda s: abs(wrap_angle(s.angle - angle))).name

        def done():
            self.truth.set_knob_state(knob_id, state, angle=angle, source="simulator")
            return state

        fail = f"{knob_id} is stuck" if knob_id in self.stuck_knobs else None
        act = TimedAction("turn_knob", self.clock, duration, on_done=done, fail=fail, fail_at=fa)
        return self._start("arm", act, knob=knob_id, angle=angle)

    def grasp(self, object_id: str, pose=None) -> Action:
        self._poll()
        busy = self._busy("arm", "grasp")
        if busy:
            return busy
        if self.held is not None:
            return self._refuse("grasp", f"already holding {self.held.id}", object=object_id)
        obj = self._node(object_id)
        reached = None
        if pose is not None:
            p = pose.position if isinstance(pose, Pose) else np.asarray(pose, float)[:3]
            reached = self._physical(np.r_[p, 1.0])[:3]
        if not isinstance(obj, SmallObject):
            if obj is None and reached is not None:
                # not in the home at all (a false detection of an absent object): the arm
                # goes to the pose and the gripper closes on nothing there
                far = self._out_of_reach(None, point=reached)
                if far:
                    return self._refuse("grasp", far, object=object_id)
                return self._timed_failure("grasp", f"{EMPTY_GRASP} at ({p[0]:.2f}, "
                                           f"{p[1]:.2f}, {p[2]:.2f})", object=object_id)
            return self._refuse("grasp", f"{object_id} is not a small object here",
                                object=object_id)
        # the arm goes where it is told: the reach is checked at that point (a false
        # detection far from the object is a grasp that closes on nothing, not "out of reach")
        far = self._out_of_reach(object_id, point=reached)
        if far:
            return self._refuse("grasp", far, object=object_id)
        if reached is not None:
            off = float(np.linalg.norm(self.truth.T_world(object_id)[:3, 3] - reached))
            if off > self.grasp_tolerance:
                return self._timed_failure("grasp", f"{EMPTY_GRASP} at "
                                           f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})",
                                           object=object_id)
        closed = self._closed_container(obj)
        if closed:
            return self._timed_failure("grasp", f"{object_id} is behind the closed {closed}",
                                       object=object_id)

        def done():
            if object_id not in self.truth:
                raise RobotError(f"{object_id} is gone")
            held = self.truth.get(object_id)
            self.truth.remove_small_object(object_id, source="simulator")
            self.held = held
            self._dirty = True
            return object_id

        act = TimedAction("grasp", self.clock, self.approach_time * 2, on_done=done)
        return self._start("arm", act, object=object_id)

    def place(self, parent_id: str, pose, relation: str = "on") -> Action:
        self._poll()
        busy = self._busy("arm", "place")
        if busy:
            return busy
        if self.held is None:
            return self._refuse("place", "not holding anything", parent=parent_id)
        parent = self._node(parent_id)
        if not isinstance(parent, LargeObject):
            return self._refuse("place", f"{parent_id} is not a large object", parent=parent_id)
        T_world = self._physical(pose.matrix() if isinstance(pose, Pose)
                                 else np.asarray(pose, float))
        far = self._out_of_reach(None, point=T_world[:3, 3])
        if far:
            return self._refuse("place", far, parent=parent_id)
        obj = self.held

        def done():
            obj.pose = Pose.from_matrix(np.linalg.inv(self.truth.T_world(parent_id)) @ T_world)
            obj.relation = relation
            self.truth.add_small_object(obj, parent_id, source="simulator")
            self.held = None
            self._dirty = True
            return obj.id

        act = TimedAction("place", self.clock, self.approach_time * 2, on_done=done)
        return self._start("arm", act, parent=parent_id, object=obj.id)

    def hand_over(self) -> Action:
        self._poll()
        busy = self._busy("arm", "hand_over")
        if busy:
            return busy
        if self.held is None:
            return self._refuse("hand_over", "not holding anything")
        obj = self.held

        def done():
            # The user puts it down on the surface nearest the robot (the belief's HandOver
            # skill assumes the same, World.handover_spot); with none near, they keep it.
            self.handed_over.append(obj.id)
            spot = self.truth.handover_spot(self._true.x, self._true.y)
            if spot is not None:
                obj.pose, obj.relation = spot[1], spot[2]
                self.truth.add_small_object(obj, spot[0], source="simulator")
            self.held = None
            self._dirty = True
            return obj.id

        act = TimedAction("hand_over", self.clock, self.approach_time * 1.5, on_done=done)
        return self._start("arm", act, object=obj.id)

    # -- battery and charger ---------------------------------------------------------------
    def battery_state(self) -> BatteryState:
        """The battery now (level 0..1, charging, docked). Safe from any thread: it only
        integrates the battery (under a lock), never polls or changes the actions."""
        self._drain(self.clock.now())
        return self.battery.state()

    def dock(self) -> Action:
        """Back onto the charger whose dock pose the robot stands at (within
        ``DOCK_TOLERANCE``); charging starts when it is docked. Result: the charger's id."""
        self._poll()
        busy = self._busy("base", "dock")
        if busy:
            return busy
        if self.battery.docked is not None:
            return DoneAction("dock", result=self.battery.docked)
        charger, far = self._charger_at(self._true)
        if charger is None:
            return self._refuse("dock", far)

        def done():
            self._settle()
            self.battery.docked = charger
            return charger

        act = TimedAction("dock", self.clock, self.dock_time, on_done=done)
        return self._start("base", act, charger=charger)

    def undock(self) -> Action:
        """Drive off the charger (charging stops at once); done at once when not docked."""
        self._poll()
        busy = self._busy("base", "undock")
        if busy:
            return busy
        if self.battery.docked is None:
            return DoneAction("undock")
        charger, self.battery.docked = self.battery.docked, None
        act = TimedAction("undock", self.clock, self.undock_time)
        return self._start("base", act, charger=charger)

    def look_for_person(self) -> Action:
        """The simulated person detector (no person is drawn: rendering people is not part
        of this simulator): after a ``LOOK_FOR_PERSON_S`` look around, succeeds with the
        room id when the user is in the room the robot truly stands in, fails otherwise."""
        self._poll()
        room = room_at(self.truth, self._true.x, self._true.y, margin=0.05)
        here = room.id if room is not None else None
        user = self.person_room
        fail = None if (here is not None and user == here) else (
            f"no one in the {room.name or room.id}" if room is not None else "no one here")
        act = TimedAction("look_for_person", self.clock, self.LOOK_FOR_PERSON_S,
                          on_done=lambda: here, fail=fail)
        return self._start("head", act, room=here)

    def _charger_at(self, pose: Pose) -> tuple[Optional[str], str]:
        best = None
        for c in self.truth.chargers():
            d = self.truth.dock_pose(c.id)
            dist = d.planar_distance(pose)
            if dist <= self.DOCK_TOLERANCE[0] and abs(d.yaw_difference(pose)) <= self.DOCK_TOLERANCE[1]:
                return c.id, ""
            if best is None or dist < best[0]:
                best = (dist, c.id)
        if best is None:
            return None, "there is no charger in this home"
        return None, f"not at a charger's dock ({best[1]}'s is {best[0]:.2f} m away)"

    def _flat(self, name: str) -> Optional[Action]:
        if self.battery.level <= 0.0:
            return self._refuse(name, "the battery is flat")
        return None

    def _settle(self) -> None:
        """Integrate the battery up to now (before its docked state changes)."""
        self._drain(self.clock.now())

    def _drain(self, now: float) -> None:
        with self._battery_lock:
            self._drain_locked(now)

    def _drain_locked(self, now: float) -> None:
        last = self.battery.t
        if now <= last:
            return
        busy = {"base": 0.0, "arm": 0.0}
        for res, act in list(self._actions):
            start = getattr(act, "start", None)
            if start is None or res not in busy:
                continue
            end = start + act.duration
            stopped = getattr(act, "stopped_at", None)
            if stopped is not None:
                end = min(end, stopped)
            busy[res] += max(min(end, now) - max(start, last), 0.0)
        self.battery.update(now, driving_s=busy["base"], arm_s=busy["arm"])

    # -- speech and safety -------------------------------------------------------------------
    def stop(self) -> None:
        self.stops += 1
        for _, act in list(self._actions):
            act.cancel()
        self._log("stop")

    # -- helpers -----------------------------------------------------------------------------
    def _poll(self) -> None:
        self._drain(self.clock.now())
        still = []
        for res, act in self._actions:
            if act.status() == "running":
                still.append((res, act))
        self._actions = still

    def _busy(self, resource: str, name: str) -> Optional[Action]:
        for res, act in self._actions:
            if res == resource and act.status() == "running":
                return self._refuse(name, f"the {resource} is busy with {act.name}")
        return None

    def _start(self, resource: str, act: Action, **info) -> Action:
        self._actions.append((resource, act))
        self._log(act.name, **info)
        return act

    def _refuse(self, name: str, reason: str, **info) -> Action:
        self._log(name, refused=reason, **info)
        return FailedAction(name, reason)

    def _timed_failure(self, name: str, reason: str, **info) -> Action:
        act = TimedAction(name, self.clock, self.approach_time * 2, fail=reason)
        return self._start("arm", act, **info)

    def _node(self, node_id: str):
        return self.truth.get(node_id) if node_id in self.truth else None

    def _physical(self, T: np.ndarray) -> np.ndarray:
        """Where a pose (4 x 4) or point (4,) the robot gives in its believed world frame lies
        in truth: the arm moves relative to the base, placed by the believed pose."""
        return self._true.matrix() @ np.linalg.inv(self._believed().matrix()) @ T

    def _out_of_reach(self, node_id: Optional[str], point=None) -> Optional[str]:
        p = self.truth.T_world(node_id)[:3, 3] if point is None else np.asarray(point, float)
        d = math.hypot(p[0] - self._true.x, p[1] - self._true.y)
        if d > self.reach:
            what = node_id or f"({p[0]:.2f}, {p[1]:.2f})"
            return f"{what} is out of reach ({d:.2f} m from the base, reach {self.reach:.2f} m)"
        return None

    def _closed_container(self, obj: SmallObject) -> Optional[str]:
        """What keeps the hand from an object (its id), if anything: the drawer it is in
        while that is not open; a sliding door that covers it; a container whose doors are
        all closed."""
        if obj.relation != "in":
            return None
        parent = self.truth.parent(obj.id)
        if not isinstance(parent, LargeArticulatedObject):
            return None
        from hearth.worldmodel.containers import covering_door, is_open
        if obj.part:
            part = self.truth.get(obj.part)
            return None if is_open(part) else part.id
        cover = covering_door(self.truth, obj.id)
        if cover is not None:
            return cover
        movable = [p for p in _all_parts(parent.parts) if p.joint.type != "fixed" and not p.track]
        if movable and all(abs(p.joint.state - p.joint.lower) < 0.05 for p in movable):
            return parent.id
        return None

    def _inside_home(self, pose: Pose) -> bool:
        if not any(r.bounds is not None for r in self.truth.rooms):
            return True
        return room_at(self.truth, pose.x, pose.y, margin=0.05) is not None

    def _parking_at(self, believed: Pose, tol: float = 0.05) -> Optional[str]:
        """The parking position id (of the truth's map) the believed pose is at, if any."""
        for obj in self.truth.large_objects():
            for p, pose in self.truth.parking_positions(obj.id):
                if (pose.planar_distance(believed) < tol
                        and abs(pose.yaw_difference(believed)) < math.radians(5)):
                    return p.id
        return None


def _all_parts(parts):
    for p in parts:
        yield p
        yield from _all_parts(p.parts)


def _planar(T) -> Pose:
    return as_base_pose(T)


def _corner_turns(points: np.ndarray, legs: np.ndarray) -> float:
    """Sum of the heading changes (rad) at a path's corners (legs under 5 cm, the moves on
    and off the grid, do not count)."""
    d = np.diff(points, axis=0)[legs > 0.05]
    if len(d) < 2:
        return 0.0
    h = np.arctan2(d[:, 1], d[:, 0])
    return float(sum(abs(wrap_angle(b - a)) for a, b in zip(h[:-1], h[1:])))


def _along(points: np.ndarray, cum: np.ndarray, a: Pose, b: Pose, f: float) -> Pose:
    """The base pose a fraction ``f`` of the way along a path (by length); the heading turns
    evenly from ``a``'s to ``b``'s."""
    yaw = wrap_angle(a.yaw + wrap_angle(b.yaw - a.yaw) * f)
    if f >= 1.0:
        return Pose.planar(b.x, b.y, b.yaw)
    total = cum[-1]
    if total <= 0:
        return Pose.planar(a.x, a.y, yaw)
    s = f * total
    i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(points) - 2))
    seg = cum[i + 1] - cum[i]
    g = 0.0 if seg <= 0 else (s - cum[i]) / seg
    x, y = points[i] + g * (points[i + 1] - points[i])
    return Pose.planar(float(x), float(y), yaw)


def _first_parking(world) -> Pose:
    for obj in world.large_objects():
        pp = world.parking_positions(obj.id)
        if pp:
            return pp[0][1]
    return Pose()
