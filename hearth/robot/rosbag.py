"""ROS 2 bags as recordings: replay a bag's RGB-D frames through tf, and record runs as bags.

Reading and writing use ``rosbags`` (pure Python, no ROS installation): a bag is an ``.mcap``
file, or a rosbag2 directory (``metadata.yaml`` with MCAP or sqlite3 storage). See
docs/ros2-foxglove.md for the topics, the mapping and what is refused.

- ``TopicMap``: which topics are the depth image, the colour image and the camera info, and
  which tf frames are the map, the base and the camera. ``load_topic_map`` reads it from
  ``--topics`` (a YAML file or ``key=value,...``) or the bag's side file
  (``NAME.topics.yaml`` beside ``NAME.mcap``; ``topics.yaml`` in a bag directory).
- ``BagRecording``: a bag read and checked whole when opened, shaped like
  ``hearth.robot.recording.Recording`` so that ``ReplayRobot`` serves it. Every depth image
  (``16UC1`` millimetres or ``32FC1`` metres) is paired with the colour image (``rgb8`` or
  ``bgr8``, or ``CompressedImage`` jpeg/png and compressedDepth) nearest in stamp; depth
  not registered to colour is registered from both camera_infos and tf, distortion is
  undone with OpenCV. Its camera and base poses are looked up in tf at the image's stamp,
  interpolated.
- ``BagWriter``: what ``RecordingRobot(..., format="mcap")`` writes: the standard topics
  (``sensor_msgs/msg/Image``, ``CameraInfo``, ``tf2_msgs/msg/TFMessage``) and Hearth's extras
  on their own topics with their own message definitions (``hearth_msgs/msg/...``).

Every problem with a bag is one ``RobotError`` line naming the bag and the topic or frame.
"""
from __future__ import annotations

import json
import math
import os
import stat
import threading
from bisect import bisect_left
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Optional

import numpy as np

from hearth.robot.adapter import as_base_pose
from hearth.robot.errors import RobotError
from hearth.util.files import BadJSON, load_json, read_limited
from hearth.robot.captures import (BadField, Capture, check_intrinsics, depth_to_mm,
                                   frame_entry)
from hearth.worldmodel.validate import MAX_COORD
from hearth.robot.sim import Frame
from hearth.worldmodel.pose import Pose

INSTALL = "pip install 'hearth[ros]' (rosbags, mcap, mcap-ros2-support, foxglove-sdk)"

#: Default topics, tried in order when the mapping does not name one (registered depth first,
#: raw before compressed).
DEPTH_TOPICS = ("/camera/aligned_depth_to_color/image_raw", "/camera/depth_registered/image_raw",
                "/camera/depth_registered/image_rect", "/camera/depth/image_raw",
                "/camera/depth/image_rect_raw",
                "/camera/aligned_depth_to_color/image_raw/compressedDepth",
                "/camera/depth/image_rect_raw/compressedDepth")
COLOR_TOPICS = ("/camera/color/image_raw", "/camera/rgb/image_raw", "/camera/rgb/image_rect_color",
                "/camera/color/image_raw/compressed", "/camera/color/image_rect_color/compressed")
INFO_TOPICS = ("/camera/color/camera_info", "/camera/rgb/camera_info")
#: The depth camera's own info, needed only when depth is not registered to colour.
DEPTH_INFO_TOPICS = ("/camera/depth/camera_info", "/camera/aligned_depth_to_color/camera_info")
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
#: Distortion models OpenCV undistorts (ROS's plumb_bob is OpenCV's 5 coefficients).
DISTORTION_MODELS = ("plumb_bob", "rational_polynomial", "")
#: What Hearth writes (and reads back).
WRITE = dict(depth="/camera/depth/image_raw", color="/camera/color/image_raw",
             camera_info="/camera/color/camera_info", tf="/tf", tf_static="/tf_static")
CAMERA_FRAME, BASE_FRAME, ODOM_FRAME, MAP_FRAME = ("camera_color_optical_frame", "base_link",
                                                  "odom", "map")
EXTRAS = dict(capture="/hearth/capture", truth="/hearth/truth", actions="/hearth/actions",
              events="/hearth/events", info="/hearth/info")
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
#: A 32FC1 depth beyond this many metres is refused (no RGB-D camera sees a kilometre; 3.4e38
#: is a float's largest, not a distance). NaN and +-inf mean "no reading" (REP 118).
MAX_DEPTH_M = 1000.0
#: A topic mapping is a few lines; a bag's metadata.yaml a few kilobytes per topic.
MAX_TOPIC_MAP_BYTES = 64 << 10
MAX_METADATA_BYTES = 16 << 20
COLOR_ENCODINGS = ("rgb8", "bgr8")

#: Hearth's own message definitions (ROS 2 .msg syntax), written into every bag it records.
HEARTH_MSGS = {
    "hearth_msgs/msg/CaptureInfo": """\
# One capture: its number, the parking position and navigation goal it was taken at, the head.
std_msgs/Header header
uint32 index
string parking
bool has_goal
geometry_msgs/Pose2D goal
float64 pan
float64 tilt
""",
    "hearth_msgs/msg/GroundTruth": """\
# Simulation only: where the robot and the camera truly were when capture `index` was taken.
std_msgs/Header header
uint32 index
geometry_msgs/Pose2D base_pose
geometry_msgs/Pose camera_pose
""",
    "hearth_msgs/msg/RobotAction": """\
# A request made of the robot (status "requested"), and later its outcome, by `number`.
std_msgs/Header header
uint32 number
string action
string args_json
string status
string reason
""",
    "hearth_msgs/msg/MissionEvent": """\
# One execution-log event of the mission (docs/missions.md): kind, run, tick, tree path, data.
std_msgs/Header header
string run
string kind
uint32 tick
string path
string data_json
""",
    "hearth_msgs/msg/RecordingInfo": """\
# Provenance (mission, world, scenario, parameters, seed) and the believed start pose.
std_msgs/Header header
string info_json
bool has_start_pose
geometry_msgs/Pose2D start_pose
""",
}


