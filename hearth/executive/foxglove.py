"""Watch runs in Foxglove: the execution log as MCAP with Foxglove schemas, and the same
channels live through foxglove-sdk's WebSocket server on localhost (docs/ros2-foxglove.md).

``FoxgloveSink(mcap=PATH, port=PORT)`` owns a foxglove ``Context`` with the channels below,
an MCAP writer and/or a WebSocket server on it. ``sink.attach(executive)`` subscribes to the
Executive's events (its public ``subscribe`` API) and wraps ``hearth.executive.robot`` so that every
capture and base pose is published too. Times are the robot clock's wall time.

| topic | schema | what |
| --- | --- | --- |
| /hearth/log | foxglove.Log | every execution-log event as one line (status changes, feedback with its values, lifecycle, parameters, map updates), named by its tree path |
| /hearth/tree | hearth.TreeStatus (JSON) | the whole tree after each change: run, mission, state, tick, and every node's path, status, last feedback and the values it carried (JSON values, plottable) |
| /robot/pose | foxglove.PoseInFrame | the believed base pose in ``map`` |
| /tf | foxglove.FrameTransforms | map -> base_link -> camera_color_optical_frame |
| /camera/color, /camera/depth | foxglove.RawImage | each capture: rgb8, and 16UC1 millimetres |
| /camera/calibration | foxglove.CameraCalibration | the camera's intrinsics |
| /map/objects | foxglove.SceneUpdate | a box per object of the map at its bounds, with its states (doors, drawers, knobs) as text and metadata; sent whole at the start and per object when the map changes |
"""
from __future__ import annotations

import logging
import math
import sys
import threading
from typing import Any, Optional

import numpy as np

INSTALL = "pip install 'hearth[ros]' (foxglove-sdk)"
CAMERA_FRAME = "camera_color_optical_frame"
TREE_SCHEMA = {
    "title": "hearth.TreeStatus", "type": "object",
    "properties": {
        "run": {"type": "string"}, "mission": {"type": "string"}, "state": {"type": "string"},
        "tick": {"type": "integer"}, "t": {"type": "number"},
        "nodes": {"type": "array", "items": {"type": "object", "properties": {
            "path": {"type": "string"}, "status": {"type": "string"},
            "feedback": {"type": "string"},
            "values": {"type": "object", "description": "the values the feedback carried "
                                                         "(hearth.skills.base.Feedback)"}}}}}}
TOPICS = ("/hearth/log", "/hearth/tree", "/robot/pose", "/tf", "/camera/color", "/camera/depth",
          "/camera/calibration", "/map/objects")


def require_foxglove():
    try:
        import foxglove
    except ImportError:
        from hearth.robot.errors import RobotError
        raise RobotError(f"Foxglove output needs the ros extra: {INSTALL}") from None
    return foxglove


def _ts(ns: int):
    from foxglove.messages import Timestamp
    return Timestamp(sec=int(ns // 1_000_000_000), nsec=int(ns % 1_000_000_000))


def _pose(T):
    from foxglove.messages import Pose, Quaternion, Vector3
    from scipy.spatial.transform import Rotation
    T = np.asarray(T, dtype=float)
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    return Pose(position=Vector3(x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
                orientation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)))


def _transform(ns: int, parent: str, child: str, T):
    from foxglove.messages import FrameTransform, Quaternion, Vector3
    from scipy.spatial.transform import Rotation
    T = np.asarray(T, dtype=float)
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    return FrameTransform(timestamp=_ts(ns), parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
                          rotation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)))


class _Listener:
    """Counts WebSocket subscriptions so a simulated run can wait for a viewer."""

    def __init__(self):
        self.subscriptions: set = set()
        self.changed = threading.Condition()
        self.wants_map = False            # a viewer subscribed to /map/objects: send it whole

    def on_subscribe(self, client, channel) -> None:
        with self.changed:
            self.subscriptions.add((client.id, channel.id))
            if channel.topic == "/map/objects":
                self.wants_map = True
            self.changed.notify_all()

    def on_unsubscribe(self, client, channel) -> None:
        with self.changed:
            self.subscriptions.discard((client.id, channel.id))
            self.changed.notify_all()


