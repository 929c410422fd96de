"""The tour recording a map is built from, checked: a Hearth recording directory or a ROS 2
bag (hearth/robot/recording.py, hearth/robot/rosbag.py), with every problem one line naming
the file (``MappingError`` or the recording's own ``RobotError``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hearth.mapping import MappingError

#: A colour frame whose mean brightness (0..255) is below this is dark: nothing to map.
DARK_MEAN = 8.0
#: ... and a depth frame with fewer valid readings than this share is blind.
MIN_DEPTH_SHARE = 0.02


class BlindFrame(MappingError):
    """A frame whose depth camera saw (almost) nothing: the build skips it with a warning.
    A tour has them where the camera faced a wall or a wardrobe nearer than the depth
    camera's range (a Kinect-class camera reads nothing nearer than ~0.45 m); a dark frame,
    by contrast, stops the build (the lights were off: the whole tour is suspect)."""


def open_tour(path, topics=None):
    """The recording at ``path``, checked for what a map needs: captures, and (a bag) no depth
    image left without its colour image or its pose."""
    from hearth.robot.recording import open_recording
    rec = open_recording(path, topics=topics)
    where = str(getattr(rec, "path", path))
    if len(rec.captures) == 0:
        raise MappingError("empty recording: no captures to build a map from", file=where)
    skipped = getattr(rec, "skipped", None) or {}
    lost = int(skipped.get("unpaired", 0)) + int(skipped.get("outside_tf", 0))
    if lost:
        raise MappingError(
            f"{lost} of {len(rec.captures) + lost} frames are missing (a depth image without "
            f"its colour image or its tf); a map from a tour with holes would have holes: "
            f"record the tour again or drop the broken part of the bag", file=where)
    return rec


def frame_file(rec, i: int) -> str:
    """Where capture ``i`` lives, for messages: its colour file, or the bag and topic."""
    c = rec.captures[i]
    d = getattr(rec, "dir", None)
    if d is not None and (Path(d) / c.color).exists():
        return str(Path(d) / c.color)
    return f"{rec.path} ({c.color})"


def read_frame(rec, i: int):
    """Capture ``i`` as a Frame, refused when it is dark (``MappingError``) or blind
    (``BlindFrame``; one line naming it)."""
    f = rec.frame(i)
    mean = float(np.asarray(f.color).mean())
    if mean < DARK_MEAN:
        raise MappingError(f"frame {i} is dark (mean brightness {mean:.1f} of 255, below "
                           f"{DARK_MEAN:g}): turn the lights on and record the tour again, or "
                           "drop the frame", file=frame_file(rec, i))
    valid = float(np.mean(np.asarray(f.depth) > 0))
    if valid < MIN_DEPTH_SHARE:
        raise BlindFrame(f"frame {i} has depth readings in {valid:.1%} of its pixels: the "
                         "depth camera saw nothing", file=frame_file(rec, i))
    return f


def base_camera(rec) -> tuple[np.ndarray, np.ndarray]:
    """Believed ``T_world_base`` (N, 4, 4) and ``T_base_camera`` (N, 4, 4) of every capture;
    a capture without a base pose gets a base on the floor under its camera, facing its way."""
    from hearth.worldmodel.pose import Pose
    B, C = [], []
    for c in rec.captures:
        T = np.asarray(c.T_world_camera, float)
        base = c.base_pose
        if base is None:
            base = Pose.planar(T[0, 3], T[1, 3], float(np.arctan2(T[1, 2], T[0, 2])))
        Tb = base.matrix()
        B.append(Tb)
        C.append(np.linalg.inv(Tb) @ T)
    return np.stack(B), np.stack(C)


def true_cameras(rec):
    """True ``T_world_camera`` of every capture (N, 4, 4), or None when any is unknown."""
    if any(c.T_world_camera_true is None for c in rec.captures):
        return None
    return np.stack([np.asarray(c.T_world_camera_true, float) for c in rec.captures])
