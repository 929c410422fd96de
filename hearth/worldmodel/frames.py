"""Frames of the map, in one place: rooms, planar transforms, joints and knobs, pose coercion.

Every caller that asks "which room is this point in", "where is this point in its room's
frame", "what is ``T_parent_part`` at this joint state" or "turn this value into a Pose"
uses these functions. Rooms may be turned and offset: a room's ``bounds`` (xmin, ymin, xmax,
ymax) are in the room frame, and ``room.pose`` is ``T_world_room``; nothing here assumes
that a room's pose is the identity. Lengths are metres, angles radians.

Only numpy and scipy (through ``hearth.worldmodel.pose``): cheap to import.
"""
from __future__ import annotations

import math
from typing import Any, Iterable, Optional

import numpy as np

from hearth.worldmodel.outline import outline_contains, room_outline
from hearth.worldmodel.pose import Pose, rotation_about_axis, translation_along_axis

# -- planar transforms --------------------------------------------------------------------


def planar_T(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """4x4 transform: rotation ``yaw`` about +z, then translation (x, y, z)."""
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[0, 0], T[0, 1], T[1, 0], T[1, 1] = c, -s, s, c
    T[:3, 3] = (x, y, z)
    return T


def planar_of(T: np.ndarray) -> tuple[float, float, float]:
    """(x, y, yaw) of a 4x4 transform: its translation and the heading of its x axis."""
    T = np.asarray(T, dtype=float)
    return float(T[0, 3]), float(T[1, 3]), float(math.atan2(T[1, 0], T[0, 0]))


def planar_about(x: float, y: float, yaw: float, centre) -> np.ndarray:
    """4x4 planar motion that turns by ``yaw`` about the vertical through ``centre`` (x, y)
    and then moves by (x, y)."""
    T = planar_T(0.0, 0.0, yaw)
    c = np.asarray(centre, dtype=float)[:2]
    T[:2, 3] = c - T[:2, :2] @ c + (x, y)
    return T


def transform_xy(T: np.ndarray, xy) -> np.ndarray:
    """(N, 2) floor points mapped by the planar part of a 4x4 transform."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return xy @ np.asarray(T)[:2, :2].T + np.asarray(T)[:2, 3]


# -- pose coercion ------------------------------------------------------------------------


def as_pose(value: Any) -> Pose:
    """A full ``Pose`` from a Pose, a 4x4 matrix, a mapping with x, y (z, roll, pitch, yaw),
    or a sequence of 3 (x, y, yaw) or 6 (x, y, z, roll, pitch, yaw) numbers.

    Raises ValueError for anything else (callers turn it into their own error family)."""
    if isinstance(value, Pose):
        return value
    if isinstance(value, dict):
        try:
            return Pose(float(value["x"]), float(value["y"]), float(value.get("z", 0.0)),
                        float(value.get("roll", 0.0)), float(value.get("pitch", 0.0)),
                        float(value.get("yaw", 0.0)))
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"not a pose: {value!r}") from None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"not a pose: {value!r}") from None
    if arr.shape == (4, 4):
        return Pose.from_matrix(arr)
    if arr.shape == (3,):
        return Pose.planar(*map(float, arr))
    if arr.shape == (6,):
        return Pose(*map(float, arr))
    raise ValueError(f"not a pose: {value!r}")


def as_matrix(value: Any) -> np.ndarray:
    """4x4 ``T`` from anything ``as_pose`` takes (a 4x4 array is returned as a float copy)."""
    if not isinstance(value, (Pose, dict)):
        arr = np.asarray(value, dtype=float)
        if arr.shape == (4, 4):
            return arr.copy()
    return as_pose(value).matrix()


def as_base_pose(value: Any) -> Pose:
    """A planar base Pose (x, y, yaw; z, roll, pitch zero) from anything ``as_pose`` takes.
    The yaw of a 4x4 is the heading of its x axis (robust to small roll and pitch)."""
    if not isinstance(value, (Pose, dict)):
        arr = np.asarray(value, dtype=float)
        if arr.shape == (4, 4):
            return Pose.planar(*planar_of(arr))
    p = as_pose(value)
    return Pose.planar(p.x, p.y, p.yaw)


# -- joints and knobs ---------------------------------------------------------------------


def joint_T(joint, state: Optional[float] = None) -> np.ndarray:
    """``T_parent_part`` of a ``Joint`` at ``state`` (default: its current state): the
    joint origin, then a rotation about (revolute) or a slide along (prismatic) its axis."""
    s = joint.state if state is None else state
    T = joint.origin.matrix()
    if joint.type == "revolute":
        T = T @ rotation_about_axis(joint.axis, s)
    elif joint.type == "prismatic":
        T = T @ translation_along_axis(joint.axis, s)
    return T


def knob_T(knob, angle: Optional[float] = None) -> np.ndarray:
    """``T_parent_knob`` of a ``Knob`` turned to ``angle`` (default: its current angle) about
    its +z axis."""
    a = knob.angle if angle is None else angle
    return knob.pose.matrix() @ rotation_about_axis((0, 0, 1), a)


# -- rooms --------------------------------------------------------------------------------


def T_world_room(room) -> np.ndarray:
    """4x4 ``T_world_room``."""
    return room.pose.matrix()


def to_room(room, points_world) -> np.ndarray:
    """World points (N, 3) or floor points (N, 2) in the room's frame."""
    P = np.asarray(points_world, dtype=float)
    T_room_world = np.linalg.inv(T_world_room(room))
    if P.ndim == 1:
        return to_room(room, P[None])[0]
    if P.shape[1] == 2:
        return transform_xy(T_room_world, P)
    return P @ T_room_world[:3, :3].T + T_room_world[:3, 3]


def room_centre(room) -> tuple[float, float]:
    """World (x, y) of the centre of a room's bounds (its pose without bounds)."""
    if room.bounds is None:
        return float(room.pose.x), float(room.pose.y)
    x0, y0, x1, y1 = room.bounds
    c = transform_xy(T_world_room(room), [((x0 + x1) / 2, (y0 + y1) / 2)])[0]
    return float(c[0]), float(c[1])


def room_contains(room, x: float, y: float, margin: float = 0.0) -> bool:
    """Whether the world floor point (x, y) lies on the room's floor (its outline, or its
    bounds) grown by ``margin`` (negative: shrunk; see ``outline.outline_contains``). A room
    without bounds or outline contains nothing."""
    poly = room_outline(room)
    if not poly:
        return False
    q = to_room(room, np.array([[x, y]], dtype=float))[0]
    return outline_contains(poly, float(q[0]), float(q[1]), margin)


def room_at(rooms: Iterable, x: float, y: float, margin: float = 0.0):
    """The room (of ``rooms``: a World, an Apartment or a list of rooms) whose bounds hold
    the world floor point (x, y), or None. Where rooms overlap the first listed wins."""
    for room in _rooms(rooms):
        if room_contains(room, x, y, margin):
            return room
    return None


def room_corners(room) -> np.ndarray:
    """(N, 2) world x, y of the corners of the room's floor, counter-clockwise in the room
    frame: its outline's, or the four of its bounds from (xmin, ymin)."""
    return transform_xy(T_world_room(room), room_outline(room))


def _rooms(rooms) -> list:
    if hasattr(rooms, "rooms"):
        return list(rooms.rooms)
    return list(rooms)