#: The subprotocol foxglove-sdk's server speaks; it refuses a client that offers only the
#: older one (docs/ros2-foxglove.md, "Which clients connect").
SUBPROTOCOL = "foxglove.sdk.v1"
OLD_SUBPROTOCOL = "foxglove.websocket.v1"
REFUSED_HANDSHAKE = (f"foxglove: a client could not connect (handshake failed): this server "
                     f"speaks {SUBPROTOCOL} (the Foxglove app); a client that offers only "
                     f"{OLD_SUBPROTOCOL} (older Foxglove Studio, Lichtblick) cannot connect: "
                     "open the run's MCAP log in it instead (--foxglove-mcap; "
                     "docs/ros2-foxglove.md)")


class _ServerLog(logging.Handler):
    """foxglove-sdk's server lines (Python logger ``foxglove``) go to the /hearth/log channel
    and the process's logging at DEBUG, not to the mission's output; a refused handshake
    prints the one documented line above, once per server."""

    def __init__(self, sink: "FoxgloveSink", stream: Any = None):
        super().__init__(level=logging.INFO)
        self.sink = sink
        self.stream = stream
        self.told = False

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            if "handshake failed" in text and not self.told:
                self.told = True
                print(REFUSED_HANDSHAKE, file=self.stream or sys.stderr, flush=True)
            self.sink.server_line(record.levelno, record.name, text)
        except Exception:       # noqa: BLE001 - a log handler must never raise
            self.handleError(record)


