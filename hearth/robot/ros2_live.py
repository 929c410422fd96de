"""A live ROS 2 robot through Zenoh, with no ROS installation on Hearth's side
(docs/ros2-foxglove.md, "A live robot"; docs/robot-adapter.md).

``Ros2Robot`` is a robot adapter (hearth/robot/adapter.py) speaking to a robot whose ROS 2
runs on ``rmw_zenoh_cpp`` (``RMW_IMPLEMENTATION=rmw_zenoh_cpp``), through a Zenoh router
(rmw_zenoh's ``rmw_zenohd``, default ``tcp/localhost:7447``). Names come from the topic
mapping bag replay uses (``hearth.robot.rosbag.TopicMap``):

- colour, depth and camera_info (``sensor_msgs/Image`` rgb8/bgr8 and 16UC1/32FC1, or
  ``CompressedImage``), the first of the bag defaults that publishes when the mapping names
  none; distortion undone with OpenCV as for bags; depth must be registered to colour;
- ``/tf`` and ``/tf_static``: the believed base pose is ``map -> base_frame``, a frame's
  camera pose ``map -> camera frame`` at the image's stamp (interpolated, as for bags);
- driving: Nav2's ``NavigateToPose`` (``navigate_action``), cancelled on halt;
- the head: ``trajectory_msgs/JointTrajectory`` on ``head_command`` for the two joints
  ``head_pan_joint``/``head_tilt_joint``, done when ``joint_states`` shows them there;
- the arm and the charger: Hearth's ``RobotTask`` action (``task_action``), see
  ``hearth.robot.zenoh_ros.TASK_ACTION``;
- a localisation fix goes to ``initial_pose`` (``PoseWithCovarianceStamped``, as AMCL takes
  it), speech to ``say`` (``std_msgs/String``), the battery from ``battery``.

A lost link (the robot's action server's liveliness token gone, or no tf for
``link_timeout`` seconds) fails every running action and every later request with one line
saying so.
"""
from __future__ import annotations

import json
import math
import threading
import time
import uuid
from collections import deque
from typing import Any, Optional

import numpy as np

from hearth.robot.adapter import Action, DoneAction, FailedAction, as_base_pose
from hearth.robot.errors import RobotError
from hearth.robot.rosbag import (COLOR_TOPICS, DEPTH_TOPICS, INFO_TOPICS, MAX_DEPTH_M, TfBuffer,
                                 TopicMap, _Camera, _undistort, decode_compressed,
                                 load_topic_map)
from hearth.robot.sim import Frame, HEAD, pan_tilt_to
from hearth.robot.zenoh_ros import (ADMIN_SPACE, CANCEL_SRV, CANCELED, DEFAULT_ENDPOINT,
                                    NAV2_ACTION, SUCCEEDED, TASK_ACTION, TERMINAL, Node,
                                    action_names, mangle, open_session, stamp, stamp_ns,
                                    type_hash)
from hearth.worldmodel.pose import Pose

LOST = "lost the link to the robot"


def _close_at_exit(robot: "Ros2Robot") -> None:
    """Close ``robot`` when the interpreter exits, even if its user forgot: zenoh-python runs
    callbacks on Python threads that end only when their subscriber goes, and the interpreter
    joins such threads *before* ``atexit`` handlers run, so a forgotten session would hang the
    exit. ``threading._register_atexit`` (what concurrent.futures uses) runs before that join;
    ``atexit`` is the fallback."""
    import weakref
    ref = weakref.ref(robot)

    def close() -> None:
        r = ref()
        if r is not None:
            r.close()
    register = getattr(threading, "_register_atexit", None)
    try:
        if register is None:
            raise RuntimeError
        register(close)
    except RuntimeError:                               # no such hook, or already shutting down
        import atexit
        atexit.register(close)


