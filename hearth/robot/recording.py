"""Recordings of RGB-D captures (docs/recording-format.md), the recorder and the replay robot.

- ``RecordingWriter`` writes a recording directory, version 2: ``manifest.json`` (a small
  header: format, version, depth scale, intrinsics, provenance, start pose), then one JSON
  line per capture appended to ``captures.jsonl`` once its ``frames/NNNNNN_color.png`` (8-bit
  RGB stored by OpenCV) and ``frames/NNNNNN_depth.png`` (16-bit, millimetres, 0 = no reading;
  in folders of 250 captures)
  are on disk, and one JSON line per robot request and per outcome appended to
  ``actions.jsonl``. Writing is append-only (linear in the recording's length); an
  interrupted run leaves a readable recording (a torn last line is ignored). Frames go in
  folders of 250 captures (``frames/0000/000000_color.png``).
- ``Recording`` reads version 1 (everything in ``manifest.json``) and version 2, and checks
  the whole recording when it is opened: every number finite (depth scale, intrinsics, poses,
  times), every frame file inside the folder, present, a complete PNG of the right bit depth
  and size. Every problem is one RobotError line naming the file (and line), so a bad
  recording is refused before a mission starts, never halfway through it.
- ``RecordingRobot`` wraps any adapter and records every capture and every action it is asked
  (into this format, or a ROS 2 bag: ``hearth.robot.rosbag.BagWriter``).
- ``ReplayRobot`` is an adapter that serves, for a capture, the recorded frame taken nearest
  to its believed base pose within position and yaw tolerances; arm actions and speech are
  logged and succeed (or fail as they did in the recording). It replays anything shaped like
  ``Recording`` (``open_recording`` also opens ROS 2 bags).
"""
from __future__ import annotations

import json
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any, Optional

import cv2
import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.robot.adapter import Action, FailedAction, TimedAction, as_base_pose
from hearth.robot.captures import (DEPTH_SCALE, MAX_TIME, BadField, Capture, _number,  # noqa: F401
                                   _planar, _pose_dict, _transform, check_intrinsics,
                                   depth_to_mm, frame_entry)
from hearth.robot.clock import SimClock
from hearth.robot.errors import RobotError
from hearth.util.files import BadJSON, load_json, read_limited
from hearth.robot.frames import (FrameFileError,
                                 check_color_png, check_depth_png, decode_color, decode_depth,
                                 inside)
from hearth.robot.sim import HEAD, Frame, HeadMount, PanTiltHead, SpokenAndLogged
from hearth.worldmodel.io import atomic_write
from hearth.worldmodel.pose import Pose, wrap_angle

FORMAT = "hearth-recording"
VERSION = 2
VERSIONS = (1, 2)
MANIFEST = "manifest.json"
CAPTURES = "captures.jsonl"
ACTIONS = "actions.jsonl"
#: depth_scale's bounds, metres per unit: 0.01 mm (a 0.65 m range) to 1 cm (655 m). Beyond
#: them the depth is no depth: 1e300 overflows float32 to inf, 1e-60 rounds every reading to 0.
DEPTH_SCALE_RANGE = (1e-5, 1e-2)
#: Limits of the recording's own files (its frames: hearth.robot.frames): the header, and
#: each JSON-lines file (a capture line is ~700 bytes: 128 MiB holds 180,000 captures).
MAX_MANIFEST_BYTES = 64 << 20
MAX_LINES_BYTES = 128 << 20
#: Captures in one recording (a capture holds a few hundred bytes of poses in memory).
MAX_CAPTURES = 200_000
FRAMES_PER_FOLDER = 250      # frames/0000/, frames/0001/, ...


# -- writing ---------------------------------------------------------------------------------

