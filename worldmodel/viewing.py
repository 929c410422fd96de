"""A base pose straight in front of a node's knob panel, facing it: another view of knobs the
parking positions (often to one side of the panel) left unread."""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from worldmodel.frames import room_at
from worldmodel.pose import Pose

#: Robot centre to the knobs' mean, along their panel's normal (metres). Nearer is not better:
#: the camera stands 1.3 m up, so a nearer view looks down on a front panel more steeply (on
#: generated homes, views from 0.4-0.6 m read no knob that 0.6-0.9 m parking positions missed;
#: views from 0.8-1.1 m read some).
KNOB_VIEW_DISTANCE = 1.0
#: The base's disc must be this clear (metres) of every other large object's footprint.
BASE_CLEARANCE = 0.3
#: Knob axes steeper than this (cos of the angle to the vertical) face up: no front to stand in.
_UPRIGHT = 0.9


def knob_view_pose(world, node_id: str, distance: float = KNOB_VIEW_DISTANCE,
                   clearance: float = BASE_CLEARANCE) -> Optional[Pose]:
    """The world base pose (x, y, yaw) ``distance`` in front of the mean of ``node_id``'s
    knobs along their mean axis (+z out of the panel), facing them; None when the node has no
    knobs, the knobs face up or down, or the pose is outside every room or within
    ``clearance`` of another large object's footprint (its axis-aligned world bounds)."""
    knobs = world.knobs(node_id)
    if not knobs:
        return None
    Ts = [world.T_world(k.id) for k in knobs]
    centre = np.mean([T[:3, 3] for T in Ts], axis=0)
    axis = np.mean([T[:3, 2] for T in Ts], axis=0)
    n = float(np.linalg.norm(axis))
    if n < 1e-9 or abs(axis[2] / n) > _UPRIGHT:
        return None
    h = axis[:2] / np.linalg.norm(axis[:2])
    x, y = centre[:2] + distance * h
    bounded = [r for r in world.rooms if r.bounds is not None]
    if bounded and room_at(bounded, float(x), float(y), margin=-clearance) is None:
        return None
    own = world.large_object_of(node_id).id
    for obj in world.large_objects():
        if obj.id == own:
            continue
        lo, hi = world.bounds_world(obj.id)
        dx = max(lo[0] - x, 0.0, x - hi[0])
        dy = max(lo[1] - y, 0.0, y - hi[1])
        if math.hypot(dx, dy) < clearance:
            return None
    return Pose.planar(float(x), float(y), math.atan2(-h[1], -h[0]))