class _LiveTf(TfBuffer):
    """tf as it streams in: thread-safe, keeping ``keep_s`` seconds of each moving frame."""

    def __init__(self, tolerance_ns: int, keep_s: float = 30.0):
        super().__init__(tolerance_ns)
        self.lock = threading.RLock()
        self.keep_ns = int(keep_s * 1e9)
        self.latest_ns = 0

    def add_msg(self, msg, static: bool) -> None:
        with self.lock:
            for tr in msg.transforms:
                ns = stamp_ns(tr.header.stamp)
                t, q = tr.transform.translation, tr.transform.rotation
                try:
                    self.add(str(tr.header.frame_id).lstrip("/"), str(tr.child_frame_id).lstrip("/"),
                             ns, [t.x, t.y, t.z], [q.x, q.y, q.z, q.w], static)
                except Exception:                      # noqa: BLE001 (a bad transform: dropped)
                    continue
                if not static:
                    self.latest_ns = max(self.latest_ns, ns)
                    samples = self._samples[str(tr.child_frame_id).lstrip("/")]
                    if len(samples) > 1 and samples[0][0] < ns - self.keep_ns:
                        samples[:] = [s for s in samples if s[0] >= ns - self.keep_ns]

    def lookup_at(self, target: str, source: str, ns: int) -> np.ndarray:
        with self.lock:
            if target not in self.frames() or source not in self.frames():
                missing = target if target not in self.frames() else source
                raise LookupError(f"no frame {missing} in tf (tf has: "
                                  f"{', '.join(sorted(self.frames())) or 'nothing yet'})")
            if not self.connected(target, source):
                raise LookupError(f"no tf between {target} and {source}: they are in separate "
                                  "trees")
            return self.lookup(target, source, ns)


def _image(msg, depth: bool, topic: str) -> np.ndarray:
    """An Image or CompressedImage message as RGB uint8 or depth float32 metres (0: none)."""
    if not hasattr(msg, "encoding"):
        try:
            return decode_compressed(msg, "depth" if depth else "colour")
        except ValueError as err:
            raise RobotError(f"topic {topic}: {err}") from None
    h, w, step, enc = int(msg.height), int(msg.width), int(msg.step), str(msg.encoding)
    rows = np.asarray(msg.data, dtype=np.uint8).reshape(h, step)
    if not depth:
        if enc not in ("rgb8", "bgr8"):
            raise RobotError(f"topic {topic}: colour encoding {enc!r} is not supported "
                             "(Hearth reads rgb8 or bgr8)")
        rgb = rows[:, :w * 3].reshape(h, w, 3)
        return np.ascontiguousarray(rgb if enc == "rgb8" else rgb[..., ::-1])
    big = bool(msg.is_bigendian)
    if enc == "32FC1":
        z = rows[:, :w * 4].copy().view(">f4" if big else "<f4").reshape(h, w).astype(np.float32)
        z[~np.isfinite(z) | (z < 0) | (z > MAX_DEPTH_M)] = 0
        return z
    if enc not in ("16UC1", "mono16"):
        raise RobotError(f"topic {topic}: depth encoding {enc!r} is not supported (Hearth reads "
                         "depth in 16UC1 or 32FC1)")
    mm = rows[:, :w * 2].copy().view(">u2" if big else "<u2").reshape(h, w)
    return mm.astype(np.float32) * np.float32(0.001)


def _camera(msg) -> _Camera:
    from hearth.perception.camera import Intrinsics
    k = np.asarray(msg.k, dtype=float)
    K = Intrinsics(fx=float(k[0]), fy=float(k[4]), cx=float(k[2]), cy=float(k[5]),
                   width=int(msg.width), height=int(msg.height))
    d = np.asarray(msg.d, dtype=float)
    return _Camera(K, d if d.size and np.abs(d).max() > 1e-9 else None,
                   str(msg.distortion_model))


def _uuid_msg(types, gid: bytes):
    return types["unique_identifier_msgs/msg/UUID"](uuid=np.frombuffer(gid, np.uint8).copy())


class _Link:
    """Whether the robot is there: its action server's liveliness token, and tf arriving."""

    def __init__(self):
        self.lost: Optional[str] = None
        self.tokens: dict[str, str] = {}      # key -> kind of the robot's tokens seen