class RecordingWriter:
    """Writes captures into ``directory`` (created; an existing recording there is replaced).
    ``info``: free-form provenance (world, scenario, mission) kept in the header.

    Append-only: the header is written (atomically) when the recording starts and again only
    when the intrinsics or the start pose become known; each capture and each action is one
    appended line. ``len(writer)`` is the number of captures written."""

    def __init__(self, directory, intrinsics: Optional[Intrinsics] = None, info: Optional[dict] = None):
        self.dir = Path(directory)
        (self.dir / "frames").mkdir(parents=True, exist_ok=True)
        self.header: dict[str, Any] = dict(format=FORMAT, version=VERSION,
                                           depth_scale=DEPTH_SCALE, info=dict(info or {}),
                                           intrinsics=intrinsics.as_dict() if intrinsics else None,
                                           start_pose=None, captures=CAPTURES, actions=ACTIONS)
        self._write_header()
        self._captures = open(self.dir / CAPTURES, "w", encoding="utf-8")  # noqa: SIM115
        self._actions = open(self.dir / ACTIONS, "w", encoding="utf-8")    # noqa: SIM115
        self._n = 0
        self._n_actions = 0

    def __len__(self) -> int:
        return self._n

    def _write_header(self) -> None:
        # atomically, and a temporary file a writer killed mid-rename left is removed
        atomic_write(self.dir / MANIFEST, (json.dumps(self.header, indent=1) + "\n").encode())

    def set_start_pose(self, pose) -> None:
        self.header["start_pose"] = _pose_dict(pose)
        self._write_header()

    def add(self, frame, goal=None) -> dict:
        """Write one frame (robot.sim.Frame or alike); ``goal``: the navigation goal the robot
        was sent to before it (the base pose it was "taken at" in the plan)."""
        i = self._n
        K = getattr(frame, "intrinsics", None) or getattr(frame, "K", None)
        if self.header["intrinsics"] is None and K is not None:
            self.header["intrinsics"] = K.as_dict()
            self._write_header()
        # Frames in folders of FRAMES_PER_FOLDER: creating a file in a folder of thousands
        # costs measurably more, which would make a long recording slower per capture.
        folder = f"frames/{i // FRAMES_PER_FOLDER:04d}"
        if i % FRAMES_PER_FOLDER == 0:
            (self.dir / folder).mkdir(parents=True, exist_ok=True)
        color_name, depth_name = f"{folder}/{i:06d}_color.png", f"{folder}/{i:06d}_depth.png"
        color = np.asarray(frame.color, dtype=np.uint8)
        if not cv2.imwrite(str(self.dir / color_name), color[..., ::-1]):
            raise RobotError("cannot write frame", file=str(self.dir / color_name))
        if not cv2.imwrite(str(self.dir / depth_name), depth_to_mm(frame.depth)):
            raise RobotError("cannot write frame", file=str(self.dir / depth_name))
        entry = dict(index=i, color=color_name, depth=depth_name) | frame_entry(frame, goal)
        # One write per line, flushed, after the frames are on disk: a line is only ever
        # there with its frames, and a kill leaves at most a torn last line.
        self._captures.write(json.dumps(entry) + "\n")
        self._captures.flush()
        self._n += 1
        return entry

    def log_action(self, entry: dict) -> int:
        """Append a robot request (``time``, ``action``, ``args``); its number for
        ``action_done``."""
        k = self._n_actions
        self._n_actions += 1
        self._actions.write(json.dumps(dict(i=k) | entry, default=repr) + "\n")
        self._actions.flush()
        return k

    def action_done(self, k: int, status: str, reason: str = "") -> None:
        """Append the outcome of request ``k``."""
        self._actions.write(json.dumps(dict(i=k, status=status, reason=reason)) + "\n")
        self._actions.flush()

    def flush(self) -> None:
        self._captures.flush()
        self._actions.flush()

    def close(self) -> None:
        for f in (self._captures, self._actions):
            if not f.closed:
                f.close()


# -- reading ---------------------------------------------------------------------------------

def _capture(c, i: int) -> Capture:
    if not isinstance(c, dict):
        raise BadField("a capture must be a JSON object")
    for k in ("color", "depth"):
        if not isinstance(c.get(k), str):
            raise BadField(f"{k} must be the path of a frame file")
    truth = c.get("truth") or {}
    if not isinstance(truth, dict):
        raise BadField("truth must be an object or null")
    Tt = truth.get("T_world_camera")
    parking = c.get("parking")
    if parking is not None and not isinstance(parking, str):
        raise BadField("parking must be a string or null")
    return Capture(index=i, timestamp=_number(c.get("timestamp", 0.0), "timestamp",
                                              bound=MAX_TIME),
                   color=c["color"], depth=c["depth"], base_pose=_planar(c.get("base_pose"), "base_pose"),
                   T_world_camera=_transform(c.get("T_world_camera"), "T_world_camera"),
                   pan=_number(c.get("pan", 0.0), "pan"), tilt=_number(c.get("tilt", 0.0), "tilt"),
                   parking=parking, goal=_planar(c.get("goal"), "goal"),
                   base_pose_true=_planar(truth.get("base_pose"), "truth.base_pose"),
                   T_world_camera_true=None if Tt is None else _transform(Tt, "truth.T_world_camera"))


