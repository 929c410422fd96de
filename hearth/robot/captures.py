"""What a capture is, whichever file holds it: the fields a recording keeps of a frame
(``frame_entry``), depth in millimetres (``depth_to_mm``), a recorded ``Capture``, and the
checks of its numbers, poses, transforms and intrinsics (``BadField`` names what is wrong).

Hearth's recording directory (hearth.robot.recording) and ROS 2 bags (hearth.robot.rosbag)
both read and write through this module, so neither imports the other's internals.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.robot.adapter import as_base_pose
from hearth.robot.frames import MAX_FRAME_PIXELS, MAX_IMAGE_SIDE
from hearth.worldmodel.pose import Pose
from hearth.worldmodel.validate import MAX_COORD

DEPTH_SCALE = 0.001          # metres per unit of the 16-bit depth PNG
#: A time on the recording's clock, seconds (ROS stamps are ~1.7e9).
MAX_TIME = 1e11


def _pose_dict(p) -> Optional[dict]:
    if p is None:
        return None
    p = as_base_pose(p)
    return dict(x=p.x, y=p.y, yaw=p.yaw)


def _matrix(T) -> Optional[list]:
    return None if T is None else np.asarray(T, dtype=float).round(9).tolist()


def frame_entry(frame, goal=None) -> dict:
    """The fields of a capture a recording keeps (poses, head, provenance), JSON-ready."""
    truth = None
    if getattr(frame, "T_world_camera_true", None) is not None:
        truth = dict(base_pose=_pose_dict(getattr(frame, "base_pose_true", None)),
                     T_world_camera=_matrix(frame.T_world_camera_true))
    return dict(timestamp=float(getattr(frame, "timestamp", 0.0)),
                base_pose=_pose_dict(getattr(frame, "base_pose", None)),
                T_world_camera=_matrix(frame.T_world_camera),
                pan=float(getattr(frame, "pan", 0.0)), tilt=float(getattr(frame, "tilt", 0.0)),
                parking=getattr(frame, "parking", None), goal=_pose_dict(goal), truth=truth)


def depth_to_mm(depth) -> np.ndarray:
    """float metres (0 or NaN: no reading) -> uint16 millimetres (0: no reading)."""
    mm = np.nan_to_num(np.asarray(depth, dtype=np.float64) / DEPTH_SCALE, nan=0.0)
    return np.clip(np.rint(mm), 0, 65535).astype(np.uint16)


@dataclass
class Capture:
    """One recorded capture (poses as Pose / 4x4 arrays; truth None when unknown). ``index``
    is its position in the recording."""
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


class BadField(ValueError):
    """A field of a recording that is missing or wrong (the message says which)."""


def _number(x, what: str, positive: bool = False, bound: float = MAX_COORD) -> float:
    """``x`` as a finite float of magnitude at most ``bound`` (and > 0 with ``positive``)."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise BadField(f"{what} must be a number")
    try:
        v = float(x)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise BadField(f"{what} is not finite ({str(x)[:40]})")
    if positive and v <= 0:
        raise BadField(f"{what} must be positive (is {x!r})")
    if abs(v) > bound:
        raise BadField(f"{what} is beyond +-{bound:g} (is {v:g})")
    return v


def _planar(d, what: str) -> Optional[Pose]:
    if d is None:
        return None
    if not isinstance(d, dict):
        raise BadField(f"{what} must be an object with x, y, yaw")
    # positions in metres within the world format's bounds; yaw in radians, any turn count
    # a person could mean (a 1e300 yaw loses every digit of its angle)
    return Pose.planar(*(_number(d.get(k), f"{what}.{k}") for k in ("x", "y", "yaw")))


_EYE3, _BOTTOM = np.eye(3), np.array([0.0, 0.0, 0.0, 1.0])


def _transform(m, what: str) -> np.ndarray:
    try:
        T = np.asarray(m, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise BadField(f"{what} must be a 4x4 matrix of numbers") from None
    if T.shape != (4, 4):
        raise BadField(f"{what} must be a 4x4 matrix")
    if not np.isfinite(T).all():
        raise BadField(f"{what} has numbers that are not finite")
    if np.abs(T[:3, 3]).max() > MAX_COORD:
        raise BadField(f"{what}: the position is beyond +-{MAX_COORD:g} m")
    R = T[:3, :3]
    # (np.allclose, twice per capture, was most of the time to open 20,000 captures; a
    # rotation's entries are within +-1, and checking that first keeps 1e308 entries from
    # overflowing the product with a RuntimeWarning on stderr)
    if not (float(np.abs(R).max()) <= 1.0 + 1e-4
            and float(np.abs(R @ R.T - _EYE3).max()) <= 1e-4
            and float(np.abs(T[3] - _BOTTOM).max()) <= 1e-4 and np.linalg.det(R) > 0):
        raise BadField(f"{what} is not a rigid transform")
    return T


def check_intrinsics(d, what: str = "intrinsics") -> Intrinsics:
    """Intrinsics from a mapping, refused unless fx, fy > 0 and finite, cx, cy finite and the
    image size a positive whole number of pixels (at most MAX_IMAGE_SIDE)."""
    if not isinstance(d, dict):
        raise BadField(f"{what} must be an object with fx, fy, cx, cy, width, height")
    fx, fy = (_number(d.get(k), f"{what}.{k}", positive=True, bound=1e7) for k in ("fx", "fy"))
    cx, cy = (_number(d.get(k), f"{what}.{k}", bound=1e7) for k in ("cx", "cy"))
    size = []
    for k in ("width", "height"):
        v = _number(d.get(k), f"{what}.{k}", positive=True, bound=math.inf)
        if v != int(v) or v > MAX_IMAGE_SIDE:
            raise BadField(f"{what}.{k} must be a whole number of pixels up to {MAX_IMAGE_SIDE}")
        size.append(int(v))
    if size[0] * size[1] > MAX_FRAME_PIXELS:
        raise BadField(f"{what}: {size[0]}x{size[1]} is more than the {MAX_FRAME_PIXELS} pixels "
                   "a frame may have")
    return Intrinsics(fx, fy, cx, cy, size[0], size[1])