def require_ros() -> None:
    """RobotError (one line saying what to install) unless the ``ros`` extra is installed."""
    try:
        import rosbags.highlevel  # noqa: F401
        import rosbags.rosbag2  # noqa: F401
    except ImportError:
        raise RobotError(f"reading and writing ROS 2 bags needs the ros extra: {INSTALL}") from None


def typestore():
    """The ROS 2 Humble message types plus Hearth's."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for name, text in HEARTH_MSGS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


# -- the mapping -------------------------------------------------------------------------------

@dataclass(frozen=True)
class TopicMap:
    """Topics and frames of a bag (None: the first default topic the bag has; the camera
    frame None: the images' ``frame_id``). ``sync_tolerance``: seconds between a depth and a
    colour stamp for them to pair; ``tf_tolerance``: seconds a stamp may lie outside the tf
    data of a moving frame and still use its first or last transform."""
    depth: Optional[str] = None
    color: Optional[str] = None
    camera_info: Optional[str] = None
    depth_info: Optional[str] = None
    map_frame: str = MAP_FRAME
    base_frame: str = BASE_FRAME
    camera_frame: Optional[str] = None
    tf: str = "/tf"
    tf_static: str = "/tf_static"
    sync_tolerance: float = 0.02
    tf_tolerance: float = 0.05
    # A live robot (hearth/robot/ros2_live.py) reads the same mapping; bag replay ignores these.
    odom_frame: str = ODOM_FRAME
    navigate_action: str = "/navigate_to_pose"
    task_action: str = "/hearth/robot_task"
    head_command: str = "/head_controller/joint_trajectory"
    joint_states: str = "/joint_states"
    head_pan_joint: str = "head_pan_joint"
    head_tilt_joint: str = "head_tilt_joint"
    initial_pose: str = "/initialpose"
    battery: str = "/battery_state"
    say: str = "/hearth/say"
    link_timeout: float = 3.0          # no tf for this long (s): the link is lost
    connect_timeout: float = 10.0      # no NavigateToPose server and tf within this (s): refused


_KEYS = {f.name for f in fields(TopicMap)}


def _topic_map(values: dict, where: str) -> TopicMap:
    if not isinstance(values, dict):
        raise RobotError("a topic mapping is a mapping of keys to topics or frames "
                         f"(keys: {', '.join(sorted(_KEYS))})", file=where)
    out = {}
    for k, v in values.items():
        if k not in _KEYS:
            raise RobotError(f"unknown key {k!r} in the topic mapping (keys: "
                             f"{', '.join(sorted(_KEYS))})", file=where)
        if k.endswith(("tolerance", "timeout")):
            try:
                v = float(v)
            except (TypeError, ValueError):
                v = math.nan
            if not (math.isfinite(v) and 0 <= v <= 10):
                raise RobotError(f"{k} must be a number of seconds between 0 and 10", file=where)
        elif not isinstance(v, str) or not v:
            raise RobotError(f"{k} must be a topic or frame name", file=where)
        out[k] = v
    return TopicMap(**out)


def side_file(bag: Path) -> Path:
    """Where a bag's topic mapping is looked for when ``--topics`` is not given."""
    return bag / "topics.yaml" if bag.is_dir() else bag.with_suffix(".topics.yaml")


def load_topic_map(spec=None, bag=None) -> TopicMap:
    """The mapping from ``spec`` (a TopicMap, a dict, a YAML file path or ``key=value,...``)
    or, when None, from the bag's side file, or the defaults."""
    if isinstance(spec, TopicMap):
        return spec
    if isinstance(spec, dict):
        return _topic_map(spec, "--topics")
    if spec is None:
        if bag is None or not os.path.lexists(side_file(Path(bag))):
            return TopicMap()
        spec = str(side_file(Path(bag)))
    text = str(spec)
    if "\x00" in text:
        raise RobotError("a topic mapping holds a NUL byte", file="--topics")
    if "=" in text and not os.path.lexists(text):
        pairs = {}
        for item in text.split(","):
            k, sep, v = item.partition("=")
            if not sep:
                raise RobotError(f"expected KEY=VALUE, got {item!r}", file="--topics")
            pairs[k.strip()] = v.strip()
        return _topic_map(pairs, "--topics")
    import yaml
    data = read_limited(text, MAX_TOPIC_MAP_BYTES, RobotError,
                        f"larger than {MAX_TOPIC_MAP_BYTES >> 10} KiB (a topic mapping is a "
                        "few lines)")
    try:
        values = yaml.safe_load(data.decode("utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        line = getattr(getattr(err, "problem_mark", None), "line", None)
        raise RobotError(f"not a YAML mapping: {getattr(err, 'problem', err)}", file=text,
                         line=None if line is None else line + 1) from None
    except RecursionError:
        raise RobotError("not a YAML mapping: nested too deeply (a topic mapping is flat)",
                         file=text) from None
    return _topic_map(values or {}, text)


# -- tf ------------------------------------------------------------------------------------

def _T(t, q) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q).as_matrix()       # scipy: (x, y, z, w), as ROS
    T[:3, 3] = t
    return T


class TfBuffer:
    """The frames of a bag's /tf and /tf_static: a tree, each frame with one parent, static
    transforms and time-stamped ones, looked up between any two frames at a stamp with the
    translation interpolated linearly and the rotation by slerp, never extrapolated beyond
    ``tolerance`` seconds. Written here because tf2 itself needs a ROS installation."""

    def __init__(self, tolerance_ns: int = 0):
        self.parent: dict[str, str] = {}
        self.static: dict[str, np.ndarray] = {}
        self._samples: dict[str, list] = {}
        self._edges: dict[str, tuple] = {}
        self.tolerance_ns = int(tolerance_ns)

    def add(self, parent: str, child: str, stamp_ns: int, t, q, static: bool) -> None:
        t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
        if not (np.isfinite(t).all() and np.isfinite(q).all()) or np.linalg.norm(q) < 1e-6:
            raise BadField(f"the transform {parent} -> {child} at {stamp_ns * 1e-9:.3f} s has "
                       "numbers that are not finite (or a zero quaternion)")
        known = self.parent.get(child)
        if known is not None and known != parent:
            raise BadField(f"frame {child} has two parents in tf ({known} and {parent})")
        self.parent[child] = parent
        if static:
            self.static[child] = _T(t, q / np.linalg.norm(q))
        else:
            self._samples.setdefault(child, []).append((int(stamp_ns), t, q / np.linalg.norm(q)))
        self._edges.pop(child, None)

    def frames(self) -> set[str]:
        return set(self.parent) | set(self.parent.values())

    def _chain(self, frame: str) -> list[str]:
        out = [frame]
        while out[-1] in self.parent and len(out) <= len(self.parent):
            out.append(self.parent[out[-1]])
        return out

    def _edge(self, child: str, stamp_ns: int) -> np.ndarray:
        """T_parent_child at a stamp (static edges: at any stamp)."""
        if child in self.static:
            return self.static[child]
        edge = self._edges.get(child)
        if edge is None:
            from scipy.spatial.transform import Rotation, Slerp
            samples = sorted(self._samples[child], key=lambda s: s[0])
            times = [s[0] for s in samples]
            rot = Rotation.from_quat([s[2] for s in samples])
            slerp = Slerp(np.asarray(times, dtype=float), rot) if len(times) > 1 else None
            edge = (times, np.array([s[1] for s in samples]), rot, slerp)
            self._edges[child] = edge
        times, trans, rot, slerp = edge
        tol = self.tolerance_ns
        if stamp_ns < times[0] - tol or stamp_ns > times[-1] + tol:
            raise LookupError(f"{self.parent[child]} -> {child}")
        s = min(max(stamp_ns, times[0]), times[-1])
        T = np.eye(4)
        if slerp is None:
            T[:3, :3], T[:3, 3] = rot.as_matrix()[0], trans[0]
            return T
        i = min(max(bisect_left(times, s), 1), len(times) - 1)
        a = (s - times[i - 1]) / max(times[i] - times[i - 1], 1)
        T[:3, 3] = trans[i - 1] + (trans[i] - trans[i - 1]) * a
        T[:3, :3] = slerp([float(s)]).as_matrix()[0]
        return T

    def connected(self, target: str, source: str) -> bool:
        return self._chain(target)[-1] == self._chain(source)[-1]

    def lookup(self, target: str, source: str, stamp_ns: int) -> np.ndarray:
        """``T_target_source`` at ``stamp_ns``; LookupError naming the edge whose data does
        not cover the stamp."""
        up_s, up_t = self._chain(source), self._chain(target)
        common = next(f for f in up_s if f in up_t)
        T_common_source = np.eye(4)
        for f in up_s[:up_s.index(common)]:
            T_common_source = self._edge(f, stamp_ns) @ T_common_source
        T_common_target = np.eye(4)
        for f in up_t[:up_t.index(common)]:
            T_common_target = self._edge(f, stamp_ns) @ T_common_target
        return np.linalg.inv(T_common_target) @ T_common_source


# -- reading -----------------------------------------------------------------------------------

def _check_bag_files(source: Path) -> None:
    """Refuse a bag whose files are not regular files (a FIFO would block the reader, a link
    to /dev/zero never end) or whose metadata.yaml is absurdly large, before rosbags opens
    anything."""
    paths = [source]
    if source.is_dir():
        meta = source / "metadata.yaml"
        read_limited(meta, MAX_METADATA_BYTES, RobotError,
                     f"larger than {MAX_METADATA_BYTES >> 20} MiB")
        paths = sorted(p for p in source.iterdir() if p.suffix in (".mcap", ".db3"))
    for p in paths:
        try:
            st = os.stat(p)
        except FileNotFoundError:
            raise RobotError("no such bag file", file=str(p)) from None
        except (OSError, ValueError) as err:
            raise RobotError(f"cannot read the bag ({getattr(err, 'strerror', None) or err})",
                             file=str(p)) from None
        if not stat.S_ISREG(st.st_mode):
            raise RobotError("not a regular file (a bag is an .mcap file or a rosbag2 "
                             "directory)", file=str(p))


def _stamp(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


@dataclass
class _Image:
    log_ns: int
    stamp_ns: int
    frame_id: str
    width: int
    height: int
    encoding: str
    compressed: bool = False


@dataclass(frozen=True)
class _Camera:
    """A camera_info: pinhole intrinsics and the distortion OpenCV undistorts (None: none)."""
    K: Any
    D: Optional[np.ndarray]
    model: str


def decode_compressed(msg, what: str) -> np.ndarray:
    """A ``sensor_msgs/CompressedImage`` as an array: colour (jpeg/png) as RGB uint8; depth
    as metres (float32, 0 = no reading) from ``compressed_depth_image_transport``'s format
    (a 12-byte header, then a PNG of 16UC1 millimetres, or of quantised inverse depth for
    32FC1). ValueError when it does not decode."""
    import cv2
    fmt = str(msg.format)
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if "compressedDepth" in fmt:
        if data.size <= 12:
            raise ValueError("a compressedDepth image shorter than its 12-byte header")
        quant_a, quant_b = np.frombuffer(data[4:12].tobytes(), dtype="<f4")
        raw = cv2.imdecode(data[12:], cv2.IMREAD_UNCHANGED)
        if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
            raise ValueError(f"the compressedDepth PNG does not decode ({fmt})")
        if fmt.split(";")[0].strip() == "32FC1":
            v = raw.astype(np.float32)
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.where(v > 0, quant_a / (v - quant_b), 0.0).astype(np.float32)
            z[~np.isfinite(z) | (z < 0)] = 0
            return z
        return raw.astype(np.float32) * np.float32(0.001)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"the {what} image does not decode ({fmt or 'no format'})")
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.dtype != np.uint8:
        img = (img >> 8).astype(np.uint8)
    return np.ascontiguousarray(img[..., 2::-1])      # OpenCV decodes BGR(A)


class BagRecording:
    """A ROS 2 bag, read and checked whole, shaped like ``Recording`` (``captures``,
    ``actions``, ``intrinsics``, ``start_pose``, ``info``, ``frame(i)``, ``path``)."""

    def __init__(self, path, topics=None):
        require_ros()
        from rosbags.highlevel import AnyReader
        self.dir = self.path = Path(path)
        self.depth_scale = 0.001
        where = str(self.path)
        if not self.path.exists():
            raise RobotError("no such bag (an .mcap file or a rosbag2 directory)", file=where)
        self.topics = load_topic_map(topics, self.path)
        source = self.path
        if self.path.is_dir() and not os.path.lexists(self.path / "metadata.yaml"):
            files = sorted(self.path.glob("*.mcap"))
            if len(files) != 1:
                raise RobotError("a bag directory needs its metadata.yaml (or one .mcap file)",
                                 file=where)
            source = files[0]         # a bag whose recorder was killed before metadata.yaml
        _check_bag_files(source)
        self._lock = threading.Lock()
        try:
            self._reader = AnyReader([source], default_typestore=typestore())
            self._reader.open()
        except Exception as err:  # noqa: BLE001 - rosbags raises many kinds for a broken file
            raise RobotError(f"not a readable ROS 2 bag ({_reason(err)}); a truncated bag can "
                             "be repaired with `ros2 bag reindex` or `mcap recover`",
                             file=where) from None
        try:
            self._read()
        except BadField as err:
            self.close()
            raise RobotError(str(err), file=where) from None
        except RobotError:
            self.close()
            raise
        except Exception as err:  # noqa: BLE001
            self.close()
            raise RobotError(f"corrupt bag ({_reason(err)})", file=where) from None

    def close(self) -> None:
        reader, self._reader = getattr(self, "_reader", None), None
        if reader is not None and reader.stack is not None:
            reader.close()

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001
            pass

    def __len__(self) -> int:
        return len(self.captures)

    # ---- opening
    def _pick(self, name: str, given: Optional[str], defaults: tuple, present: dict) -> str:
        if given is not None:
            if given not in present:
                raise BadField(f"no {name} topic {given} in the bag (it has: "
                           f"{', '.join(sorted(present)) or 'no topics'})")
            return given
        for t in defaults:
            if t in present:
                return t
        raise BadField(f"no {name} topic: none of {', '.join(defaults)} is in the bag (it has: "
                   f"{', '.join(sorted(present)) or 'no topics'}); name it with --topics "
                   f"{name}=TOPIC")

    def _read(self) -> None:
        r, m = self._reader, self.topics
        present = {c.topic: c.msgtype for c in r.connections}
        depth_t = self._pick("depth", m.depth, DEPTH_TOPICS, present)
        color_t = self._pick("color", m.color, COLOR_TOPICS, present)
        info_t = self._pick("camera_info", m.camera_info, INFO_TOPICS, present)
        depth_info_t = m.depth_info or next((t for t in DEPTH_INFO_TOPICS if t in present
                                             and t != info_t), None)
        if m.depth_info is not None and m.depth_info not in present:
            raise BadField(f"no depth_info topic {m.depth_info} in the bag")
        for topic, want in ((depth_t, IMAGE_TYPES), (color_t, IMAGE_TYPES),
                            (info_t, ("sensor_msgs/msg/CameraInfo",)),
                            (depth_info_t, ("sensor_msgs/msg/CameraInfo",)),
                            (m.tf, ("tf2_msgs/msg/TFMessage",)),
                            (m.tf_static, ("tf2_msgs/msg/TFMessage",))):
            if topic in present and present[topic] not in want:
                raise BadField(f"topic {topic} is {present[topic]}; Hearth reads "
                           f"{' or '.join(want)} there")
        if m.tf not in present and m.tf_static not in present:
            raise BadField(f"no tf: neither {m.tf} nor {m.tf_static} is in the bag")
        self._conn = {t: [c for c in r.connections if c.topic == t] for t in (depth_t, color_t)}
        self._topic = dict(depth=depth_t, color=color_t)
        wanted = {depth_t, color_t, info_t, depth_info_t, m.tf, m.tf_static, *EXTRAS.values()}
        conns = [c for c in r.connections if c.topic in wanted]
        tf = TfBuffer(int(m.tf_tolerance * 1e9))
        depth, color, info, depth_info = [], [], None, None
        extras: dict[str, list] = {k: [] for k in EXTRAS}
        topic_of = {v: k for k, v in EXTRAS.items()}
        for conn, log_ns, raw in r.messages(connections=conns):
            topic = conn.topic
            try:
                msg = r.deserialize(raw, conn.msgtype)
            except Exception as err:  # noqa: BLE001
                raise BadField(f"topic {topic}: a message at {log_ns * 1e-9:.3f} s does not "
                           f"decode as {conn.msgtype} ({_reason(err)})") from None
            if topic in (m.tf, m.tf_static):
                for ts in msg.transforms:
                    tr, q = ts.transform.translation, ts.transform.rotation
                    tf.add(ts.header.frame_id, ts.child_frame_id, _stamp(ts.header),
                           (tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w), topic == m.tf_static)
            elif topic == depth_t:
                depth.append(self._check_image(msg, log_ns, topic, DEPTH_ENCODINGS, "depth",
                                               depth[0] if depth else None))
            elif topic == color_t:
                color.append(self._check_image(msg, log_ns, topic, COLOR_ENCODINGS, "colour",
                                               color[0] if color else None))
            elif topic == info_t:
                if info is None:
                    info = self._camera_info(msg, topic)
            elif topic == depth_info_t:
                if depth_info is None:
                    depth_info = self._camera_info(msg, topic)
            elif topic in topic_of:
                extras[topic_of[topic]].append(msg)
        if info is None:
            raise BadField(f"topic {info_t} has no CameraInfo message")
        if not depth:
            raise BadField(f"topic {depth_t} has no image")
        if not color:
            raise BadField(f"topic {color_t} has no image")
        self.intrinsics = info.K
        self._color_camera = info
        self._depth_camera = depth_info
        self._depth_info_topic = depth_info_t
        self._tf = tf
        self._pair(depth, color, tf, extras)

    def _check_image(self, msg, log_ns: int, topic: str, encodings, what: str,
                     first: Optional[_Image]) -> _Image:
        if not hasattr(msg, "encoding"):            # CompressedImage: sizes from the first
            if first is None:
                try:
                    a = decode_compressed(msg, what)
                except ValueError as err:
                    raise BadField(f"topic {topic}: the image at {log_ns * 1e-9:.3f} s: {err}") \
                        from None
                h, w = a.shape[:2]
            else:
                w, h = first.width, first.height
            return _Image(log_ns, _stamp(msg.header), str(msg.header.frame_id), w, h,
                          str(msg.format), compressed=True)
        enc = str(msg.encoding)
        if enc not in encodings:
            raise BadField(f"topic {topic}: {what} encoding {enc!r} is not supported (Hearth reads "
                       f"{what} in {' or '.join(e for e in encodings if e != 'mono16')})")
        bpp = {"16UC1": 2, "mono16": 2, "32FC1": 4, "rgb8": 3, "bgr8": 3}[enc]
        w, h, step = int(msg.width), int(msg.height), int(msg.step)
        if w <= 0 or h <= 0 or step < w * bpp or len(msg.data) != step * h:
            raise BadField(f"topic {topic}: an image at {log_ns * 1e-9:.3f} s has {len(msg.data)} "
                       f"bytes for {w}x{h} {enc} with step {step}")
        return _Image(log_ns, _stamp(msg.header), str(msg.header.frame_id), w, h, enc)

    def _camera_info(self, msg, topic: str):
        k = np.asarray(msg.k, dtype=float)
        try:
            K = check_intrinsics(dict(fx=float(k[0]), fy=float(k[4]), cx=float(k[2]),
                                      cy=float(k[5]), width=int(msg.width), height=int(msg.height)),
                                 what=f"topic {topic}: camera info")
        except (IndexError, ValueError, OverflowError):
            raise BadField(f"topic {topic}: camera info has no usable K matrix") from None
        d = np.asarray(msg.d, dtype=float)
        model = str(msg.distortion_model)
        if d.size and not np.isfinite(d).all():
            raise BadField(f"topic {topic}: distortion coefficients are not finite")
        if not d.size or np.abs(d).max() <= 1e-9:
            return _Camera(K, None, model)
        if model not in DISTORTION_MODELS or d.size not in (4, 5, 8, 12, 14):
            raise BadField(f"topic {topic}: distortion model {model!r} with {d.size} coefficients "
                       "is not one OpenCV undistorts (plumb_bob, rational_polynomial)")
        return _Camera(K, d, model)

    def _pair(self, depth: list, color: list, tf: TfBuffer, extras: dict) -> None:
        m, K = self.topics, self.intrinsics
        d0, c0 = depth[0], color[0]
        # Depth in the colour camera's frame and size is registered; otherwise it is moved
        # into the colour camera with both camera_infos and tf (hearth.perception.camera.
        # register_depth), as a RealSense driver's aligned_depth_to_color does.
        self._registered = d0.frame_id == c0.frame_id and \
            (d0.width, d0.height) == (c0.width, c0.height)
        if not self._registered:
            if self._depth_camera is None:
                raise BadField(f"depth {self._topic['depth']} (frame {d0.frame_id}, {d0.width}x"
                           f"{d0.height}) is not registered to colour {self._topic['color']} "
                           f"(frame {c0.frame_id}, {c0.width}x{c0.height}) and the bag has no "
                           f"depth camera_info ({', '.join(DEPTH_INFO_TOPICS)}) to register it "
                           "with; name it with --topics depth_info=TOPIC")
            if not tf.connected(c0.frame_id, d0.frame_id):
                raise BadField(f"no tf between the colour frame {c0.frame_id} and the depth frame "
                           f"{d0.frame_id}: depth cannot be registered to colour")
            Kd = self._depth_camera.K
            if (d0.width, d0.height) != (Kd.width, Kd.height):
                raise BadField(f"topic {self._topic['depth']}: images are {d0.width}x{d0.height}, "
                           f"the depth camera info says {Kd.width}x{Kd.height}")
        checks = ((c0, self._topic["color"]),) if not self._registered else \
            ((d0, self._topic["depth"]), (c0, self._topic["color"]))
        for img, topic in checks:
            if (img.width, img.height) != (K.width, K.height):
                raise BadField(f"topic {topic}: images are {img.width}x{img.height}, the camera "
                           f"info says {K.width}x{K.height}")
        for imgs, topic, i0 in ((depth, self._topic["depth"], d0),
                                (color, self._topic["color"], c0)):
            for img in imgs:
                if (img.frame_id, img.width, img.height) != (i0.frame_id, i0.width, i0.height):
                    raise BadField(f"topic {topic}: an image at {img.log_ns * 1e-9:.3f} s changes "
                               f"frame or size ({img.frame_id}, {img.width}x{img.height})")
        camera = m.camera_frame or c0.frame_id
        self._color_frame, self._depth_frame = c0.frame_id, d0.frame_id
        for frame in (m.map_frame, m.base_frame, camera):
            if frame not in tf.frames():
                raise BadField(f"no frame {frame} in tf (tf has: {', '.join(sorted(tf.frames()))})")
        for frame in (m.base_frame, camera):
            if not tf.connected(m.map_frame, frame):
                raise BadField(f"no tf between {m.map_frame} and {frame}: they are in separate "
                           "trees")
        color_stamps = [c.stamp_ns for c in color]
        order = sorted(range(len(color)), key=lambda i: color_stamps[i])
        sorted_stamps = [color_stamps[i] for i in order]
        tol = int(m.sync_tolerance * 1e9)
        info = extras["capture"]
        by_stamp = {_stamp(x.header): x for x in info}
        truth = {_stamp(x.header): x for x in extras["truth"]}
        self.captures, self._images = [], []
        unpaired = untimed = 0
        missing_edge = None
        for d in sorted(depth, key=lambda x: x.stamp_ns):
            j = bisect_left(sorted_stamps, d.stamp_ns)
            near = [k for k in (j - 1, j) if 0 <= k < len(order)]
            k = min(near, key=lambda k: abs(sorted_stamps[k] - d.stamp_ns))
            if abs(sorted_stamps[k] - d.stamp_ns) > tol:
                unpaired += 1
                continue
            try:
                T_map_camera = tf.lookup(m.map_frame, camera, d.stamp_ns)
                T_map_base = tf.lookup(m.map_frame, m.base_frame, d.stamp_ns)
            except LookupError as err:
                untimed += 1
                missing_edge = str(err)
                continue
            if not (np.isfinite(T_map_camera).all() and np.isfinite(T_map_base).all()
                    and np.abs(T_map_camera[:3, 3]).max() <= MAX_COORD
                    and np.abs(T_map_base[:3, 3]).max() <= MAX_COORD):
                raise BadField(f"tf: the pose of {camera} or {m.base_frame} at "
                           f"{d.stamp_ns * 1e-9:.3f} s is not finite or beyond +-{MAX_COORD:g} m")
            base = as_base_pose(T_map_base)
            T_base_camera = np.linalg.inv(T_map_base) @ T_map_camera
            z = T_base_camera[:3, 2]                       # optical axis in the base frame
            pan, tilt = math.atan2(z[1], z[0]), math.asin(float(np.clip(-z[2], -1, 1)))
            ci, gt = by_stamp.get(d.stamp_ns), truth.get(d.stamp_ns)
            parking = goal = None
            if ci is not None:
                pan, tilt = float(ci.pan), float(ci.tilt)
                parking = str(ci.parking) or None
                goal = Pose.planar(ci.goal.x, ci.goal.y, ci.goal.theta) if ci.has_goal else None
            bt = Tt = None
            if gt is not None:
                bt = Pose.planar(gt.base_pose.x, gt.base_pose.y, gt.base_pose.theta)
                p, q = gt.camera_pose.position, gt.camera_pose.orientation
                Tt = _T((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
            self.captures.append(Capture(
                index=len(self.captures), timestamp=d.stamp_ns * 1e-9,
                color=f"{self._topic['color']}@{sorted_stamps[k]}",
                depth=f"{self._topic['depth']}@{d.stamp_ns}", base_pose=base,
                T_world_camera=T_map_camera, pan=pan, tilt=tilt, parking=parking, goal=goal,
                base_pose_true=bt, T_world_camera_true=Tt))
            self._images.append((d, color[order[k]]))
        if not self.captures:
            if unpaired and not untimed:
                raise BadField(f"no colour image on {self._topic['color']} within "
                           f"{m.sync_tolerance * 1000:.0f} ms of any depth image on "
                           f"{self._topic['depth']}")
            raise BadField(f"no tf between {m.map_frame} and {camera} at any image stamp (the "
                       f"transform {missing_edge} does not cover the images' times)")
        self.skipped = dict(unpaired=unpaired, outside_tf=untimed)
        self.actions = _actions(extras["actions"])
        self.info, self.start_pose = {}, None
        if extras["info"]:
            last = extras["info"][-1]
            try:
                info = load_json(str(last.info_json) or "{}")
            except BadJSON:
                info = {}
            self.info = info if isinstance(info, dict) else {}
            if last.has_start_pose:
                sp = last.start_pose
                self.start_pose = Pose.planar(sp.x, sp.y, sp.theta)

    # ---- serving
    def _image(self, img: _Image, topic: str) -> np.ndarray:
        with self._lock:
            if self._reader is None:
                raise RobotError("the bag is closed", file=str(self.path))
            msg = None
            for conn, _, raw in self._reader.messages(connections=self._conn[topic],
                                                      start=img.log_ns, stop=img.log_ns + 1):
                cand = self._reader.deserialize(raw, conn.msgtype)
                if _stamp(cand.header) == img.stamp_ns:
                    msg = cand
                    break
        if msg is None:
            raise RobotError(f"topic {topic}: the image at {img.log_ns * 1e-9:.3f} s is gone",
                             file=str(self.path))
        if img.compressed:
            try:
                a = decode_compressed(msg, "depth" if topic == self._topic["depth"] else
                                      "colour")
            except ValueError as err:
                raise RobotError(f"topic {topic}: the image at {img.log_ns * 1e-9:.3f} s: {err}",
                                 file=str(self.path)) from None
            if a.shape[:2] != (img.height, img.width):
                raise RobotError(f"topic {topic}: the image at {img.log_ns * 1e-9:.3f} s is "
                                 f"{a.shape[1]}x{a.shape[0]}, not {img.width}x{img.height}",
                                 file=str(self.path))
            return a
        data = np.asarray(msg.data, dtype=np.uint8)
        h, w, step = img.height, img.width, int(msg.step)
        rows = data.reshape(h, step)
        enc = img.encoding
        if enc in ("rgb8", "bgr8"):
            rgb = rows[:, :w * 3].reshape(h, w, 3)
            return np.ascontiguousarray(rgb if enc == "rgb8" else rgb[..., ::-1])
        big = bool(msg.is_bigendian)
        if enc == "32FC1":
            z = rows[:, :w * 4].copy().view(">f4" if big else "<f4").reshape(h, w).astype(np.float32)
            z[~np.isfinite(z) | (z < 0)] = 0            # REP 118: NaN / inf mean no reading
            if z.size and float(z.max()) > MAX_DEPTH_M:
                raise RobotError(f"topic {topic}: the depth image at {img.log_ns * 1e-9:.3f} s "
                                 f"has a depth of {float(z.max()):.3g} m (at most "
                                 f"{MAX_DEPTH_M:g} m; NaN or inf for no reading)",
                                 file=str(self.path))
            return z
        mm = rows[:, :w * 2].copy().view(">u2" if big else "<u2").reshape(h, w)
        return mm.astype(np.float32) * np.float32(0.001)

    def frame(self, i: int) -> Frame:
        """Capture ``i`` as a Frame (depth in metres, 0 = no reading; colour RGB)."""
        c = self.captures[i]
        d, col = self._images[i]
        color = self._image(col, self._topic["color"])
        depth = self._image(d, self._topic["depth"])
        if not self._registered:
            cam = self._depth_camera
            if cam.D is not None:
                depth = _undistort(depth, cam, nearest=True)
            T_color_depth = self._tf.lookup(self._color_frame, self._depth_frame, d.stamp_ns)
            from hearth.perception.camera import register_depth
            depth = register_depth(depth, cam.K, self.intrinsics, T_color_depth)
            if self._color_camera.D is not None:
                # register_depth projected with the pinhole model: move it to where the
                # distorted colour pixels are, so that both are undistorted alike below.
                depth = _distort(depth, self._color_camera)
        if self._color_camera.D is not None:
            color = _undistort(color, self._color_camera, nearest=False)
            depth = _undistort(depth, self._color_camera, nearest=True)
        return Frame(color=color, depth=depth, intrinsics=self.intrinsics,
                     T_world_camera=c.T_world_camera.copy(), timestamp=c.timestamp, pan=c.pan,
                     tilt=c.tilt, base_pose=c.base_pose, T_world_camera_true=c.T_world_camera_true,
                     base_pose_true=c.base_pose_true, parking=c.parking)


def _undistort(img: np.ndarray, cam: _Camera, nearest: bool) -> np.ndarray:
    """``img`` as the pinhole camera ``cam.K`` sees it (OpenCV's undistortion maps; nearest
    neighbour for depth, so that no reading is blended with another or with a hole)."""
    import cv2
    K = cam.K.matrix()
    mx, my = cv2.initUndistortRectifyMap(K, cam.D, None, K, (cam.K.width, cam.K.height),
                                         cv2.CV_32FC1)
    return cv2.remap(img, mx, my, cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _distort(img: np.ndarray, cam: _Camera) -> np.ndarray:
    """The inverse of :func:`_undistort` for a depth image: a pinhole image resampled at the
    distorted camera's pixels (each distorted pixel undistorted with cv2.undistortPoints)."""
    import cv2
    w, h = cam.K.width, cam.K.height
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    pts = np.stack([u.ravel(), v.ravel()], axis=1)[:, None, :]
    K = cam.K.matrix()
    und = cv2.undistortPoints(pts, K, cam.D, P=K).reshape(h, w, 2)
    return cv2.remap(img, und[..., 0], und[..., 1], cv2.INTER_NEAREST,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _actions(msgs) -> list[dict]:
    out: dict[int, dict] = {}
    for a in msgs:
        k = int(a.number)
        if a.status == "requested" or k not in out:
            try:
                args = load_json(str(a.args_json) or "{}")
            except BadJSON:
                args = {}
            out.setdefault(k, dict(time=_stamp(a.header) * 1e-9, action=str(a.action), args=args))
        if a.status != "requested":
            out[k]["status"], out[k]["reason"] = str(a.status), str(a.reason)
    return [out[k] for k in sorted(out)]


def _reason(err: BaseException) -> str:
    text = " ".join(str(err).split()) or type(err).__name__
    return text[:200]


# -- writing ---------------------------------------------------------------------------------

class BagWriter:
    """Writes a recording as a ROS 2 bag (rosbag2 directory, MCAP storage, version 9).

    Per capture, at its stamp: ``/tf`` (odom -> base_link: the believed base pose;
    base_link -> camera_color_optical_frame: the camera on the head), the depth image
    (``16UC1`` millimetres) and the colour image (``rgb8``), registered, in the camera frame,
    the camera info, and Hearth's ``/hearth/capture`` and ``/hearth/truth``; ``/tf_static``
    holds map -> odom (identity). Robot requests and their outcomes go on
    ``/hearth/actions``, mission events on ``/hearth/events`` (``event``), provenance on
    ``/hearth/info``. Captures in the same instant of a simulated clock are stamped 1 ms
    apart, so that tf stays a function of time."""

    def __init__(self, directory, intrinsics=None, info: Optional[dict] = None):
        require_ros()
        from rosbags.rosbag2 import StoragePlugin, Writer
        self.dir = Path(directory)
        if self.dir.exists():
            raise RobotError("exists; hearth record --format mcap writes a new bag",
                             file=str(self.dir))
        self.intrinsics = intrinsics
        self.info = dict(info or {})
        self.store = typestore()
        self._types = self.store.types
        self._lock = threading.Lock()
        self._writer = Writer(self.dir, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._conns: dict[str, Any] = {}
        self._n = 0
        self._n_actions = 0
        self._action_names: dict[int, tuple[str, int]] = {}
        self._last_ns = -1
        self._static_done = False
        self._info_done = False
        self._start_pose = None
        self._closed = False

    def __len__(self) -> int:
        return self._n

    def _write(self, topic: str, msgtype: str, msg, ns: int) -> None:
        conn = self._conns.get(topic)
        if conn is None:
            conn = self._conns[topic] = self._writer.add_connection(topic, msgtype,
                                                                    typestore=self.store)
        self._writer.write(conn, max(int(ns), 0), self.store.serialize_cdr(msg, msgtype))

    def _header(self, ns: int, frame: str = ""):
        t = self._types
        ns = max(int(ns), 0)
        return t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)

    def _pose2d(self, p):
        return self._types["geometry_msgs/msg/Pose2D"](x=float(p.x), y=float(p.y),
                                                       theta=float(p.yaw))

    def _transform(self, ns: int, parent: str, child: str, T):
        from scipy.spatial.transform import Rotation
        t = self._types
        q = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()
        return t["geometry_msgs/msg/TransformStamped"](
            header=self._header(ns, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](*map(float, np.asarray(T)[:3, 3])),
                rotation=t["geometry_msgs/msg/Quaternion"](*map(float, q))))

    def _pose(self, T):
        from scipy.spatial.transform import Rotation
        t = self._types
        q = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()
        return t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](*map(float, np.asarray(T)[:3, 3])),
            orientation=t["geometry_msgs/msg/Quaternion"](*map(float, q)))

    def set_start_pose(self, pose) -> None:
        self._start_pose = as_base_pose(pose)
        with self._lock:
            self._write_info(0)

    def _write_info(self, ns: int) -> None:
        t = self._types
        sp = self._start_pose
        self._write(EXTRAS["info"], "hearth_msgs/msg/RecordingInfo",
                    t["hearth_msgs/msg/RecordingInfo"](
                        header=self._header(ns), info_json=json.dumps(self.info, default=repr),
                        has_start_pose=sp is not None,
                        start_pose=self._pose2d(sp if sp is not None else Pose())), ns)
        self._info_done = True

    def add(self, frame, goal=None) -> dict:
        t = self._types
        with self._lock:
            ns = int(round(float(getattr(frame, "timestamp", 0.0)) * 1e9))
            ns = max(ns, self._last_ns + 1_000_000 if self._last_ns >= 0 else 0)
            self._last_ns = ns
            if not self._info_done:
                self._write_info(ns)
            K = getattr(frame, "intrinsics", None) or self.intrinsics
            self.intrinsics = K
            if not self._static_done:
                msg = t["tf2_msgs/msg/TFMessage"](transforms=[
                    self._transform(ns, MAP_FRAME, ODOM_FRAME, np.eye(4))])
                self._write(WRITE["tf_static"], "tf2_msgs/msg/TFMessage", msg, ns)
                self._static_done = True
            T_wc = np.asarray(frame.T_world_camera, dtype=float)
            base = getattr(frame, "base_pose", None)
            if base is None:                  # a bare view: a base under the camera, facing it
                base = Pose.planar(T_wc[0, 3], T_wc[1, 3], math.atan2(T_wc[1, 2], T_wc[0, 2]))
            T_wb = as_base_pose(base).matrix()
            msg = t["tf2_msgs/msg/TFMessage"](transforms=[
                self._transform(ns, ODOM_FRAME, BASE_FRAME, T_wb),
                self._transform(ns, BASE_FRAME, CAMERA_FRAME, np.linalg.inv(T_wb) @ T_wc)])
            self._write(WRITE["tf"], "tf2_msgs/msg/TFMessage", msg, ns)
            mm = depth_to_mm(frame.depth)
            h, w = mm.shape
            Image = t["sensor_msgs/msg/Image"]
            self._write(WRITE["depth"], "sensor_msgs/msg/Image", Image(
                header=self._header(ns, CAMERA_FRAME), height=h, width=w, encoding="16UC1",
                is_bigendian=0, step=w * 2, data=mm.astype("<u2").view(np.uint8).reshape(-1)), ns)
            rgb = np.ascontiguousarray(np.asarray(frame.color, dtype=np.uint8))
            self._write(WRITE["color"], "sensor_msgs/msg/Image", Image(
                header=self._header(ns, CAMERA_FRAME), height=h, width=w, encoding="rgb8",
                is_bigendian=0, step=w * 3, data=rgb.reshape(-1)), ns)
            self._write(WRITE["camera_info"], "sensor_msgs/msg/CameraInfo",
                        self._camera_info(ns, K, w, h), ns)
            entry = frame_entry(frame, goal)
            self._write(EXTRAS["capture"], "hearth_msgs/msg/CaptureInfo",
                        t["hearth_msgs/msg/CaptureInfo"](
                            header=self._header(ns, CAMERA_FRAME), index=self._n,
                            parking=entry["parking"] or "", has_goal=goal is not None,
                            goal=self._pose2d(as_base_pose(goal) if goal is not None else Pose()),
                            pan=entry["pan"], tilt=entry["tilt"]), ns)
            truth = entry["truth"]
            if truth is not None:
                bt = truth["base_pose"] or dict(x=0.0, y=0.0, yaw=0.0)
                self._write(EXTRAS["truth"], "hearth_msgs/msg/GroundTruth",
                            t["hearth_msgs/msg/GroundTruth"](
                                header=self._header(ns, MAP_FRAME), index=self._n,
                                base_pose=self._pose2d(as_base_pose(bt)),
                                camera_pose=self._pose(frame.T_world_camera_true)), ns)
            self._n += 1
            return entry

    def _camera_info(self, ns: int, K, w: int, h: int):
        t = self._types
        fx, fy, cx, cy = ((K.fx, K.fy, K.cx, K.cy) if K is not None
                          else (1.0, 1.0, (w - 1) / 2, (h - 1) / 2))
        return t["sensor_msgs/msg/CameraInfo"](
            header=self._header(ns, CAMERA_FRAME), height=h, width=w,
            distortion_model="plumb_bob", d=np.zeros(5),
            k=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=float),
            r=np.eye(3).reshape(-1), p=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], dtype=float),
            binning_x=0, binning_y=0,
            roi=t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                      do_rectify=False))

    def _action(self, k: int, ns: int, action: str, args: str, status: str, reason: str) -> None:
        self._write(EXTRAS["actions"], "hearth_msgs/msg/RobotAction",
                    self._types["hearth_msgs/msg/RobotAction"](
                        header=self._header(ns), number=k, action=action, args_json=args,
                        status=status, reason=reason), ns)

    def log_action(self, entry: dict) -> int:
        with self._lock:
            k = self._n_actions
            self._n_actions += 1
            t = entry.get("time")
            ns = int(round(t * 1e9)) if isinstance(t, (int, float)) and math.isfinite(t) else 0
            self._action_names[k] = (str(entry.get("action")), ns)
            self._action(k, ns, str(entry.get("action")),
                         json.dumps(entry.get("args", {}), default=repr), "requested", "")
            return k

    def action_done(self, k: int, status: str, reason: str = "") -> None:
        with self._lock:
            name, ns = self._action_names.get(k, ("", 0))
            self._action(k, max(ns, self._last_ns, 0), name, "", str(status), str(reason or ""))

    def event(self, ev) -> None:
        """A mission event (hearth.executive.executive.Event) on /hearth/events."""
        data = ev.to_json() if hasattr(ev, "to_json") else dict(ev)
        ns = int(round(float(data.get("t", 0.0)) * 1e9))
        rest = {k: v for k, v in data.items() if k not in ("e", "run", "tick", "t", "path")}
        with self._lock:
            if self._closed:
                return
            self._write(EXTRAS["events"], "hearth_msgs/msg/MissionEvent",
                        self._types["hearth_msgs/msg/MissionEvent"](
                            header=self._header(ns), run=str(data.get("run", "")),
                            kind=str(data.get("e", "")), tick=max(int(data.get("tick", 0)), 0),
                            path=str(data.get("path") or ""),
                            data_json=json.dumps(rest, default=repr)), ns)

    def flush(self) -> None:
        pass

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if not self._info_done:
                self._write_info(0)
            self._writer.close()


__all__ = ["BagRecording", "BagWriter", "TfBuffer", "TopicMap", "load_topic_map", "require_ros",
           "typestore", "HEARTH_MSGS"]