def _own_file(directory: Path, name: str, limit: int) -> bytes:
    """The bytes of the recording's own file ``name`` (manifest, captures, actions): a
    regular file inside the folder (a symbolic link may not lead out of it), at most
    ``limit`` bytes, read without blocking (a FIFO or a link to /dev/zero is refused)."""
    path = directory / name
    try:
        inside(directory, name, limit=limit, what=name)
    except FrameFileError as err:
        if str(err) == "missing":
            raise RobotError("missing (a version 2 recording has it beside manifest.json)",
                             file=str(path)) from None
        raise RobotError(str(err), file=str(path)) from None
    return read_limited(path, limit, RobotError, f"larger than {limit >> 20} MiB")


def _json_lines(path: Path) -> list[tuple[int, Any]]:
    """(line number, value) of a JSON-lines file; a torn last line (no newline, not JSON:
    a writer killed mid-line) is left out."""
    data = _own_file(path.parent, path.name, MAX_LINES_BYTES)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise RobotError("not UTF-8 text", file=str(path)) from None
    lines = text.split("\n")
    out = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        if len(out) >= MAX_CAPTURES * 2:     # a capture, or an action and its outcome
            raise RobotError(f"more than {MAX_CAPTURES * 2} lines", file=str(path), line=n)
        try:
            out.append((n, load_json(line)))
        except BadJSON as err:
            if n == len(lines) and not err.message.startswith("an integer"):
                break                     # the last line, not newline-terminated: torn
            raise RobotError(f"corrupt line: {err.message}", file=str(path), line=n) from None
    return out


