"""Recordings of RGB-D captures (docs/recording-format.md), the recorder and the replay robot.

- ``RecordingWriter`` writes a recording directory: ``manifest.json`` (versioned) and
  ``frames/NNNNNN_color.png`` (8-bit RGB stored by OpenCV) + ``frames/NNNNNN_depth.png``
  (16-bit, millimetres, 0 = no reading). The manifest is rewritten atomically after every
  capture and action, so an interrupted run leaves a readable recording.
- ``Recording`` reads one; every problem is one RobotError line naming the file.
- ``RecordingRobot`` wraps any adapter and records every capture and every action it is asked.
- ``ReplayRobot`` is an adapter that serves, for a capture, the recorded frame taken nearest
  to its believed base pose within position and yaw tolerances; arm actions and speech are
  logged and succeed (or fail as they did in the recording).
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

import cv2
import numpy as np

from perception.camera import Intrinsics
from hearth.robot.adapter import Action, DoneAction, FailedAction, TimedAction, as_base_pose
from hearth.robot.clock import SimClock
from hearth.robot.errors import RobotError
from hearth.robot.sim import HEAD, Frame, HeadMount, pan_tilt_to
from worldmodel.pose import Pose, wrap_angle

FORMAT = "hearth-recording"
VERSION = 1
MANIFEST = "manifest.json"
DEPTH_SCALE = 0.001          # metres per unit of the 16-bit depth PNG


# -- writing ---------------------------------------------------------------------------------

def _pose_dict(p) -> Optional[dict]:
    if p is None:
        return None
    p = as_base_pose(p)
    return dict(x=p.x, y=p.y, yaw=p.yaw)


def _matrix(T) -> Optional[list]:
    return None if T is None else np.asarray(T, dtype=float).round(9).tolist()


def _atomic_write_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, path)


class RecordingWriter:
    """Writes captures into ``directory`` (created; an existing recording there is replaced).
    ``info``: free-form provenance (world, scenario, mission) kept in the manifest."""

    def __init__(self, directory, intrinsics: Optional[Intrinsics] = None, info: Optional[dict] = None):
        self.dir = Path(directory)
        (self.dir / "frames").mkdir(parents=True, exist_ok=True)
        self.intrinsics = intrinsics
        self.manifest: dict[str, Any] = dict(format=FORMAT, version=VERSION,
                                             depth_scale=DEPTH_SCALE, info=dict(info or {}),
                                             intrinsics=intrinsics.as_dict() if intrinsics else None,
                                             captures=[], actions=[])
        self.flush()

    def add(self, frame, goal=None) -> dict:
        """Write one frame (robot.sim.Frame or alike); ``goal``: the navigation goal the robot
        was sent to before it (the base pose it was "taken at" in the plan)."""
        i = len(self.manifest["captures"])
        K = getattr(frame, "intrinsics", None) or getattr(frame, "K", None)
        if self.manifest["intrinsics"] is None and K is not None:
            self.manifest["intrinsics"] = K.as_dict()
        color_name, depth_name = f"frames/{i:06d}_color.png", f"frames/{i:06d}_depth.png"
        color = np.asarray(frame.color, dtype=np.uint8)
        if not cv2.imwrite(str(self.dir / color_name), color[..., ::-1]):
            raise RobotError("cannot write frame", file=str(self.dir / color_name))
        mm = np.nan_to_num(np.asarray(frame.depth, dtype=np.float64) / DEPTH_SCALE, nan=0.0)
        mm = np.clip(np.rint(mm), 0, 65535).astype(np.uint16)
        if not cv2.imwrite(str(self.dir / depth_name), mm):
            raise RobotError("cannot write frame", file=str(self.dir / depth_name))
        truth = None
        if getattr(frame, "T_world_camera_true", None) is not None:
            truth = dict(base_pose=_pose_dict(getattr(frame, "base_pose_true", None)),
                         T_world_camera=_matrix(frame.T_world_camera_true))
        entry = dict(index=i, timestamp=float(getattr(frame, "timestamp", 0.0)),
                     color=color_name, depth=depth_name,
                     base_pose=_pose_dict(getattr(frame, "base_pose", None)),
                     T_world_camera=_matrix(frame.T_world_camera),
                     pan=float(getattr(frame, "pan", 0.0)), tilt=float(getattr(frame, "tilt", 0.0)),
                     parking=getattr(frame, "parking", None), goal=_pose_dict(goal), truth=truth)
        self.manifest["captures"].append(entry)
        self.flush()
        return entry

    def log_action(self, entry: dict) -> dict:
        self.manifest["actions"].append(entry)
        self.flush()
        return entry

    def flush(self) -> None:
        _atomic_write_text(self.dir / MANIFEST, json.dumps(self.manifest, indent=1) + "\n")


# -- reading ---------------------------------------------------------------------------------

@dataclass
class Capture:
    """One manifest entry (poses as Pose / 4x4 arrays; truth None when unknown)."""
    index: int
    timestamp: float
    color: str
    depth: str
    base_pose: Optional[Pose]
    T_world_camera: np.ndarray
    pan: float
    tilt: float
    parking: Optional[str]
    goal: Optional[Pose]
    base_pose_true: Optional[Pose]
    T_world_camera_true: Optional[np.ndarray]


class Recording:
    """A recording directory, read and checked (``captures``, ``actions``, ``intrinsics``)."""

    def __init__(self, directory):
        self.dir = Path(directory)
        self.path = self.dir / MANIFEST
        if not self.path.is_file():
            raise RobotError("not a recording: manifest.json is missing", file=str(self.path))
        try:
            data = json.loads(self.path.read_text())
        except json.JSONDecodeError as err:
            raise RobotError(f"corrupt manifest: {err.msg} (column {err.colno})",
                             file=str(self.path), line=err.lineno) from None
        except UnicodeDecodeError:
            raise RobotError("corrupt manifest: not UTF-8 text", file=str(self.path)) from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise RobotError(f"corrupt manifest: not a {FORMAT} manifest", file=str(self.path))
        if data.get("version") != VERSION:
            raise RobotError(f"unknown recording version {data.get('version')!r} (this Hearth "
                             f"reads version {VERSION})", file=str(self.path))
        try:
            self.depth_scale = float(data.get("depth_scale", DEPTH_SCALE))
            self.intrinsics = (Intrinsics.from_dict(data["intrinsics"])
                               if data.get("intrinsics") else None)
            self.captures = [self._capture(c) for c in data["captures"]]
            self.actions = list(data.get("actions", []))
            self.info = dict(data.get("info", {}))
            sp = data.get("start_pose")
            self.start_pose = (None if sp is None else
                               Pose.planar(float(sp["x"]), float(sp["y"]), float(sp["yaw"])))
        except (KeyError, TypeError, ValueError) as err:
            raise RobotError(f"corrupt manifest: bad or missing field {err}",
                             file=str(self.path)) from None
        if self.captures and self.intrinsics is None:
            raise RobotError("corrupt manifest: captures without intrinsics", file=str(self.path))

    @staticmethod
    def _capture(c: dict) -> Capture:
        def pose(d):
            return None if d is None else Pose.planar(float(d["x"]), float(d["y"]), float(d["yaw"]))
        truth = c.get("truth") or {}
        T = np.asarray(c["T_world_camera"], dtype=float)
        if T.shape != (4, 4):
            raise ValueError("T_world_camera")
        Tt = truth.get("T_world_camera")
        return Capture(index=int(c["index"]), timestamp=float(c.get("timestamp", 0.0)),
                       color=str(c["color"]), depth=str(c["depth"]), base_pose=pose(c.get("base_pose")),
                       T_world_camera=T, pan=float(c.get("pan", 0.0)), tilt=float(c.get("tilt", 0.0)),
                       parking=c.get("parking"), goal=pose(c.get("goal")),
                       base_pose_true=pose(truth.get("base_pose")),
                       T_world_camera_true=None if Tt is None else np.asarray(Tt, dtype=float))

    def __len__(self) -> int:
        return len(self.captures)

    def frame(self, i: int) -> Frame:
        """Capture ``i`` as a Frame (colour and depth loaded from their PNGs)."""
        c = self.captures[i]
        color_path, depth_path = self.dir / c.color, self.dir / c.depth
        for p in (color_path, depth_path):
            if not p.is_file():
                raise RobotError(f"frame {c.index} is missing", file=str(p))
        bgr = cv2.imread(str(color_path), cv2.IMREAD_COLOR)
        if bgr is None:
            raise RobotError(f"frame {c.index}: unreadable colour PNG", file=str(color_path))
        raw = cv2.imread(str(depth_path), cv2.IMREAD_UNCHANGED)
        if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
            raise RobotError(f"frame {c.index}: depth must be a 16-bit single-channel PNG",
                             file=str(depth_path))
        K = self.intrinsics
        if raw.shape != (K.height, K.width) or bgr.shape[:2] != (K.height, K.width):
            raise RobotError(f"frame {c.index}: image size differs from the intrinsics "
                             f"({K.width}x{K.height})", file=str(depth_path))
        return Frame(color=np.ascontiguousarray(bgr[..., ::-1]),
                     depth=(raw.astype(np.float32) * np.float32(self.depth_scale)),
                     intrinsics=K, T_world_camera=c.T_world_camera.copy(), timestamp=c.timestamp,
                     pan=c.pan, tilt=c.tilt, base_pose=c.base_pose,
                     T_world_camera_true=c.T_world_camera_true, base_pose_true=c.base_pose_true,
                     parking=c.parking)


# -- recording any adapter -------------------------------------------------------------------

class _LoggedAction(Action):
    """An action proxy that writes its outcome into the recording's action log."""

    def __init__(self, inner: Action, entry: dict, writer: RecordingWriter):
        self._inner, self._entry, self._writer = inner, entry, writer
        self.name = getattr(inner, "name", entry["action"])

    def status(self) -> str:
        s = self._inner.status()
        if s != "running" and self._entry.get("status") != s:
            self._entry["status"] = s
            self._entry["reason"] = getattr(self._inner, "reason", "")
            self._writer.flush()
        return s

    def cancel(self) -> None:
        self._inner.cancel()
        self.status()

    @property
    def progress(self):
        return getattr(self._inner, "progress", 0.0)

    @property
    def reason(self):
        return getattr(self._inner, "reason", "")

    @property
    def result(self):
        return getattr(self._inner, "result", None)


