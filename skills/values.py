"""Turning mission-file values into typed values skills use (poses, ids)."""
from __future__ import annotations

from typing import Any

from skills.errors import SkillError
from worldmodel.pose import Pose


def as_pose(value: Any) -> Pose:
    """A ``Pose`` from a Pose, a mapping with x, y (z, roll, pitch, yaw), or a sequence of 3
    (x, y, yaw) or 6 (x, y, z, roll, pitch, yaw) numbers."""
    if isinstance(value, Pose):
        return value
    if isinstance(value, dict):
        try:
            return Pose(float(value["x"]), float(value["y"]), float(value.get("z", 0.0)),
                        float(value.get("roll", 0.0)), float(value.get("pitch", 0.0)),
                        float(value.get("yaw", 0.0)))
        except (KeyError, TypeError, ValueError):
            raise SkillError(f"not a pose: {value!r}") from None
    if isinstance(value, (list, tuple)):
        v = [float(x) for x in value]
        if len(v) == 3:
            return Pose.planar(*v)
        if len(v) == 6:
            return Pose(*v)
    raise SkillError(f"not a pose: {value!r}")