class Recording:
    """A recording directory, read and checked whole (``captures``, ``actions``,
    ``intrinsics``, ``depth_scale``, ``start_pose``, ``info``). ``check_frames=False`` skips
    the frame files (for tools that only read the manifest)."""

    def __init__(self, directory, check_frames: bool = True):
        self.dir = Path(directory)
        self.path = self.dir / MANIFEST
        if not os.path.lexists(self.path):
            raise RobotError("not a recording: manifest.json is missing", file=str(self.path))
        raw = _own_file(self.dir, MANIFEST, MAX_MANIFEST_BYTES)
        try:
            data = load_json(raw)
        except BadJSON as err:
            raise RobotError(f"corrupt manifest: {err.message}", file=str(self.path),
                             line=err.line or None) from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise RobotError(f"corrupt manifest: not a {FORMAT} manifest", file=str(self.path))
        self.version = data.get("version")
        if self.version not in VERSIONS or isinstance(self.version, bool):
            raise RobotError(f"unknown recording version {data.get('version')!r} (this Hearth "
                             f"reads versions {', '.join(map(str, VERSIONS))})",
                             file=str(self.path))
        try:
            self.depth_scale = _number(data.get("depth_scale", DEPTH_SCALE), "depth_scale",
                                       positive=True, bound=math.inf)
            lo, hi = DEPTH_SCALE_RANGE
            if not lo <= self.depth_scale <= hi:
                raise BadField(f"depth_scale {self.depth_scale:g} is not between {lo:g} and {hi:g} "
                           "metres per unit (0.001: millimetres)")
            self.intrinsics = (check_intrinsics(data["intrinsics"])
                               if data.get("intrinsics") is not None else None)
            info = data.get("info") or {}
            if not isinstance(info, dict):
                raise BadField("info must be an object")
            self.info = dict(info)
            self.start_pose = _planar(data.get("start_pose"), "start_pose")
        except BadField as err:
            raise RobotError(f"corrupt manifest: {err}", file=str(self.path)) from None
        if self.version == 1:
            self.captures, self.actions = self._version1(data)
        else:
            self.captures = []
            for n, c in _json_lines(self.dir / CAPTURES):
                if len(self.captures) == MAX_CAPTURES:
                    raise RobotError(f"more than {MAX_CAPTURES} captures",
                                     file=str(self.dir / CAPTURES), line=n)
                try:
                    self.captures.append(_capture(c, len(self.captures)))
                except BadField as err:
                    raise RobotError(f"capture {len(self.captures)}: {err}",
                                     file=str(self.dir / CAPTURES), line=n) from None
            self.actions = self._actions_v2(_json_lines(self.dir / ACTIONS))
        if self.captures and self.intrinsics is None:
            raise RobotError("corrupt manifest: captures without intrinsics", file=str(self.path))
        if check_frames:
            self._check_frames()

    def _version1(self, data: dict):
        captures = data.get("captures")
        actions = data.get("actions", [])
        if not isinstance(captures, list) or not isinstance(actions, list):
            raise RobotError("corrupt manifest: captures and actions must be lists",
                             file=str(self.path))
        if len(captures) > MAX_CAPTURES:
            raise RobotError(f"corrupt manifest: more than {MAX_CAPTURES} captures",
                             file=str(self.path))
        out = []
        for c in captures:
            try:
                out.append(_capture(c, len(out)))
            except BadField as err:
                raise RobotError(f"corrupt manifest: capture {len(out)}: {err}",
                                 file=str(self.path)) from None
        if not all(isinstance(a, dict) for a in actions):
            raise RobotError("corrupt manifest: every action must be an object",
                             file=str(self.path))
        return out, [dict(a) for a in actions]

    def _actions_v2(self, lines) -> list[dict]:
        path = str(self.dir / ACTIONS)
        actions: dict[int, dict] = {}
        for n, a in lines:
            k = a.get("i") if isinstance(a, dict) else None
            if isinstance(k, bool) or not isinstance(k, int):
                raise RobotError("corrupt line: an action needs its number i", file=path, line=n)
            if "action" in a:
                if not isinstance(a["action"], str):
                    raise RobotError("corrupt line: action must be a name", file=path, line=n)
                actions[k] = {key: v for key, v in a.items() if key != "i"}
            elif k in actions:
                actions[k]["status"] = a.get("status")
                actions[k]["reason"] = a.get("reason", "")
            else:
                raise RobotError(f"corrupt line: outcome of unknown action {k}", file=path, line=n)
        return [actions[k] for k in sorted(actions)]

    def _check_frames(self) -> None:
        """Every frame file present, inside the folder, a complete PNG of the right kind and
        size (in two threads: zlib releases the GIL). A file several captures name is checked
        once, for the first of them (20,000 captures of one frame opened in minutes)."""
        K = self.intrinsics
        seen: set[tuple[str, str]] = set()
        todo: list[tuple[Capture, str, Any]] = []
        for c in self.captures:
            for name, check in ((c.color, check_color_png), (c.depth, check_depth_png)):
                if (name, check.__name__) not in seen:
                    seen.add((name, check.__name__))
                    todo.append((c, name, check))

        def one(item) -> None:
            c, name, check = item
            where = str(self.dir / name)
            try:
                info = check(inside(self.dir, name).read_bytes())
            except FrameFileError as err:
                raise RobotError(f"frame {c.index} is missing" if str(err) == "missing"
                                 else f"frame {c.index}: {err}", file=where) from None
            except OSError as err:
                raise RobotError(f"frame {c.index}: unreadable ({err.strerror})",
                                 file=where) from None
            if (info.width, info.height) != (K.width, K.height):
                raise RobotError(f"frame {c.index}: image is {info.width}x{info.height}, the "
                                 f"intrinsics say {K.width}x{K.height}", file=where)

        if len(todo) <= 8:
            for item in todo:
                one(item)
            return
        with ThreadPoolExecutor(max_workers=2) as pool:
            list(pool.map(one, todo))      # the first problem (in order) is raised

    def __len__(self) -> int:
        return len(self.captures)

    def frame(self, i: int) -> Frame:
        """Capture ``i`` (its position) as a Frame (colour and depth loaded from their PNGs)."""
        c = self.captures[i]
        images = []
        for name, decode in ((c.color, decode_color), (c.depth, decode_depth)):
            try:
                images.append(decode(inside(self.dir, name).read_bytes()))
            except FrameFileError as err:
                raise RobotError(f"frame {c.index} is missing" if str(err) == "missing"
                                 else f"frame {c.index}: {err}", file=str(self.dir / name)) from None
            except OSError as err:
                raise RobotError(f"frame {c.index}: unreadable ({err.strerror})",
                                 file=str(self.dir / name)) from None
        rgb, raw = images
        K = self.intrinsics
        if raw.shape != (K.height, K.width) or rgb.shape[:2] != (K.height, K.width):
            raise RobotError(f"frame {c.index}: image size differs from the intrinsics "
                             f"({K.width}x{K.height})", file=str(self.dir / c.depth))
        return Frame(color=rgb, depth=(raw.astype(np.float32) * np.float32(self.depth_scale)),
                     intrinsics=K, T_world_camera=c.T_world_camera.copy(), timestamp=c.timestamp,
                     pan=c.pan, tilt=c.tilt, base_pose=c.base_pose,
                     T_world_camera_true=c.T_world_camera_true, base_pose_true=c.base_pose_true,
                     parking=c.parking)