_LOGGED = ("navigate_to", "open_articulated", "close_articulated", "turn_knob", "grasp", "place",
           "hand_over", "say", "set_head", "look_at", "apply_correction")


class RecordingRobot:
    """Any adapter, with every capture written to a recording and every action logged."""

    def __init__(self, inner, directory, info: Optional[dict] = None):
        self.inner = inner
        self.writer = RecordingWriter(directory, getattr(inner, "intrinsics", None), info)
        self._goal = None
        try:
            self.writer.manifest["start_pose"] = _pose_dict(inner.base_pose())
            self.writer.flush()
        except (AttributeError, RobotError):
            pass

    def capture(self):
        frame = self.inner.capture()
        self.writer.add(frame, goal=self._goal)
        return frame

    def stop(self) -> None:
        self.inner.stop()
        self._log("stop", {})

    def _log(self, name: str, args: dict) -> dict:
        clock = getattr(self.inner, "clock", None)
        t = clock.now() if clock is not None else None
        return self.writer.log_action(dict(time=t, action=name, args=args))

    def __getattr__(self, name):
        attr = getattr(self.inner, name)
        if name not in _LOGGED or not callable(attr):
            return attr

        def call(*args, **kwargs):
            entry = self._log(name, _jsonable(dict(enumerate(args)) | kwargs))
            if name == "navigate_to" and args:
                self._goal = args[0]
            out = attr(*args, **kwargs)
            if isinstance(out, Action) or hasattr(out, "status"):
                return _LoggedAction(out, entry, self.writer)
            return out
        return call


