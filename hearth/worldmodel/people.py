"""Where the user is likely to be, and where the robot stands to look for them in a room.

HOBBIT's "locate user" and emergency patrol visit the rooms in order of where the user
usually is. The map learns it the way it learns where objects turn up (``World.record_search``
with the object key :data:`USER`, the place a room id): a room's likelihood is
(found + 1) / (searched + 2) (Laplace's rule: an unvisited room counts one half), ties going
to the room nearer the robot.
"""
from __future__ import annotations

import math
from typing import Iterable, Optional

from hearth.worldmodel.frames import room_centre, room_contains
from hearth.worldmodel.pose import Pose

#: The search-statistics key under which the map counts where the user was looked for.
USER = "user"


def user_likelihood(world, room_id: str) -> float:
    """(found + 1) / (searched + 2) for the user in room ``room_id``."""
    stat = world.search_stats(USER).get(room_id)
    searched, found = (stat.searched, stat.found) if stat is not None else (0, 0)
    return (found + 1) / (searched + 2)


def rooms_by_user_likelihood(world, x: float, y: float, skip: Iterable[str] = ()) -> list[str]:
    """Room ids, likeliest place of the user first (ties: nearer the world point (x, y)
    first), without those in ``skip``."""
    skip = set(skip)

    def key(room):
        p = room_visit_pose(world, room.id)
        return (-user_likelihood(world, room.id), math.hypot(p.x - x, p.y - y), room.id)
    return [r.id for r in sorted((r for r in world.rooms if r.id not in skip), key=key)]


def room_visit_pose(world, room_id: str) -> Pose:
    """Where the robot stands to look around room ``room_id`` (world x, y, yaw): the parking
    position in the room nearest its centre, facing the centre; a room without one: its
    centre. UnknownNode for an id that is not a room."""
    room = world.get(room_id)
    if getattr(room, "kind", "") != "Room":
        from hearth.worldmodel.errors import UnknownNode
        raise UnknownNode("not a room", node=room_id)
    cx, cy = room_centre(room)
    best: Optional[tuple[float, Pose]] = None
    for obj in room.objects:
        for _, pose in world.parking_positions(obj.id):
            if room.bounds is not None and not room_contains(room, pose.x, pose.y, margin=0.0):
                continue
            d = math.hypot(pose.x - cx, pose.y - cy)
            if best is None or d < best[0]:
                best = (d, pose)
    if best is None:
        return Pose.planar(cx, cy, 0.0)
    p = best[1]
    yaw = math.atan2(cy - p.y, cx - p.x) if best[0] > 1e-6 else p.yaw
    return Pose.planar(p.x, p.y, yaw)