class GoalAction(Action):
    """A goal of a ROS 2 action on the robot: running until the action server's status says
    it ended (then its result is fetched), failed when the link is lost; ``cancel()`` sends
    ``cancel_goal`` and is cancelled at once (the robot's own status follows)."""

    def __init__(self, robot: "Ros2Robot", name: str, action: str, typename: str, goal,
                 on_result=None):
        super().__init__(name)
        self.robot, self.typename, self.names = robot, typename, action_names(action)
        self.gid = uuid.uuid4().bytes
        self.remote_status = 0
        self.cancel_sent = False
        self._on_result = on_result
        robot._goals[self.gid] = self
        t = robot.node.types
        req = t[typename + "_SendGoal_Request"](goal_id=_uuid_msg(t, self.gid), goal=goal)
        robot.node.call(self.names["send_goal"], typename + "_SendGoal", req, self._accepted,
                        timeout=robot.link_timeout)

    def _accepted(self, resp) -> None:
        if resp is None:
            self._finish("failed", self.robot._lost_reason() or
                         f"the robot did not answer {self.names['send_goal']} within "
                         f"{self.robot.link_timeout:g} s")
        elif not resp.accepted:
            self._finish("failed", f"the robot rejected the {self.name} goal")

    def status(self) -> str:
        if self._status == "running":
            lost = self.robot._lost_reason()
            if lost:
                self._finish("failed", lost)
        return self._status

    def on_status(self, code: int) -> None:
        self.remote_status = code
        if code in TERMINAL and self._status == "running" and not getattr(self, "_asked", False):
            self._asked = True
            t = self.robot.node.types
            req = t[self.typename + "_GetResult_Request"](goal_id=_uuid_msg(t, self.gid))
            self.robot.node.call(self.names["get_result"], self.typename + "_GetResult", req,
                                 self._result, timeout=self.robot.link_timeout)

    def on_feedback(self, fb) -> None:
        p = getattr(fb, "progress", None)          # RobotTask's
        if p is not None:
            self.progress = min(max(float(p), 0.0), 1.0)
            return
        left = getattr(fb, "distance_remaining", None)      # NavigateToPose's
        if left is not None and math.isfinite(float(left)):
            self._first_left = getattr(self, "_first_left", None) or max(float(left), 1e-6)
            self.progress = min(max(1.0 - float(left) / self._first_left, 0.0), 0.99)

    def _result(self, resp) -> None:
        if resp is None:
            self._finish("failed", self.robot._lost_reason() or
                         f"no result from {self.names['get_result']}")
            return
        code = int(resp.status)
        if code == SUCCEEDED:
            self._finish("succeeded", result=self._on_result(resp.result)
                         if self._on_result else None)
        elif code == CANCELED:
            with self._lock:
                if self._status == "running":
                    self._status, self.reason = "cancelled", "cancelled by the robot"
        else:
            r = resp.result
            reason = getattr(r, "message", "") or getattr(r, "error_msg", "") or \
                f"{self.name} aborted by the robot (error code {getattr(r, 'error_code', '?')})"
            self._finish("failed", str(reason))

    def cancel(self) -> None:
        with self._lock:
            if self._status != "running":
                return
            super().cancel()
        self.cancel_sent = True
        t = self.robot.node.types
        req = t["action_msgs/srv/CancelGoal_Request"](goal_info=t["action_msgs/msg/GoalInfo"](
            goal_id=_uuid_msg(t, self.gid), stamp=stamp(0, t)))
        answered = threading.Event()
        self.robot._cancels.append(answered)          # close() waits for the robot's answer
        self.robot.node.call(self.names["cancel_goal"], CANCEL_SRV[0], req,
                             lambda r: answered.set(), timeout=self.robot.link_timeout)


class _HeadAction(Action):
    """Done when joint_states shows both head joints within 0.02 rad of the command."""

    def __init__(self, robot: "Ros2Robot", pan: float, tilt: float, timeout: float = 5.0):
        super().__init__("set_head")
        self.robot, self.target = robot, (pan, tilt)
        self.t_end = time.monotonic() + timeout
        self.timeout = timeout

    def status(self) -> str:
        if self._status == "running":
            lost = self.robot._lost_reason()
            pan, tilt = self.robot.head()
            if lost:
                self._finish("failed", lost)
            elif abs(pan - self.target[0]) < 0.02 and abs(tilt - self.target[1]) < 0.02:
                self._finish("succeeded", result=(pan, tilt))
            elif time.monotonic() > self.t_end:
                self._finish("failed", f"the head did not reach pan {self.target[0]:.2f}, tilt "
                                       f"{self.target[1]:.2f} rad within {self.timeout:g} s")
        return self._status