def _jsonable(d: dict) -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, Pose):
            v = v.as_dict()
        elif isinstance(v, np.ndarray):
            v = v.tolist()
        elif not isinstance(v, (str, int, float, bool, type(None), list, dict)):
            v = repr(v)
        out[str(k)] = v
    return out


# -- replay ----------------------------------------------------------------------------------

class ReplayRobot:
    """An adapter serving recorded frames (docs/recording-format.md).

    The base "drives" to wherever it is sent (taking distance over ``speed`` on the clock);
    ``capture()`` returns the frame recorded nearest to the believed base pose within
    ``position_tolerance`` (m) and ``yaw_tolerance`` (rad), preferring frames not served yet
    (in recorded order), then the closest head angles. No frame near enough: one RobotError
    naming the pose asked for and the nearest recorded. Arm actions and speech are logged in
    ``log``; they succeed, or fail with the recorded reason when the recording saw them fail.
    """

    def __init__(self, recording, clock=None, position_tolerance: float = 0.10,
                 yaw_tolerance: float = math.radians(10), speed: float = 0.5,
                 turn_speed: float = 1.0, action_time: float = 2.0, start_pose=None,
                 mount: HeadMount = HEAD):
        self.recording = recording if isinstance(recording, Recording) else Recording(recording)
        self.clock = clock if clock is not None else SimClock()
        self.position_tolerance, self.yaw_tolerance = float(position_tolerance), float(yaw_tolerance)
        self.speed, self.turn_speed, self.action_time = speed, turn_speed, action_time
        self.intrinsics = self.recording.intrinsics
        self.mount = mount
        first = self.recording.start_pose or next(
            (c.base_pose for c in self.recording.captures if c.base_pose is not None), None)
        self._pose = as_base_pose(start_pose) if start_pose is not None else (first or Pose())
        self._pan, self._tilt = 0.0, 0.0
        self._served: set[int] = set()
        self._recorded_actions = [a for a in self.recording.actions if a.get("action") != "stop"]
        self._actions: list[Action] = []
        self.log: list[dict] = []
        self.said: list[str] = []
        self.stops = 0

    # localisation
    def base_pose(self) -> Pose:
        for a in self._actions:
            a.status()
        return self._pose

    def apply_correction(self, pose) -> None:
        self._pose = as_base_pose(pose)
        self._log("apply_correction", pose=self._pose.as_dict())

    # base and head
    def navigate_to(self, pose) -> Action:
        goal = as_base_pose(pose)
        start = self.base_pose()
        duration = (start.planar_distance(goal) / self.speed
                    + abs(wrap_angle(goal.yaw - start.yaw)) / self.turn_speed)

        def done():
            self._pose = goal
            return goal
        act = TimedAction("navigate_to", self.clock, duration, on_done=done)
        self._actions.append(act)
        self._log("navigate_to", goal=goal.as_dict())
        return act

    def head(self) -> tuple[float, float]:
        return self._pan, self._tilt

    def set_head(self, pan: float, tilt: float) -> Action:
        self._pan, self._tilt = self.mount.clip(float(pan), float(tilt))
        return DoneAction("set_head", result=(self._pan, self._tilt))

    def look_at(self, point_world) -> Action:
        return self.set_head(*pan_tilt_to(self.base_pose(), point_world, self.mount))

    # sensing
    def nearest(self, pose: Pose) -> tuple[Optional[Capture], float, float]:
        """The recorded capture nearest to ``pose`` (position first, then yaw), with its
        distance (m) and absolute yaw difference (rad)."""
        best, key = None, None
        for c in self.recording.captures:
            if c.base_pose is None:
                continue
            d = c.base_pose.planar_distance(pose)
            y = abs(wrap_angle(c.base_pose.yaw - pose.yaw))
            k = (d / max(self.position_tolerance, 1e-9) + y / max(self.yaw_tolerance, 1e-9))
            if key is None or k < key:
                best, key = c, k
        if best is None:
            return None, math.inf, math.inf
        return (best, best.base_pose.planar_distance(pose),
                abs(wrap_angle(best.base_pose.yaw - pose.yaw)))

    def capture(self) -> Frame:
        pose = self.base_pose()
        within = [c for c in self.recording.captures if c.base_pose is not None
                  and c.base_pose.planar_distance(pose) <= self.position_tolerance
                  and abs(wrap_angle(c.base_pose.yaw - pose.yaw)) <= self.yaw_tolerance]
        if not within:
            c, d, y = self.nearest(pose)
            asked = f"({pose.x:.2f}, {pose.y:.2f}, {math.degrees(pose.yaw):.0f} deg)"
            if c is None:
                near = "the recording has no captures"
            else:
                at = f" at {c.parking}" if c.parking else ""
                near = (f"nearest recorded: ({c.base_pose.x:.2f}, {c.base_pose.y:.2f}, "
                        f"{math.degrees(c.base_pose.yaw):.0f} deg){at}, {d:.2f} m and "
                        f"{math.degrees(y):.0f} deg away")
            raise RobotError(f"no recorded frame within {self.position_tolerance:.2f} m and "
                             f"{math.degrees(self.yaw_tolerance):.0f} deg of base pose {asked}; "
                             f"{near}", file=str(self.recording.path))
        head = (self._pan, self._tilt)
        c = min(within, key=lambda c: (c.index in self._served,
                                       round(math.hypot(wrap_angle(c.pan - head[0]),
                                                        c.tilt - head[1]) / math.radians(5)),
                                       c.index))
        self._served.add(c.index)
        frame = self.recording.frame(c.index)
        # The camera stays where it was on the recorded base; the base is where we believe it.
        if c.base_pose is not None:
            frame.T_world_camera = (pose.matrix() @ np.linalg.inv(c.base_pose.matrix())
                                    @ c.T_world_camera)
        frame.base_pose = pose
        frame.timestamp = self.clock.now()
        self._log("capture", index=c.index)
        return frame

    # arm and speech
    def _replayed(self, name: str, **args) -> Action:
        self._log(name, **args)
        recorded = next((a for a in self._recorded_actions if a.get("action") == name), None)
        if recorded is not None:
            self._recorded_actions.remove(recorded)
            if recorded.get("status") == "failed":
                act = TimedAction(name, self.clock, self.action_time,
                                  fail=recorded.get("reason") or f"{name} failed (recorded)")
                self._actions.append(act)
                return act
        act = TimedAction(name, self.clock, self.action_time, on_done=lambda: args or None)
        self._actions.append(act)
        return act

    def open_articulated(self, part_id, handle_id=None, target_state=None) -> Action:
        return self._replayed("open_articulated", part=part_id, handle=handle_id,
                              target=target_state)

    def close_articulated(self, part_id, handle_id=None, target_state=None) -> Action:
        return self._replayed("close_articulated", part=part_id, handle=handle_id,
                              target=target_state)

    def turn_knob(self, knob_id, angle) -> Action:
        return self._replayed("turn_knob", knob=knob_id, angle=float(angle))

    def grasp(self, object_id, pose=None) -> Action:
        return self._replayed("grasp", object=object_id,
                              pose=pose.as_dict() if isinstance(pose, Pose) else None)

    def place(self, parent_id, pose=None, relation: str = "on") -> Action:
        return self._replayed("place", parent=parent_id,
                              pose=pose.as_dict() if isinstance(pose, Pose) else None)

    def hand_over(self) -> Action:
        return self._replayed("hand_over")

    def say(self, text: str) -> Action:
        self.said.append(str(text))
        self._log("say", text=str(text))
        return DoneAction("say", result=str(text))

    def stop(self) -> None:
        self.stops += 1
        for a in self._actions:
            a.cancel()
        self._log("stop")

    def _log(self, action: str, **info) -> None:
        self.log.append(dict(time=self.clock.now(), action=action, **info))


__all__ = ["Capture", "Recording", "RecordingRobot", "RecordingWriter", "ReplayRobot",
           "FailedAction", "VERSION"]