class FoxgloveSink:
    """Foxglove channels fed by a run; written to ``mcap`` (a new file) and/or served live on
    ``host``:``port`` (0: any free port; ``self.port`` says which)."""

    def __init__(self, mcap: Optional[str] = None, port: Optional[int] = None,
                 host: str = "127.0.0.1", world: Any = None, clock: Any = None):
        fg = require_foxglove()
        from foxglove.channels import (CameraCalibrationChannel, FrameTransformsChannel,
                                       LogChannel, PoseInFrameChannel, RawImageChannel,
                                       SceneUpdateChannel)
        self.world, self.clock = world, clock
        self.ctx = fg.Context()
        self.log = LogChannel("/hearth/log", context=self.ctx)
        self.tree = fg.Channel("/hearth/tree", schema=TREE_SCHEMA, context=self.ctx)
        self.pose = PoseInFrameChannel("/robot/pose", context=self.ctx)
        self.tf = FrameTransformsChannel("/tf", context=self.ctx)
        self.color = RawImageChannel("/camera/color", context=self.ctx)
        self.depth = RawImageChannel("/camera/depth", context=self.ctx)
        self.calibration = CameraCalibrationChannel("/camera/calibration", context=self.ctx)
        self.scene = SceneUpdateChannel("/map/objects", context=self.ctx)
        self._lock = threading.RLock()
        self._nodes: dict[str, dict] = {}
        self._run: dict[str, Any] = {}
        self._ex = None
        self._last_pose = None
        self.writer = fg.open_mcap(mcap, context=self.ctx) if mcap else None
        self.listener = _Listener()
        self.server = None
        self.port = None
        self._server_log = None
        if port is not None:
            self._server_log = _ServerLog(self)
            logger = logging.getLogger("foxglove")
            logger.addHandler(self._server_log)
            logger.propagate = False        # not Python's last-resort handler on stderr
            if logger.level == logging.NOTSET or logger.level > logging.INFO:
                logger.setLevel(logging.INFO)
            self.server = fg.start_server(name="hearth", host=host, port=int(port),
                                          context=self.ctx, server_listener=self.listener)
            self.port = self.server.port

    def server_line(self, level: int, name: str, text: str) -> None:
        """One line of foxglove-sdk's server, on /hearth/log (and logging at DEBUG)."""
        from foxglove.messages import Log, LogLevel
        logging.getLogger("hearth.foxglove").debug("%s: %s", name, text)
        lv = (LogLevel.Error if level >= logging.ERROR else LogLevel.Warning
              if level >= logging.WARNING else LogLevel.Info)
        ns = self._ns()
        self.log.log(Log(timestamp=_ts(ns), level=lv, message=text, name=name, file="",
                         line=0), log_time=ns)

    # ---- time
    def _ns(self, t: Optional[float] = None) -> int:
        """Wall-clock nanoseconds of robot-clock time ``t`` (now when None)."""
        clock = self.clock
        if clock is None:
            import time
            return time.time_ns()
        offset = clock.wall() - clock.now()
        return int(round(((clock.now() if t is None else t) + offset) * 1e9))

    # ---- wiring
    def attach(self, executive) -> None:
        """Follow ``executive``: its events, its robot's captures and poses, its map."""
        self._ex = executive
        self.clock = self.clock or executive.clock
        self.world = self.world if self.world is not None else executive.world
        if executive.robot is not None and not isinstance(executive.robot, FoxgloveRobot):
            executive.robot = FoxgloveRobot(executive.robot, self)
        executive.subscribe(self.on_event)
        self.publish_map()

    def wait_for_viewer(self, timeout: float) -> bool:
        """Block until a WebSocket client subscribes to a channel (and the rest of its
        subscriptions had a moment to arrive), or ``timeout`` seconds pass."""
        if self.server is None or timeout <= 0:
            return False
        with self.listener.changed:
            seen = self.listener.changed.wait_for(lambda: self.listener.subscriptions, timeout)
            if seen:         # a client subscribes to all its panels' topics in one message
                self.listener.changed.wait_for(
                    lambda: len({c for _, c in self.listener.subscriptions}) >= len(TOPICS), 0.5)
        return bool(seen)

    def wait_for_viewers_to_leave(self, timeout: float) -> None:
        if self.server is None or timeout <= 0:
            return
        with self.listener.changed:
            self.listener.changed.wait_for(lambda: not self.listener.subscriptions, timeout)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None
        if self.server is not None:
            self.server.stop()
            self.server = None
        if self._server_log is not None:
            logging.getLogger("foxglove").removeHandler(self._server_log)
            self._server_log = None

    # ---- events
    def on_event(self, ev) -> None:
        from hearth.executive.replay import format_event
        from foxglove.messages import Log, LogLevel
        e = ev.to_json()
        kind = e["e"]
        if kind == "tick":
            return
        ns = self._ns(ev.time)
        level = LogLevel.Info
        if kind == "run" and e.get("state") in ("failed",):
            level = LogLevel.Error
        elif kind == "run" and e.get("state") in ("cancelled", "preempted", "halting"):
            level = LogLevel.Warning
        elif kind in ("write", "stopped"):
            level = LogLevel.Debug
        text = format_event(e).split("s  ", 1)[-1].strip()
        self.log.log(Log(timestamp=_ts(ns), level=level, message=text, name=ev.path or "mission",
                         file=self._run.get("file", ""), line=0), log_time=ns)
        with self._lock:
            if ev.run != self._run.get("run"):
                self._new_run(ev.run)
            elif not self._run.get("mission"):
                self._name_run(ev.run)
            if kind == "status":
                self._node(ev.path)["status"] = e["status"]
            elif kind == "feedback":
                self._node(ev.path).update(feedback=e["message"], values=e.get("values", {}))
            elif kind == "run":
                self._run["state"] = e.get("state", "")
            if kind in ("status", "feedback", "run"):
                self.tree.log({"run": ev.run, "mission": self._run.get("mission", ""),
                               "state": self._run.get("state", ""), "tick": int(ev.tick),
                               "t": float(ev.time), "nodes": list(self._nodes.values())},
                              log_time=ns)
        if self.listener.wants_map:
            self.listener.wants_map = False
            self.publish_map(None, ns)
        elif kind == "map" and self.world is not None and e.get("node"):
            self.publish_map([e["node"]], ns)
        robot = getattr(self._ex, "robot", None) if self._ex is not None else None
        if ev.tick != self._run.get("tick") and isinstance(robot, FoxgloveRobot):
            self._run["tick"] = ev.tick          # the pose once a tick (it moves while driving)
            try:
                self.publish_pose(robot.inner.base_pose(), ns)
            except Exception:  # noqa: BLE001 - a viewer must never stop the robot
                pass

    def _node(self, path: str) -> dict[str, Any]:
        return self._nodes.setdefault(path, {"path": path, "status": "INVALID", "feedback": "",
                                             "values": {}})

    def _new_run(self, run_id: str) -> None:
        self._run = {"run": run_id, "state": "running", "mission": "", "file": ""}
        self._nodes = {}
        self._name_run(run_id)

    def _name_run(self, run_id: str) -> None:
        """The run's mission and its nodes, once the Executive says which it is (its first
        events come while it is being started)."""
        handle = getattr(self._ex, "current", None) if self._ex is not None else None
        if handle is None or handle.id != run_id:
            return
        mission = handle.mission
        self._run.update(mission=mission.name, file=str(getattr(mission, "file", "") or ""))
        for n in mission.nodes():
            self._node(n.path)

    # ---- the robot
    def publish_pose(self, pose, ns: Optional[int] = None) -> None:
        from foxglove.messages import FrameTransforms, PoseInFrame
        key = (round(pose.x, 3), round(pose.y, 3), round(pose.yaw, 3))
        if key == self._last_pose:
            return
        self._last_pose = key
        ns = self._ns() if ns is None else ns
        T = pose.matrix()
        self.pose.log(PoseInFrame(timestamp=_ts(ns), frame_id="map", pose=_pose(T)), log_time=ns)
        self.tf.log(FrameTransforms(transforms=[_transform(ns, "map", "base_link", T)]),
                    log_time=ns)

    def publish_frame(self, frame) -> None:
        from foxglove.messages import CameraCalibration, FrameTransforms, RawImage
        from hearth.robot.recording import depth_to_mm
        ns = self._ns(getattr(frame, "timestamp", None))
        K = frame.intrinsics
        h, w = frame.depth.shape
        base = getattr(frame, "base_pose", None)
        if base is not None:
            self._last_pose = None
            self.publish_pose(base, ns)
            T_bc = np.linalg.inv(base.matrix()) @ np.asarray(frame.T_world_camera, dtype=float)
            self.tf.log(FrameTransforms(transforms=[_transform(ns, "base_link", CAMERA_FRAME,
                                                               T_bc)]), log_time=ns)
        else:
            self.tf.log(FrameTransforms(transforms=[_transform(ns, "map", CAMERA_FRAME,
                                                               frame.T_world_camera)]), log_time=ns)
        self.calibration.log(CameraCalibration(
            timestamp=_ts(ns), frame_id=CAMERA_FRAME, width=w, height=h,
            distortion_model="plumb_bob", D=[0.0] * 5,
            K=[K.fx, 0.0, K.cx, 0.0, K.fy, K.cy, 0.0, 0.0, 1.0],
            R=[1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
            P=[K.fx, 0.0, K.cx, 0.0, 0.0, K.fy, K.cy, 0.0, 0.0, 0.0, 1.0, 0.0]), log_time=ns)
        rgb = np.ascontiguousarray(np.asarray(frame.color, dtype=np.uint8))
        self.color.log(RawImage(timestamp=_ts(ns), frame_id=CAMERA_FRAME, width=w, height=h,
                                encoding="rgb8", step=w * 3, data=rgb.tobytes()), log_time=ns)
        mm = depth_to_mm(frame.depth).astype("<u2")
        self.depth.log(RawImage(timestamp=_ts(ns), frame_id=CAMERA_FRAME, width=w, height=h,
                                encoding="16UC1", step=w * 2, data=mm.tobytes()), log_time=ns)

    # ---- the map
    def publish_map(self, nodes=None, ns: Optional[int] = None) -> None:
        """The map's objects (all, or those owning ``nodes``) as a SceneUpdate."""
        w = self.world
        if w is None:
            return
        from foxglove.messages import SceneUpdate
        ns = self._ns() if ns is None else ns
        if nodes is None:
            ids = [o.id for o in w.large_objects()] + [o.id for o in w.small_objects()]
        else:
            ids = []
            for n in nodes:
                if n not in w:
                    continue
                node = w.get(n)
                owner = n if node.kind in ("LargeObject", "LargeArticulatedObject", "SmallObject") \
                    else w.large_object_of(n).id
                if owner not in ids:
                    ids.append(owner)
        entities = [self._entity(i, ns) for i in ids if i in w]
        if entities:
            self.scene.log(SceneUpdate(entities=entities), log_time=ns)

    def _entity(self, node_id: str, ns: int):
        from foxglove.messages import (Color, CubePrimitive, KeyValuePair, SceneEntity,
                                       TextPrimitive, Vector3)
        w = self.world
        node = w.get(node_id)
        lo, hi = w.bounds_world(node_id)
        size = np.maximum(hi - lo, 0.01)
        centre = np.eye(4)
        centre[:3, 3] = (lo + hi) / 2
        small = node.kind == "SmallObject"
        states = []
        for d in w.descendants(node_id):
            if getattr(d, "kind", "") == "Part" and d.joint.type != "fixed":
                unit = "rad" if d.joint.type == "revolute" else "m"
                states.append((d.id, f"{d.joint.state:.2f} {unit}"))
            elif getattr(d, "kind", "") == "Knob":
                states.append((d.id, str(d.state)))
        label = w.label(node_id) if hasattr(w, "label") else node_id
        text_pose = np.eye(4)
        text_pose[:3, 3] = ((lo + hi) / 2)[:2].tolist() + [float(hi[2]) + 0.1]
        text = "\n".join([label] + [f"{k}: {v}" for k, v in states])
        colour = Color(r=0.2, g=0.4, b=0.9, a=0.8) if small else Color(r=0.6, g=0.6, b=0.6, a=0.35)
        return SceneEntity(
            timestamp=_ts(ns), frame_id="map", id=node_id,
            metadata=[KeyValuePair(key="type", value=str(node.type))]
            + [KeyValuePair(key=k, value=v) for k, v in states],
            cubes=[CubePrimitive(pose=_pose(centre), size=Vector3(x=float(size[0]),
                                                                   y=float(size[1]),
                                                                   z=float(size[2])),
                                 color=colour)],
            texts=[TextPrimitive(pose=_pose(text_pose), billboard=True, font_size=12.0,
                                 scale_invariant=True, color=Color(r=1, g=1, b=1, a=1),
                                 text=text)])


class FoxgloveRobot:
    """A robot adapter that publishes every capture and believed base pose to a sink."""

    def __init__(self, inner, sink: FoxgloveSink):
        self.inner = inner
        self._sink = sink

    def capture(self):
        frame = self.inner.capture()
        self._sink.publish_frame(frame)
        return frame

    def base_pose(self):
        pose = self.inner.base_pose()
        self._sink.publish_pose(pose)
        return pose

    def __getattr__(self, name):
        return getattr(self.inner, name)


def sink_from_args(args, world=None, clock=None) -> Optional[FoxgloveSink]:
    """The sink the options ask for (None: neither); prints where it serves on stderr."""
    import sys
    port = getattr(args, "foxglove", None)
    mcap = getattr(args, "foxglove_mcap", None)
    if port is None and mcap is None:
        return None
    if port is not None and not 0 <= port <= 65535:
        from hearth.robot.errors import RobotError
        raise RobotError(f"--foxglove: {port} is not a port number")
    wait = getattr(args, "foxglove_wait", 0.0)
    if not (isinstance(wait, float) and math.isfinite(wait) and 0 <= wait <= 3600):
        from hearth.robot.errors import RobotError
        raise RobotError("--foxglove-wait: give seconds between 0 and 3600")
    try:
        sink = FoxgloveSink(mcap=mcap, port=port, world=world, clock=clock)
    except RuntimeError as err:          # foxglove-sdk: port in use, file exists
        from hearth.robot.errors import RobotError
        raise RobotError(f"Foxglove: {' '.join(str(err).split())}") from None
    if sink.port is not None:
        print(f"hearth: Foxglove live at ws://127.0.0.1:{sink.port} (Foxglove: open "
              "connection, Foxglove WebSocket)", file=sys.stderr, flush=True)
    return sink


__all__ = ["FoxgloveSink", "FoxgloveRobot", "TOPICS", "TREE_SCHEMA",
           "sink_from_args"]