class Ros2Robot:
    """The robot adapter of a live ROS 2 robot on Zenoh.

    ``endpoint``: the Zenoh router (rmw_zenoh's ``rmw_zenohd``); ``topics``: the mapping
    (TopicMap, dict, YAML file or ``key=value,...``); ``world``: the belief map (for the
    parking id of a frame); ``domain``: ROS_DOMAIN_ID (default: the environment's, else 0);
    ``session``: an open Zenoh session to use instead (not closed by ``close()``).
    Waits up to ``connect_timeout`` s for the robot's NavigateToPose server and tf; RobotError
    (one line) when they do not come."""

    def __init__(self, world=None, endpoint: str = DEFAULT_ENDPOINT, topics: Any = None,
                 clock=None, domain: Optional[int] = None, session=None,
                 connect_timeout: Optional[float] = None, capture_timeout: float = 5.0,
                 mount=HEAD):
        from hearth.robot.clock import WallClock
        self.world, self.endpoint = world, endpoint
        self.clock = clock or WallClock()
        self.m: TopicMap = load_topic_map(topics) if not isinstance(topics, TopicMap) else topics
        self.mount = mount
        self.link_timeout = float(self.m.link_timeout)
        connect_timeout = float(self.m.connect_timeout if connect_timeout is None
                                else connect_timeout)
        self.capture_timeout = float(capture_timeout)
        self._own_session = session is None
        self.session = open_session(endpoint) if session is None else session
        self.node = node = Node(self.session, "hearth", domain=domain)
        self.types = node.types
        self._goals: dict[bytes, GoalAction] = {}
        self._cancels: list[threading.Event] = []
        self._link = _Link()
        self._cv = threading.Condition()
        self._tf = _LiveTf(int(self.m.tf_tolerance * 1e9))
        self._tf_wall = 0.0
        self._images: dict[str, deque] = {}
        self._infos: dict[str, Any] = {}
        self._joints: dict[str, float] = {}
        self._battery = None
        self.said: list[str] = []
        self.log: list[dict] = []
        m = self.m
        node.subscribe(m.tf, "tf2_msgs/msg/TFMessage", lambda msg, _: self._on_tf(msg, False))
        node.subscribe(m.tf_static, "tf2_msgs/msg/TFMessage",
                       lambda msg, _: self._on_tf(msg, True), latched=True)
        self._topics = dict(
            color=[m.color] if m.color else list(COLOR_TOPICS),
            depth=[m.depth] if m.depth else list(DEPTH_TOPICS),
            camera_info=[m.camera_info] if m.camera_info else list(INFO_TOPICS))
        for role in ("color", "depth"):
            for topic in self._topics[role]:
                typ = "sensor_msgs/msg/CompressedImage" if topic.endswith(
                    ("/compressed", "/compressedDepth")) else "sensor_msgs/msg/Image"
                self._images[topic] = deque(maxlen=6)
                node.subscribe(topic, typ, self._image_cb(topic))
        for topic in self._topics["camera_info"]:
            node.subscribe(topic, "sensor_msgs/msg/CameraInfo", self._info_cb(topic))
        node.subscribe(m.joint_states, "sensor_msgs/msg/JointState", self._on_joints)
        node.subscribe(m.battery, "sensor_msgs/msg/BatteryState", self._on_battery)
        self._pub_head = node.publisher(m.head_command, "trajectory_msgs/msg/JointTrajectory")
        self._pub_pose = node.publisher(m.initial_pose,
                                        "geometry_msgs/msg/PoseWithCovarianceStamped")
        self._pub_say = node.publisher(m.say, "std_msgs/msg/String")
        for action, typ in ((m.navigate_action, NAV2_ACTION[0]), (m.task_action, TASK_ACTION[0])):
            n = action_names(action)
            for svc, suffix in (("send_goal", "_SendGoal"), ("get_result", "_GetResult")):
                node.client(n[svc], typ + suffix)
            node.client(n["cancel_goal"], CANCEL_SRV[0])
            node.subscribe(n["status"], "action_msgs/msg/GoalStatusArray", self._on_status)
            node.subscribe(n["feedback"], typ + "_FeedbackMessage", self._on_feedback)
        self._nav_server = mangle(action_names(m.navigate_action)["send_goal"])
        self._nav_hash = type_hash(NAV2_ACTION[0] + "_SendGoal")
        self._lv = self.session.liveliness().declare_subscriber(
            f"{ADMIN_SPACE}/{node.domain}/**", self._on_token, history=True)
        self._closed = False
        self._wait_connected(connect_timeout)
        _close_at_exit(self)

    # -- connection and link ----------------------------------------------------------------
    def _on_token(self, sample) -> None:
        key = str(sample.key_expr)
        parts = key.split("/")
        if len(parts) < 13 or parts[5] != "SS" or parts[9] != self._nav_server:
            return
        import zenoh
        with self._cv:
            if sample.kind == zenoh.SampleKind.DELETE:
                if self._link.tokens.pop(key, None) is not None and not self._link.tokens:
                    self._link.lost = (f"{LOST}: its NavigateToPose server "
                                       f"{self.m.navigate_action} left the Zenoh network "
                                       f"({self.endpoint})")
            else:
                self._link.tokens[key] = parts[11]
                if parts[11] == self._nav_hash:
                    self._link.lost = None
            self._cv.notify_all()

    def _wait_connected(self, timeout: float) -> None:
        t_end = time.monotonic() + timeout
        with self._cv:
            while time.monotonic() < t_end:
                ok = any(h == self._nav_hash for h in self._link.tokens.values())
                if ok and self._tf_wall > 0 and self._base_or_none() is not None:
                    self._link.lost = None
                    return
                self._cv.wait(0.05)
        hashes = sorted(set(self._link.tokens.values()) - {self._nav_hash})
        try:
            info = self.session.info
            alone = not list(info.routers_zid()) and not list(info.peers_zid())
        except Exception:                              # noqa: BLE001 (an older zenoh)
            alone = False
        if alone:
            why = "nothing answers there (no Zenoh router such as rmw_zenohd, no peer)"
        elif hashes:
            why = (f"its NavigateToPose ({self.m.navigate_action}) has type hash {hashes[0]}, "
                   f"Hearth's is {self._nav_hash} (another nav2_msgs version)")
        elif not self._link.tokens:
            why = (f"no NavigateToPose server {self.m.navigate_action} on domain "
                   f"{self.node.domain}")
        elif self._tf_wall <= 0:
            why = f"no tf on {self.m.tf}"
        else:
            why = f"no tf from {self.m.map_frame} to {self.m.base_frame} ({self._tf_problem()})"
        self.close()
        hint = "" if alone else " (is the robot on rmw_zenoh_cpp, ROS_DOMAIN_ID the same?)"
        raise RobotError(f"no ROS 2 robot at {self.endpoint} within {timeout:g} s: {why}{hint}")

    def robot_time_ns(self) -> int:
        """The robot's time: the stamp of the newest tf it sent (ns since the UNIX epoch on its
        clock, simulated or not; ``use_sim_time`` robots stamp with ``/clock``). Hearth stamps
        what it sends with it, never with its own clock, so the two need not agree."""
        return int(self._tf.latest_ns)

    def link_lost(self) -> Optional[str]:
        """Why the link to the robot is lost (one line), or None while it holds (after
        ``close()``: as it was when closed)."""
        if getattr(self, "_closed", False):
            return self._lost_at_close
        return self._lost_reason()

    def _lost_reason(self) -> Optional[str]:
        with self._cv:
            if self._link.lost:
                return self._link.lost
            if self._tf_wall and time.monotonic() - self._tf_wall > self.link_timeout:
                return f"{LOST}: no tf on {self.m.tf} for {self.link_timeout:g} s"
        return None

    def _check(self) -> None:
        lost = self._lost_reason()
        if lost:
            raise RobotError(lost)

    # -- callbacks ----------------------------------------------------------------------------
    def _on_tf(self, msg, static: bool) -> None:
        self._tf.add_msg(msg, static)
        with self._cv:
            if not static:
                self._tf_wall = time.monotonic()
            self._cv.notify_all()

    def _image_cb(self, topic: str):
        def cb(msg, _ns) -> None:
            with self._cv:
                self._images[topic].append(msg)
                self._cv.notify_all()
        return cb

    def _info_cb(self, topic: str):
        def cb(msg, _ns) -> None:
            with self._cv:
                self._infos[topic] = msg
        return cb

    def _on_joints(self, msg, _ns) -> None:
        with self._cv:
            for n, p in zip(msg.name, msg.position):
                self._joints[str(n)] = float(p)

    def _on_battery(self, msg, _ns) -> None:
        self._battery = msg

    def _on_status(self, msg, _ns) -> None:
        for st in msg.status_list:
            g = self._goals.get(bytes(np.asarray(st.goal_info.goal_id.uuid, dtype=np.uint8)))
            if g is not None:
                g.on_status(int(st.status))

    def _on_feedback(self, msg, _ns) -> None:
        g = self._goals.get(bytes(np.asarray(msg.goal_id.uuid, dtype=np.uint8)))
        if g is not None:
            g.on_feedback(msg.feedback)

    # -- localisation ---------------------------------------------------------------------------
    def _tf_problem(self) -> str:
        try:
            self._tf.lookup_at(self.m.map_frame, self.m.base_frame, self._tf.latest_ns)
        except LookupError as err:
            return str(err)
        return "none"

    def _base_or_none(self) -> Optional[Pose]:
        try:
            T = self._tf.lookup_at(self.m.map_frame, self.m.base_frame, self._tf.latest_ns)
        except LookupError:
            return None
        return as_base_pose(T)

    def base_pose(self) -> Pose:
        self._check()
        pose = self._base_or_none()
        if pose is None:
            raise RobotError(f"no tf from {self.m.map_frame} to {self.m.base_frame}: "
                             f"{self._tf_problem()}")
        return pose

    def apply_correction(self, pose) -> None:
        """Publish the corrected pose on ``initial_pose`` (as AMCL takes a pose estimate) and
        wait (up to ``link_timeout``) for tf to show it."""
        self._check()
        pose = as_base_pose(pose)
        t = self.types
        T = pose.matrix()
        from scipy.spatial.transform import Rotation
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        ns = self.robot_time_ns()
        cov = np.zeros(36)
        cov[0] = cov[7] = 0.01 ** 2
        cov[35] = math.radians(0.5) ** 2
        msg = t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=t["std_msgs/msg/Header"](stamp=stamp(ns, t), frame_id=self.m.map_frame),
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=float(T[0, 3]), y=float(T[1, 3]),
                                                          z=0.0),
                    orientation=t["geometry_msgs/msg/Quaternion"](*map(float, q))),
                covariance=cov))
        self._pub_pose(msg)
        self.log.append(dict(time=self.clock.now(), action="apply_correction",
                             pose=pose.as_dict()))
        t_end = time.monotonic() + self.link_timeout
        with self._cv:
            while time.monotonic() < t_end:
                now = self._base_or_none()
                if now is not None and now.planar_distance(pose) < 0.005 and \
                        abs(now.yaw_difference(pose)) < math.radians(0.3):
                    return
                self._cv.wait(0.05)
        self._check()

    # -- base and head --------------------------------------------------------------------------
    def _goal_pose(self, pose: Pose):
        t = self.types
        T = pose.matrix()
        from scipy.spatial.transform import Rotation
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        return t["geometry_msgs/msg/PoseStamped"](
            header=t["std_msgs/msg/Header"](stamp=stamp(self.robot_time_ns(), t),
                                            frame_id=self.m.map_frame),
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](*map(float, T[:3, 3])),
                orientation=t["geometry_msgs/msg/Quaternion"](*map(float, q))))

    def navigate_to(self, pose) -> Action:
        lost = self._lost_reason()
        if lost:
            return FailedAction("navigate_to", lost)
        goal = as_base_pose(pose)
        t = self.types
        msg = t[NAV2_ACTION[0] + "_Goal"](pose=self._goal_pose(goal), behavior_tree="")
        self.log.append(dict(time=self.clock.now(), action="navigate_to", goal=goal.as_dict()))
        return GoalAction(self, "navigate_to", self.m.navigate_action, NAV2_ACTION[0], msg,
                          on_result=lambda r: self._base_or_none())

    def head(self) -> tuple[float, float]:
        with self._cv:
            return (self._joints.get(self.m.head_pan_joint, 0.0),
                    self._joints.get(self.m.head_tilt_joint, 0.0))

    def set_head(self, pan: float, tilt: float) -> Action:
        lost = self._lost_reason()
        if lost:
            return FailedAction("set_head", lost)
        pan, tilt = self.mount.clip(float(pan), float(tilt))
        t = self.types
        self._pub_head(t["trajectory_msgs/msg/JointTrajectory"](
            header=t["std_msgs/msg/Header"](stamp=stamp(self.robot_time_ns(), t), frame_id=""),
            joint_names=[self.m.head_pan_joint, self.m.head_tilt_joint],
            points=[t["trajectory_msgs/msg/JointTrajectoryPoint"](
                positions=np.array([pan, tilt]), velocities=np.zeros(0),
                accelerations=np.zeros(0), effort=np.zeros(0),
                time_from_start=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=500_000_000))]))
        return _HeadAction(self, pan, tilt)

    def look_at(self, point_world) -> Action:
        """Aim with the believed base pose and the head geometry of ``mount``
        (docs/robot-adapter.md: the pan and tilt axes)."""
        try:
            base = self.base_pose()
        except RobotError as err:
            return FailedAction("look_at", str(err))
        return self.set_head(*pan_tilt_to(base, point_world, self.mount))

    # -- sensing --------------------------------------------------------------------------------
    def _pick(self, role: str, after_ns: int):
        """The newest message of the first topic of ``role`` that has one newer than
        ``after_ns`` (robot time)."""
        for topic in self._topics[role]:
            q = self._images.get(topic)
            if q and stamp_ns(q[-1].header.stamp) > after_ns:
                return topic, q
        return None, None

    def capture(self) -> Frame:
        """The first colour and depth pair taken after this call (robot time: after the
        newest tf seen), with the camera's pose from tf at its stamp."""
        self._check()
        after = self._tf.latest_ns
        t_end = time.monotonic() + self.capture_timeout
        tol = int(self.m.sync_tolerance * 1e9)
        pair = None
        with self._cv:
            while pair is None:
                ct, cq = self._pick("color", after)
                dt, dq = self._pick("depth", after)
                if cq and dq:
                    for c in reversed(cq):
                        cs = stamp_ns(c.header.stamp)
                        d = min(dq, key=lambda m: abs(stamp_ns(m.header.stamp) - cs))
                        if cs > after and abs(stamp_ns(d.header.stamp) - cs) <= tol:
                            pair = (ct, c, dt, d, cs)
                            break
                if pair is None:
                    lost = self._lost_reason()
                    if lost:
                        raise RobotError(lost)
                    left = t_end - time.monotonic()
                    if left <= 0:
                        raise RobotError(
                            f"no colour and depth image pair from the robot within "
                            f"{self.capture_timeout:g} s (colour: {ct or ' or '.join(self._topics['color'][:2])}, "
                            f"depth: {dt or ' or '.join(self._topics['depth'][:2])})")
                    self._cv.wait(min(left, 0.05))
            # tf must cover the image's stamp
            while self._tf.latest_ns < pair[4] and time.monotonic() < t_end:
                self._cv.wait(0.02)
            info = next((self._infos[t] for t in self._topics["camera_info"]
                         if t in self._infos), None)
        ct, c, dt, d, ns = pair
        if info is None:
            raise RobotError(f"no camera_info on {' or '.join(self._topics['camera_info'])}")
        cam = _camera(info)
        color = _image(c, False, ct)
        depth = _image(d, True, dt)
        if str(d.header.frame_id) != str(c.header.frame_id) or depth.shape != color.shape[:2]:
            raise RobotError(f"depth {dt} (frame {d.header.frame_id}, {depth.shape[1]}x"
                             f"{depth.shape[0]}) is not registered to colour {ct} (frame "
                             f"{c.header.frame_id}, {color.shape[1]}x{color.shape[0]}): a live "
                             "robot must publish registered depth (e.g. realsense2_camera's "
                             "align_depth.enable:=true)")
        if cam.D is not None:
            color = _undistort(color, cam, nearest=False)
            depth = _undistort(depth, cam, nearest=True)
        frame_id = self.m.camera_frame or str(c.header.frame_id)
        try:
            T_wc = self._tf.lookup_at(self.m.map_frame, frame_id, ns)
            T_wb = self._tf.lookup_at(self.m.map_frame, self.m.base_frame, ns)
        except LookupError as err:
            raise RobotError(f"tf at the image's stamp: {err}") from None
        base = as_base_pose(T_wb)
        pan, tilt = self.head()
        return Frame(color=color, depth=depth, intrinsics=cam.K, T_world_camera=T_wc,
                     timestamp=ns * 1e-9, pan=pan, tilt=tilt, base_pose=base,
                     parking=self._parking_at(base))

    def _parking_at(self, believed: Pose, tol: float = 0.05) -> Optional[str]:
        if self.world is None:
            return None
        for obj in self.world.large_objects():
            for p, pose in self.world.parking_positions(obj.id):
                if pose.planar_distance(believed) < tol and \
                        abs(pose.yaw_difference(believed)) < math.radians(5):
                    return p.id
        return None

    # -- arm and charger ---------------------------------------------------------------------
    def _task(self, task: str, target: str = "", handle: Optional[str] = None,
              value: float = 0.0, pose=None, **args) -> Action:
        lost = self._lost_reason()
        if lost:
            return FailedAction(task, lost)
        t = self.types
        goal = t[TASK_ACTION[0] + "_Goal"](
            task=task, target=str(target or ""), handle=str(handle or ""), value=float(value),
            pose=self._goal_pose(Pose() if pose is None else
                                 (pose if isinstance(pose, Pose) else Pose.from_matrix(
                                     np.asarray(pose, dtype=float)))),
            args_json=json.dumps(args))
        self.log.append(dict(time=self.clock.now(), action=task, target=target))
        return GoalAction(self, task, self.m.task_action, TASK_ACTION[0], goal,
                          on_result=lambda r: json.loads(r.result_json or "null"))

    def open_articulated(self, part_id: str, handle_id: Optional[str] = None,
                         target_state: float = 0.0) -> Action:
        return self._task("open_articulated", part_id, handle_id, target_state)

    def close_articulated(self, part_id: str, handle_id: Optional[str] = None,
                          target_state: float = 0.0) -> Action:
        return self._task("close_articulated", part_id, handle_id, target_state)

    def turn_knob(self, knob_id: str, angle: float) -> Action:
        return self._task("turn_knob", knob_id, value=angle)

    def grasp(self, object_id: str, pose=None) -> Action:
        return self._task("grasp", object_id, pose=pose)

    def place(self, parent_id: str, pose, relation: str = "on") -> Action:
        return self._task("place", parent_id, pose=pose, relation=relation)

    def hand_over(self) -> Action:
        return self._task("hand_over")

    def dock(self) -> Action:
        return self._task("dock")

    def undock(self) -> Action:
        return self._task("undock")

    def battery_state(self):
        from hearth.robot.battery import BatteryState
        b = self._battery
        if b is None:
            return BatteryState(level=1.0)
        loc = str(b.location)
        level = float(b.percentage)
        return BatteryState(level=level if math.isfinite(level) else 1.0,
                            charging=int(b.power_supply_status) == 1,
                            docked=loc.startswith("docked"),
                            charger=loc.split(":", 1)[1] or None if loc.startswith("docked:")
                            else None)

    def say(self, text: str) -> Action:
        self.said.append(str(text))
        self._pub_say(self.types["std_msgs/msg/String"](data=str(text)))
        return DoneAction("say", result=str(text))

    def stop(self) -> None:
        """Cancel every running goal of this adapter (each with its own cancel_goal)."""
        for g in list(self._goals.values()):
            g.cancel()

    def close(self) -> None:
        if getattr(self, "_closed", False):
            return
        self._lost_at_close = self._lost_reason() if hasattr(self, "_tf") else None
        self._closed = True
        t_end = time.monotonic() + self.link_timeout      # cancels sent at the end (Ctrl-C)
        for answered in getattr(self, "_cancels", []):  # reach the robot before we go
            if self._lost_at_close or not answered.wait(max(t_end - time.monotonic(), 0)):
                break
        try:
            self._lv.undeclare()
        except Exception:                              # noqa: BLE001
            pass
        self.node.close()
        if self._own_session:
            try:
                self.session.close()
            except Exception:                          # noqa: BLE001
                pass