def open_recording(path, topics=None, check_frames: bool = True):
    """A recording to replay: a Hearth recording directory (``Recording``), or a ROS 2 bag
    (an ``.mcap`` file, or a rosbag2 directory with ``metadata.yaml``:
    ``hearth.robot.rosbag.BagRecording``, with the topic and frame mapping ``topics``)."""
    p = Path(path)
    if p.suffix in (".mcap", ".db3") or (p.is_dir() and (p / "metadata.yaml").is_file()) \
            or (p.is_dir() and not (p / MANIFEST).exists() and any(p.glob("*.mcap"))):
        from hearth.robot.rosbag import BagRecording
        return BagRecording(p, topics=topics)
    if topics is not None:
        raise RobotError("--topics maps a ROS 2 bag's topics; this is a Hearth recording",
                         file=str(p))
    return Recording(p, check_frames=check_frames)


# -- recording any adapter -------------------------------------------------------------------

class _LoggedAction(Action):
    """An action proxy that appends its outcome to the recording's action log."""

    def __init__(self, inner: Action, k: int, writer):
        self._inner, self._k, self._writer = inner, k, writer
        self._logged = False
        self.name = getattr(inner, "name", "action")

    def status(self) -> str:
        s = self._inner.status()
        if s != "running" and not self._logged:
            self._logged = True
            self._writer.action_done(self._k, s, getattr(self._inner, "reason", ""))
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
FORMATS = ("hearth", "mcap")


class RecordingRobot:
    """Any adapter, with every capture written to a recording and every action logged.

    ``format``: ``hearth`` (a recording directory, docs/recording-format.md) or ``mcap``
    (a ROS 2 bag, docs/ros2-foxglove.md; needs the ``ros`` extra)."""

    def __init__(self, inner, directory, info: Optional[dict] = None, format: str = "hearth"):
        self.inner = inner
        K = getattr(inner, "intrinsics", None)
        if format == "hearth":
            self.writer = RecordingWriter(directory, K, info)
        elif format == "mcap":
            from hearth.robot.rosbag import BagWriter
            self.writer = BagWriter(directory, K, info)
        else:
            raise RobotError(f"unknown recording format {format!r} (known: {', '.join(FORMATS)})")
        self._goal = None
        try:
            self.writer.set_start_pose(inner.base_pose())
        except (AttributeError, RobotError):
            pass

    def capture(self):
        """The inner adapter's frame, recorded; the mission gets the depth as the recording
        keeps it (whole millimetres, both formats), so that a replay sees what the recorded
        run saw and perception decides the same way on both."""
        frame = self.inner.capture()
        self.writer.add(frame, goal=self._goal)
        depth = depth_to_mm(frame.depth).astype(np.float32) * np.float32(DEPTH_SCALE)
        return replace(frame, depth=depth)

    def stop(self) -> None:
        self.inner.stop()
        self._log("stop", {})

    def close(self) -> None:
        self.writer.close()

    def _log(self, name: str, args: dict) -> int:
        clock = getattr(self.inner, "clock", None)
        t = clock.now() if clock is not None else None
        return self.writer.log_action(dict(time=t, action=name, args=args))

    def __getattr__(self, name):
        attr = getattr(self.inner, name)
        if name not in _LOGGED or not callable(attr):
            return attr

        def call(*args, **kwargs):
            k = self._log(name, _jsonable(dict(enumerate(args)) | kwargs))
            if name == "navigate_to" and args:
                self._goal = args[0]
            out = attr(*args, **kwargs)
            if isinstance(out, Action) or hasattr(out, "status"):
                logged = _LoggedAction(out, k, self.writer)
                logged.status()           # refused or instant requests end at once
                return logged
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

class ReplayRobot(PanTiltHead, SpokenAndLogged):
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
        self.recording = (recording if hasattr(recording, "captures")
                          else open_recording(recording))
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

    def battery_state(self):
        """A recording carries no battery: reported full, never docked."""
        from hearth.robot.battery import BatteryState
        return BatteryState(1.0)

    def dock(self) -> Action:
        return self._replayed("dock")

    def undock(self) -> Action:
        return self._replayed("undock")

    def stop(self) -> None:
        self.stops += 1
        for a in self._actions:
            a.cancel()
        self._log("stop")


__all__ = ["Capture", "Recording", "RecordingRobot", "RecordingWriter", "ReplayRobot",
           "FailedAction", "VERSION", "open_recording"]
