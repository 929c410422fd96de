"""Hearth's simulated robot as a ROS 2 robot on Zenoh (rmw_zenoh's conventions, no ROS needed):
the other side of ``hearth.robot.ros2_live`` for tests and for trying a live link without a
robot (``hearth robot-sim``; docs/ros2-foxglove.md, "A live robot").

What it serves, under the names of the topic mapping (``hearth.robot.rosbag.TopicMap``):

- ``/tf`` (``odom -> base_link``: the believed base pose; ``base_link -> camera frame``: the
  camera on the pan/tilt head) at ``tf_rate`` Hz of robot time, and at every image's stamp;
  ``/tf_static`` (``map -> odom``, identity), latched;
- colour (``rgb8``) and depth (``16UC1`` millimetres, registered to colour) as
  ``sensor_msgs/Image`` and the colour ``CameraInfo``, rendered at ``camera_rate`` Hz;
- ``/joint_states`` (the head joints), ``/battery_state`` (``sensor_msgs/BatteryState``);
- Nav2's ``NavigateToPose`` action (goal in ``map``, feedback with the current pose and the
  distance remaining, cancel), and Hearth's ``RobotTask`` action for the arm and the charger;
- subscriptions to the head command (``trajectory_msgs/JointTrajectory``), ``/initialpose``
  (``geometry_msgs/PoseWithCovarianceStamped``, as AMCL takes it) and the speech topic.

Time: the robot runs on a ``ScaledClock`` (``rate`` times real time, so that a test drives
across a kitchen in a second) whose stamps start at ``SIM_EPOCH``.
"""
from __future__ import annotations

import json
import math
import threading
import time
from typing import Any, Optional

import numpy as np

from hearth.robot.adapter import DoneAction, FailedAction
from hearth.robot.errors import RobotError
from hearth.robot.rosbag import CAMERA_FRAME, WRITE, TopicMap, load_topic_map
from hearth.robot.zenoh_ros import (ABORTED, ACCEPTED, CANCEL_SRV, CANCELED, EXECUTING,
                                    NAV2_ACTION, SUCCEEDED, TASK_ACTION, TASKS, TERMINAL, Node,
                                    action_names, stamp)
from hearth.worldmodel.pose import Pose

#: The epoch of simulated time (2023-11-14 22:13:20 UTC): SimClock's, so that a simulated
#: run's bag, its Foxglove log and a simulated live robot share one time base.
SIM_EPOCH = 1_700_000_000.0


class ScaledClock:
    """Robot time running ``rate`` times real time from ``start``; ``wall()`` is
    ``epoch + now()``. Sleeping sleeps real time (``seconds / rate``)."""

    simulated = False

    def __init__(self, rate: float = 1.0, epoch: float = SIM_EPOCH, start: float = 0.0):
        if not (rate > 0 and math.isfinite(rate)):
            raise ValueError("a clock's rate is a positive number")
        self.rate, self.epoch = float(rate), float(epoch)
        self._t0 = time.monotonic() - start / self.rate

    def now(self) -> float:
        return (time.monotonic() - self._t0) * self.rate

    def wall(self) -> float:
        return self.epoch + self.now()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds / self.rate)

    advance = sleep


def _quat(R) -> list[float]:
    from scipy.spatial.transform import Rotation
    return [float(v) for v in Rotation.from_matrix(np.asarray(R)[:3, :3]).as_quat()]


def _T_of(pose_msg) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    p, o = pose_msg.position, pose_msg.orientation
    T = np.eye(4)
    q = np.array([o.x, o.y, o.z, o.w], dtype=float)
    T[:3, :3] = Rotation.from_quat(q if np.linalg.norm(q) > 1e-9 else [0, 0, 0, 1]).as_matrix()
    T[:3, 3] = [p.x, p.y, p.z]
    return T


