"""A base pose straight in front of a node's knob panel, facing it (or, for knobs on top, nearer
than the parking positions, looking down on them): another view of knobs the parking positions
(often to one side of the panel) left unread."""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from hearth.worldmodel.frames import room_at
from hearth.worldmodel.pose import Pose

#: Robot centre to the knobs' mean, along their panel's normal (metres). Nearer is not better:
#: the camera stands 1.3 m up, so a nearer view looks down on a front panel more steeply (on
#: generated homes, views from 0.4-0.6 m read no knob that 0.6-0.9 m parking positions missed;
#: views from 0.8-1.1 m read some).
KNOB_VIEW_DISTANCE = 1.0
#: The base's disc must be this clear (metres) of every other large object's footprint.
BASE_CLEARANCE = 0.3
#: Knob axes steeper than this (cos of the angle to the vertical) face up: no front to stand in.
_UPRIGHT = 0.9
#: Knobs on top are looked at from this much nearer than ``distance`` (metres): from 1.0 m
#: the camera 1.3 m up would look at a hob's knobs 0.4 m below it 68 degrees off their axis.
TOP_VIEW_NEARER = 0.5


def floor_clear(world, clearance: float, boxes: dict | None = None, skip: str = ""):
    """A test ``free(x, y)``: whether a base at (x, y) stands inside a room and ``clearance``
    clear of every large object's footprint (its axis-aligned world bounds) but ``skip``'s.
    ``boxes`` (id -> world bounds) when the caller has them already; the footprints are read
    once, so the test is cheap to ask of many poses."""
    if boxes is None:
        boxes = {o.id: world.bounds_world(o.id) for o in world.large_objects()}
    bounded = [r for r in world.rooms if r.bounds is not None]
    footprints = [(np.asarray(lo, float)[:2], np.asarray(hi, float)[:2])
                  for oid, (lo, hi) in boxes.items() if oid != skip]

    def free(x: float, y: float) -> bool:
        if bounded and room_at(bounded, float(x), float(y), margin=-clearance) is None:
            return False
        return all(math.hypot(max(lo[0] - x, 0.0, x - hi[0]), max(lo[1] - y, 0.0, y - hi[1]))
                   >= clearance for lo, hi in footprints)
    return free


def _clear_of(world, x: float, y: float, clearance: float, skip: str = "") -> bool:
    """``floor_clear`` for one pose."""
    return floor_clear(world, clearance, skip=skip)(x, y)


def knob_view_pose(world, node_id: str, distance: float = KNOB_VIEW_DISTANCE,
                   clearance: float = BASE_CLEARANCE) -> Optional[Pose]:
    """The world base pose (x, y, yaw) ``distance`` in front of the mean of ``node_id``'s
    knobs along their mean axis (+z out of the panel), facing them; None when the node has no
    knobs or the pose is outside every room or within ``clearance`` of another large
    object's footprint (its axis-aligned world bounds).

    Knobs on top (a hob's, axes within about 25 degrees of the vertical) have no panel to
    stand in front of: the pose is on the side of the appliance's parking positions,
    ``distance`` less ``TOP_VIEW_NEARER`` from the knobs (looking down on them more steeply
    than the parking positions do), moved out as far as the base needs to be ``clearance``
    clear of the appliance itself (at most to ``distance``)."""
    knobs = world.knobs(node_id)
    if not knobs:
        return None
    Ts = [world.T_world(k.id) for k in knobs]
    centre = np.mean([T[:3, 3] for T in Ts], axis=0)
    axis = np.mean([T[:3, 2] for T in Ts], axis=0)
    n = float(np.linalg.norm(axis))
    if n < 1e-9:
        return None
    own = world.large_object_of(node_id).id
    if abs(axis[2] / n) > _UPRIGHT:
        if axis[2] < 0:
            return None                                     # knobs facing down
        away = np.mean([[p.x - centre[0], p.y - centre[1]] for _, p in world.parking_positions(node_id)]
                       or [[0.0, 0.0]], axis=0)
        if np.linalg.norm(away) < 1e-6:
            return None
        h = away / np.linalg.norm(away)
        for d in np.arange(max(distance - TOP_VIEW_NEARER, 0.2), distance + 1e-9, 0.05):
            x, y = centre[:2] + d * h
            if _clear_of(world, x, y, clearance):           # the appliance itself included
                return Pose.planar(float(x), float(y), math.atan2(-h[1], -h[0]))
        return None
    h = axis[:2] / np.linalg.norm(axis[:2])
    x, y = centre[:2] + distance * h
    if not _clear_of(world, x, y, clearance, skip=own):
        return None
    return Pose.planar(float(x), float(y), math.atan2(-h[1], -h[0]))


#: What the arm reaches, base centre to a handle (metres), when the robot does not say: the
#: generator keeps every handle this near a parking position (HomeConfig.reach).
ARM_REACH = 1.45
#: Base centre to a handle, along the front's normal, of a pose made to reach it (metres): the
#: generator's nearest parking distances.
REACH_STANDOFFS = (0.6, 0.7, 0.8, 0.5, 0.9)


def reach_point(world, node_id: str) -> np.ndarray:
    """The world point the arm goes to for ``node_id``: a part's first handle, else the node
    itself (a handle, a knob), where the map has it now (an open door's handle moved)."""
    handles = getattr(world.get(node_id), "handles", None)
    return world.T_world(handles[0].id if handles else node_id)[:3, 3]


def reach_pose(world, node_id: str, reach: float = ARM_REACH,
               clearance: float = BASE_CLEARANCE) -> Optional[Pose]:
    """A world base pose from which the arm reaches ``node_id`` (a handle, a part: its first
    handle, a knob; its position in the map, so an open door's handle where it now is): the
    parking position of its large object nearest to it when that is within ``reach``, else
    a pose on free floor in front of it (``REACH_STANDOFFS`` out along the mean direction from
    the large object to its parking positions, facing it, ``clearance`` clear of every
    footprint); None when neither is found. A sliding door's pull at the far end of a wide
    wardrobe, or a door opened from a second parking position, may be out of reach of the one
    the robot stands at."""
    point = reach_point(world, node_id)
    large = world.large_object_of(node_id)
    parkings = sorted(world.parking_positions(large.id),
                      key=lambda pp: math.hypot(pp[1].x - point[0], pp[1].y - point[1]))
    if parkings and math.hypot(parkings[0][1].x - point[0], parkings[0][1].y - point[1]) <= reach:
        return parkings[0][1]
    centre = world.T_world(large.id)[:3, 3]
    if parkings:
        away = np.mean([[p.x - centre[0], p.y - centre[1]] for _, p in parkings], axis=0)
    else:
        away = world.T_world(large.id)[:2, 0]       # the object's front (+x)
    if np.linalg.norm(away) < 1e-6:
        return None
    h = away / np.linalg.norm(away)
    free = floor_clear(world, clearance)
    for d in REACH_STANDOFFS:
        if d > reach:
            continue
        x, y = point[:2] + d * h
        if free(x, y):
            return Pose.planar(float(x), float(y), math.atan2(-h[1], -h[0]))
    return None
