"""Turning mission-file values into typed values skills use (poses, ids)."""
from __future__ import annotations

from typing import Any

from hearth.skills.base import Feedback, words
from hearth.skills.errors import SkillError
from hearth.worldmodel import frames
from hearth.worldmodel.pose import Pose


def as_pose(value: Any) -> Pose:
    """A ``Pose`` from a Pose, a mapping with x, y (z, roll, pitch, yaw), or a sequence of 3
    (x, y, yaw) or 6 (x, y, z, roll, pitch, yaw) numbers."""
    try:
        return frames.as_pose(value)
    except ValueError:
        raise SkillError(Feedback(f"not a pose: {words(value)}", value=value)) from None