def _describe(goal) -> str:
    """A goal in a few words: a NavigateToPose's x, y, yaw; a RobotTask's task and target."""
    if hasattr(goal, "task"):
        return " ".join(str(v) for v in (goal.task, goal.target) if str(v))
    p, q = goal.pose.pose.position, goal.pose.pose.orientation
    yaw = math.degrees(2 * math.atan2(q.z, q.w))
    return f"to x {p.x:.2f}, y {p.y:.2f}, yaw {yaw:.0f} deg in {goal.pose.header.frame_id}"


class ActionServer:
    """A ROS 2 action server on a Node (the five endpoints of ``action_names``).

    ``start(goal) -> hearth Action``; ``result(action, status) -> the Result message``;
    ``feedback(action) -> the Feedback message or None``. ``poll()`` (from the server's loop)
    moves goals on, publishes feedback and status, and answers waiting get_result calls."""

    def __init__(self, node: Node, name: str, typename: str, start, result, feedback, lock,
                 log=None):
        self.node, self.typename, self._start = node, typename, start
        self._log = log or (lambda text: None)
        self.action = name
        self._result, self._feedback, self._lock = result, feedback, lock
        n = self.names = action_names(name)
        t = node.types
        self.t = t
        self.goals: dict[bytes, dict] = {}
        self.order: list[bytes] = []
        self._pub_feedback = node.publisher(n["feedback"], typename + "_FeedbackMessage")
        self._pub_status = node.publisher(n["status"], "action_msgs/msg/GoalStatusArray")
        node.service(n["send_goal"], typename + "_SendGoal", self._send_goal)
        node.service(n["cancel_goal"], CANCEL_SRV[0], self._cancel_goal)
        node.service(n["get_result"], typename + "_GetResult", self._get_result)

    def _send_goal(self, req, reply) -> None:
        gid = bytes(np.asarray(req.goal_id.uuid, dtype=np.uint8))
        with self._lock:
            try:
                act = self._start(req.goal)
            except RobotError as err:
                act = FailedAction(self.typename.rsplit("/", 1)[-1], str(err))
            now = time.time_ns()
            self.goals[gid] = dict(action=act, status=ACCEPTED, stamp=now, waiting=[],
                                   result=None)
            self.order.append(gid)
            del self.order[:-50]
            for old in list(self.goals):
                if old not in self.order:
                    del self.goals[old]
        t = self.t
        reply(t[self.typename + "_SendGoal_Response"](accepted=True, stamp=stamp(now, t)))
        self._log(f"{self.action} goal {gid.hex()[:8]}: accepted ({_describe(req.goal)})")
        self.poll()

    def _goal_info(self, gid: bytes, g: dict):
        t = self.t
        return t["action_msgs/msg/GoalInfo"](
            goal_id=t["unique_identifier_msgs/msg/UUID"](uuid=np.frombuffer(gid, np.uint8).copy()),
            stamp=stamp(g["stamp"], t))

    def _cancel_goal(self, req, reply) -> None:
        t = self.t
        target = bytes(np.asarray(req.goal_info.goal_id.uuid, dtype=np.uint8))
        everything = not any(target) and req.goal_info.stamp.sec == 0 \
            and req.goal_info.stamp.nanosec == 0
        canceling = []
        with self._lock:
            for gid, g in self.goals.items():
                if (everything or gid == target) and g["status"] not in TERMINAL:
                    g["action"].cancel()
                    canceling.append(self._goal_info(gid, g))
        code = 0 if canceling else (2 if not everything and target not in self.goals else 3)
        reply(t["action_msgs/srv/CancelGoal_Response"](return_code=code,
                                                       goals_canceling=canceling))
        self.poll()

    def _get_result(self, req, reply) -> None:
        gid = bytes(np.asarray(req.goal_id.uuid, dtype=np.uint8))
        with self._lock:
            g = self.goals.get(gid)
            if g is not None and g["status"] not in TERMINAL:
                g["waiting"].append(reply)
                return
        t = self.t
        if g is None:
            res = t[self.typename + "_GetResult_Response"](
                status=0, result=self._result(None, ABORTED))
        else:
            res = t[self.typename + "_GetResult_Response"](status=g["status"], result=g["result"])
        reply(res)

    def poll(self) -> None:
        t = self.t
        changed, answers, feedback = False, [], []
        with self._lock:
            for gid, g in self.goals.items():
                if g["status"] in TERMINAL:
                    continue
                s = g["action"].status()
                new = {"running": EXECUTING, "succeeded": SUCCEEDED, "cancelled": CANCELED,
                       "failed": ABORTED}[s]
                if new == EXECUTING:
                    fb = self._feedback(g["action"])
                    if fb is not None:
                        feedback.append(t[self.typename + "_FeedbackMessage"](
                            goal_id=self._goal_info(gid, g).goal_id, feedback=fb))
                if new != g["status"]:
                    g["status"] = new
                    changed = True
                    if new in TERMINAL:
                        self._log(f"{self.action} goal {gid.hex()[:8]}: "
                                  f"{ {SUCCEEDED: 'succeeded', CANCELED: 'canceled'}.get(new, 'aborted')}"
                                  + (f" ({g['action'].reason})" if new == ABORTED else ""))
                        g["result"] = self._result(g["action"], new)
                        res = t[self.typename + "_GetResult_Response"](status=new,
                                                                      result=g["result"])
                        answers += [(r, res) for r in g["waiting"]]
                        g["waiting"] = []
            status = t["action_msgs/msg/GoalStatusArray"](status_list=[
                t["action_msgs/msg/GoalStatus"](goal_info=self._goal_info(gid, self.goals[gid]),
                                                status=self.goals[gid]["status"])
                for gid in self.order if gid in self.goals])
        for fb in feedback:
            self._pub_feedback(fb)
        if changed:
            self._pub_status(status)
        for reply, res in answers:
            reply(res)

    def publish_status(self) -> None:
        with self._lock:
            t = self.t
            status = t["action_msgs/msg/GoalStatusArray"](status_list=[
                t["action_msgs/msg/GoalStatus"](goal_info=self._goal_info(gid, self.goals[gid]),
                                                status=self.goals[gid]["status"])
                for gid in self.order if gid in self.goals])
        self._pub_status(status)


class SimRobotServer:
    """Serve a ``SimulatedRobot`` (on a ``ScaledClock``) as a ROS 2 robot on a Zenoh session.

    ``topics``: the mapping (a TopicMap, dict, file or ``key=value,...``); images go to the
    mapping's colour/depth/camera_info topics, or to the names Hearth's bags use.
    ``close()`` stops its threads and undeclares everything (tokens vanish: the adapter on
    the other side sees the link go)."""

    def __init__(self, robot, session, topics: Any = None, camera_rate: float = 5.0,
                 tf_rate: float = 20.0, node_name: str = "hearth_sim_robot",
                 domain: Optional[int] = None, log=None):
        self.robot = robot
        self.clock = robot.clock
        self.m = m = load_topic_map(topics) if not isinstance(topics, TopicMap) else topics
        self.node = node = Node(session, node_name, domain=domain)
        self.t = node.types
        self.lock = threading.RLock()
        self.camera_frame = m.camera_frame or CAMERA_FRAME
        self.topic = dict(color=m.color or WRITE["color"], depth=m.depth or WRITE["depth"],
                          camera_info=m.camera_info or WRITE["camera_info"])
        self.camera_period = 1.0 / camera_rate
        self.tf_period = 1.0 / tf_rate          # robot seconds
        self.frames_published = 0
        self.tf_stamps: list[int] = []            # ns of every /tf message (tests measure rates)
        self.head_commands = 0
        self._pub = dict(
            tf=node.publisher(m.tf, "tf2_msgs/msg/TFMessage"),
            tf_static=node.publisher(m.tf_static, "tf2_msgs/msg/TFMessage", latched=True),
            color=node.publisher(self.topic["color"], "sensor_msgs/msg/Image"),
            depth=node.publisher(self.topic["depth"], "sensor_msgs/msg/Image"),
            camera_info=node.publisher(self.topic["camera_info"], "sensor_msgs/msg/CameraInfo"),
            joints=node.publisher(m.joint_states, "sensor_msgs/msg/JointState"),
            battery=node.publisher(m.battery, "sensor_msgs/msg/BatteryState"))
        node.subscribe(m.head_command, "trajectory_msgs/msg/JointTrajectory", self._on_head)
        node.subscribe(m.initial_pose, "geometry_msgs/msg/PoseWithCovarianceStamped",
                       self._on_initial_pose)
        node.subscribe(m.say, "std_msgs/msg/String", self._on_say)
        self.nav = ActionServer(node, m.navigate_action, NAV2_ACTION[0], self._navigate,
                                self._nav_result, self._nav_feedback, self.lock, log=log)
        self.task = ActionServer(node, m.task_action, TASK_ACTION[0], self._task,
                                 self._task_result, self._task_feedback, self.lock, log=log)
        self._stop = threading.Event()
        self.robot.capture()        # the first frame builds the scene (seconds): not while live
        self._camera_errors = 0
        self._pub["tf_static"](self.t["tf2_msgs/msg/TFMessage"](transforms=[
            self._transform(self._ns(), m.map_frame, m.odom_frame, np.eye(4))]))
        self._threads = [threading.Thread(target=self._loop, name="sim-robot-tf", daemon=True),
                         threading.Thread(target=self._camera, name="sim-robot-camera",
                                          daemon=True)]
        for th in self._threads:
            th.start()

    # -- time and messages
    def _ns(self) -> int:
        return int(round(self.clock.wall() * 1e9))

    def _stamp_of(self, clock_s: float) -> int:
        """ns since the UNIX epoch of a time of the robot's clock."""
        return int(round((self.clock.epoch + clock_s) * 1e9)) if hasattr(self.clock, "epoch") \
            else self._ns()

    def _header(self, ns: int, frame: str):
        return self.t["std_msgs/msg/Header"](stamp=stamp(ns, self.t), frame_id=frame)

    def _transform(self, ns: int, parent: str, child: str, T):
        t = self.t
        T = np.asarray(T, dtype=float)
        return t["geometry_msgs/msg/TransformStamped"](
            header=self._header(ns, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](*map(float, T[:3, 3])),
                rotation=t["geometry_msgs/msg/Quaternion"](*_quat(T))))

    def _pose_stamped(self, ns: int, pose: Pose):
        t = self.t
        T = pose.matrix()
        return t["geometry_msgs/msg/PoseStamped"](
            header=self._header(ns, self.m.map_frame), pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](*map(float, T[:3, 3])),
                orientation=t["geometry_msgs/msg/Quaternion"](*_quat(T))))

    def _publish_tf(self, ns: int, base: Pose, T_base_camera) -> None:
        m = self.m
        self._pub["tf"](self.t["tf2_msgs/msg/TFMessage"](transforms=[
            self._transform(ns, m.odom_frame, m.base_frame, base.matrix()),
            self._transform(ns, m.base_frame, self.camera_frame, T_base_camera)]))
        self.tf_stamps.append(ns)
        del self.tf_stamps[:-10000]

    def _T_base_camera(self) -> np.ndarray:
        from hearth.robot.sim import camera_pose
        pan, tilt = self.robot.head()
        return camera_pose(Pose(), pan, tilt, self.robot.mount)

    # -- loops
    def _loop(self) -> None:
        t = self.t
        last_battery = -1e9
        due = self.clock.now()
        while not self._stop.is_set():
            with self.lock:
                ns = self._ns()
                base = self.robot.base_pose()
                T_bc = self._T_base_camera()
                pan, tilt = self.robot.head()
                self._publish_tf(ns, base, T_bc)
                self._pub["joints"](t["sensor_msgs/msg/JointState"](
                    header=self._header(ns, ""), name=[self.m.head_pan_joint,
                                                       self.m.head_tilt_joint],
                    position=np.array([pan, tilt]), velocity=np.zeros(0), effort=np.zeros(0)))
                if ns - last_battery > 1e9:
                    last_battery = ns
                    b = self.robot.battery_state()
                    self._pub["battery"](self._battery_msg(ns, b))
            self.nav.poll()
            self.task.poll()
            # on a schedule of robot time (not a sleep after the work): a late message is
            # followed by the next one sooner, a stall is not made up for with a burst
            due = max(due + self.tf_period, self.clock.now())
            self.clock.sleep(due - self.clock.now())

    def _battery_msg(self, ns: int, b):
        t = self.t
        BS = t["sensor_msgs/msg/BatteryState"]
        nan = float("nan")
        return BS(header=self._header(ns, self.m.base_frame), voltage=nan, temperature=nan,
                  current=nan, charge=nan, capacity=nan, design_capacity=nan,
                  percentage=float(b.level),
                  power_supply_status=1 if b.charging else 2,      # CHARGING, DISCHARGING
                  power_supply_health=0, power_supply_technology=0, present=True,
                  cell_voltage=np.zeros(0, np.float32), cell_temperature=np.zeros(0, np.float32),
                  location="docked:" + (b.charger or "") if b.docked else "",
                  serial_number="")

    def _camera(self) -> None:
        while not self._stop.is_set():
            t0 = time.monotonic()
            try:
                self.publish_frame()
            except Exception as err:                   # noqa: BLE001 (keep the camera up)
                if self._stop.is_set():
                    return
                self._camera_errors += 1
                if self._camera_errors <= 3:
                    print(f"hearth sim robot: camera: {err}", flush=True)
            self._stop.wait(max(self.camera_period - (time.monotonic() - t0), 0.01))

    def publish_frame(self) -> None:
        """Render one RGB-D frame and publish it (tf at its stamp first)."""
        t = self.t
        job = getattr(self.robot, "capture_job", None)
        if job is not None and getattr(self.robot, "renderer", "") != "mujoco":
            with self.lock:                     # the state now, and tf at its stamp (in order)
                render = job()
                ns = self._stamp_of(render.timestamp)
                self._publish_tf(ns, self.robot.base_pose(), self._T_base_camera())
            frame = render()                    # tf goes on while it renders
        else:
            with self.lock:                     # MuJoCo reads the truth while it draws
                frame = self.robot.capture()
                ns = self._stamp_of(frame.timestamp)
                base = frame.base_pose
                self._publish_tf(ns, base, np.linalg.inv(base.matrix())
                                 @ np.asarray(frame.T_world_camera))
        mm = np.clip(np.round(np.nan_to_num(frame.depth) * 1000.0), 0, 65535).astype("<u2")
        h, w = mm.shape
        Image = t["sensor_msgs/msg/Image"]
        rgb = np.ascontiguousarray(np.asarray(frame.color, dtype=np.uint8))
        self._pub["color"](Image(header=self._header(ns, self.camera_frame), height=h, width=w,
                                 encoding="rgb8", is_bigendian=0, step=w * 3,
                                 data=rgb.reshape(-1)))
        self._pub["depth"](Image(header=self._header(ns, self.camera_frame), height=h, width=w,
                                 encoding="16UC1", is_bigendian=0, step=w * 2,
                                 data=mm.view(np.uint8).reshape(-1)))
        K = frame.intrinsics
        self._pub["camera_info"](t["sensor_msgs/msg/CameraInfo"](
            header=self._header(ns, self.camera_frame), height=h, width=w,
            distortion_model="plumb_bob", d=np.zeros(5),
            k=np.array([K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1], dtype=float),
            r=np.eye(3).reshape(-1),
            p=np.array([K.fx, 0, K.cx, 0, 0, K.fy, K.cy, 0, 0, 0, 1, 0], dtype=float),
            binning_x=0, binning_y=0,
            roi=t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                      do_rectify=False)))
        self.frames_published += 1

    # -- subscriptions
    def _on_head(self, msg, _ns) -> None:
        names = list(msg.joint_names)
        if not msg.points:
            return
        pos = list(msg.points[-1].positions)
        with self.lock:
            pan, tilt = self.robot.head()
            if self.m.head_pan_joint in names:
                pan = float(pos[names.index(self.m.head_pan_joint)])
            if self.m.head_tilt_joint in names:
                tilt = float(pos[names.index(self.m.head_tilt_joint)])
            self.robot.set_head(pan, tilt)
            self.head_commands += 1

    def _on_initial_pose(self, msg, _ns) -> None:
        with self.lock:
            self.robot.apply_correction(_T_of(msg.pose.pose))

    def _on_say(self, msg, _ns) -> None:
        with self.lock:
            self.robot.say(str(msg.data))

    # -- actions
    def _navigate(self, goal):
        from hearth.robot.adapter import as_base_pose
        target = as_base_pose(_T_of(goal.pose.pose))
        act = self.robot.navigate_to(target)
        act.goal = target
        return act

    def _nav_result(self, act, status):
        t = self.t
        ok = status == SUCCEEDED
        reason = "" if act is None else (act.reason or "")
        return t[NAV2_ACTION[0] + "_Result"](result=t["std_msgs/msg/Empty"](),
                                             error_code=0 if ok else 9000,
                                             error_msg="" if ok else reason)

    def _nav_feedback(self, act):
        t = self.t
        ns = self._ns()
        base = self.robot.base_pose()
        goal = getattr(act, "goal", None)
        return t[NAV2_ACTION[0] + "_Feedback"](
            current_pose=self._pose_stamped(ns, base),
            navigation_time=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
            estimated_time_remaining=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
            number_of_recoveries=0,
            distance_remaining=float(0.0 if goal is None else goal.planar_distance(base)))

    def _task(self, goal):
        task, r = str(goal.task), self.robot
        pose = _T_of(goal.pose.pose)
        args = json.loads(goal.args_json) if goal.args_json else {}
        handle = str(goal.handle) or None
        if task not in TASKS:
            return FailedAction(task or "task", f"unknown task {task!r} (tasks: "
                                                f"{', '.join(TASKS)})")
        if task == "open_articulated":
            return r.open_articulated(str(goal.target), handle, float(goal.value))
        if task == "close_articulated":
            return r.close_articulated(str(goal.target), handle, float(goal.value))
        if task == "turn_knob":
            return r.turn_knob(str(goal.target), float(goal.value))
        if task == "grasp":
            return r.grasp(str(goal.target), Pose.from_matrix(pose))
        if task == "place":
            return r.place(str(goal.target), Pose.from_matrix(pose),
                           **({"relation": args["relation"]} if "relation" in args else {}))
        if task == "hand_over":
            return r.hand_over()
        if task == "dock":
            return r.dock()
        return r.undock() if hasattr(r, "undock") else DoneAction("undock")

    def _task_result(self, act, status):
        res = None if act is None else act.result
        if isinstance(res, Pose):
            res = res.as_dict()
        try:
            text = json.dumps(res)
        except (TypeError, ValueError):
            text = json.dumps(repr(res))
        return self.t[TASK_ACTION[0] + "_Result"](
            success=status == SUCCEEDED, message="" if act is None else (act.reason or ""),
            result_json=text)

    def _task_feedback(self, act):
        return self.t[TASK_ACTION[0] + "_Feedback"](progress=float(act.progress),
                                                    state=act.status())

    def close(self) -> None:
        """Stop serving: the threads end, the robot stops what it was doing (as a robot whose
        software ends does), every liveliness token goes."""
        self._stop.set()
        for th in self._threads:
            th.join(timeout=5)
        with self.lock:
            stop = getattr(self.robot, "stop", None)
            if callable(stop):
                stop()
        self.node.close()


def serve_simulated(session, world=None, scenario: Optional[str] = None, topics: Any = None,
                    rate: float = 1.0, camera_rate: float = 5.0, tf_rate: float = 20.0,
                    domain: Optional[int] = None, log=None, **kw) -> SimRobotServer:
    """A SimulatedRobot (on a scenario or a copy of ``world``) on a ``ScaledClock`` served on
    ``session``. Keywords go to SimulatedRobot."""
    from hearth.robot import create_adapter
    clock = ScaledClock(rate)
    robot = create_adapter(world=world, scenario=scenario, clock=clock, **kw)
    return SimRobotServer(robot, session, topics=topics, camera_rate=camera_rate,
                          tf_rate=tf_rate, domain=domain, log=log)
