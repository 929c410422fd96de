"""Where the robot rests (go_to_rest), taken from the map of any home.

Near the user (the user is at home): a large object declared a rest place (affordance
``rest``) in the user's room, else the free floor nearest the user's room (in it when it has
any). Out of the way (the user is away): a large object with affordance ``rest_away``, else
the dock of the charger nearest the robot (resting there also charges), else the free floor
nearest the first room's centre.

Free floor: a spot whose disc of the robot's radius and a margin (``CLEARANCE``) lies inside
the room's bounds and clear of every large object's world bounds, and which keeps ``AWAY``
from every parking position (a robot resting there is in nobody's way, its own searches
included). Spots are taken on a ``STEP`` grid; of a room's free spots the one nearest the
room's centre is chosen, facing the centre (seen from there the room is in view).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hearth.worldmodel.chargers import AWAY, CLEARANCE
from hearth.worldmodel.frames import T_world_room, room_at, room_centre, transform_xy
from hearth.worldmodel.pose import Pose

#: Affordance of a large object the robot rests at (its default parking position) while the
#: user is at home, and while the user is away.
REST_NEAR_USER = "rest"
REST_AWAY = "rest_away"
#: Grid step (m) of the free floor spots tried.
STEP = 0.1


@dataclass(frozen=True)
class RestPlace:
    """Where to rest: ``target`` is a node id (rest at its default parking position) or a
    world base pose; ``words`` say it for a person ("the sofa", "the free floor of the
    living room")."""
    target: object
    words: str
    how: str          # declared | charger | free_floor


def rest_place(world, room_id: Optional[str] = None, away: bool = False,
               robot_pose: Optional[Pose] = None) -> Optional[RestPlace]:
    """The rest place for the user at home in ``room_id`` (default: the room the robot is in,
    else the first room), or away. None when the map has no room with free floor and
    declares none."""
    here = robot_pose or Pose()
    if away:
        declared = _declared(world, REST_AWAY, None, here)
        if declared is not None:
            return declared
        docks = sorted((math.hypot(p.x - here.x, p.y - here.y), c.id, p)
                       for c in world.chargers() for p in [world.dock_pose(c.id)])
        if docks:
            return RestPlace(docks[0][2], "charging station", "charger")
        room = world.rooms[0] if world.rooms else None
    else:
        room = world.get(room_id) if room_id else room_at(world, here.x, here.y)
        room = room if room is not None else (world.rooms[0] if world.rooms else None)
        if room is None:
            return None
        declared = _declared(world, REST_NEAR_USER, room.id, here)
        if declared is not None:
            return declared
    if room is None:
        return None
    pose, in_room = free_floor_near(world, room.id)
    if pose is None:
        return _declared(world, REST_NEAR_USER if not away else REST_AWAY, None, here)
    where = room.id if in_room is None else in_room
    return RestPlace(pose, f"free floor of the {world.get(where).name}", "free_floor")


def _declared(world, affordance: str, room_id: Optional[str], here: Pose) -> Optional[RestPlace]:
    """The declared rest place (a large object with ``affordance`` and parking positions) in
    ``room_id`` (any room when None) nearest the robot."""
    found = []
    for obj in world.large_objects():
        if affordance not in obj.affordances or not obj.parking:
            continue
        if room_id is not None and world.room_of(obj.id).id != room_id:
            continue
        p = world.parking_positions(obj.id)[0][1]
        found.append((math.hypot(p.x - here.x, p.y - here.y), obj.id))
    if not found:
        return None
    oid = min(found)[1]
    return RestPlace(oid, f"the {world.label(oid)}", "declared")


def _obstacles(world):
    """(furniture world bounds, parking position x/y) of the whole map."""
    return ([world.bounds_world(o.id) for o in world.large_objects()],
            [(p.x, p.y) for o in world.large_objects() for _, p in world.parking_positions(o.id)])


def free_floor(world, room, obstacles=None) -> list[tuple[float, float]]:
    """World (x, y) of the free floor spots of a room (module docstring), on the STEP grid."""
    if room.bounds is None:
        return []
    boxes, parkings = obstacles if obstacles is not None else _obstacles(world)
    x0, y0, x1, y1 = room.bounds
    xs = np.arange(x0 + CLEARANCE, x1 - CLEARANCE + 1e-9, STEP)
    ys = np.arange(y0 + CLEARANCE, y1 - CLEARANCE + 1e-9, STEP)
    if not len(xs) or not len(ys):
        return []
    grid = np.array([(x, y) for x in xs for y in ys], dtype=float)
    pts = transform_xy(T_world_room(room), grid)
    ok = np.ones(len(pts), dtype=bool)
    for (lx, ly, _), (hx, hy, _) in boxes:
        dx = np.maximum(np.maximum(lx - pts[:, 0], 0.0), pts[:, 0] - hx)
        dy = np.maximum(np.maximum(ly - pts[:, 1], 0.0), pts[:, 1] - hy)
        ok &= np.hypot(dx, dy) >= CLEARANCE
    for px, py in parkings:
        ok &= np.hypot(pts[:, 0] - px, pts[:, 1] - py) >= AWAY
    return [(float(x), float(y)) for x, y in pts[ok]]


def free_floor_near(world, room_id: str) -> tuple[Optional[Pose], Optional[str]]:
    """The free floor spot nearest the centre of room ``room_id``, facing that centre, and
    the id of the room it is in: that room when it has free floor, else the room whose free
    floor comes nearest its centre. (None, None) when no room has any."""
    target = world.get(room_id)
    cx, cy = room_centre(target)
    obstacles = _obstacles(world)
    spots = free_floor(world, target, obstacles)
    if spots:
        best = min(spots, key=lambda s: (math.hypot(s[0] - cx, s[1] - cy), s))
        return _facing(best, (cx, cy)), target.id
    # The user's room has no free floor: the nearest of any other room's.
    best = None
    for room in (r for r in world.rooms if r is not target):
        for s in free_floor(world, room, obstacles):
            d = math.hypot(s[0] - cx, s[1] - cy)
            if best is None or (d, s) < best[:2]:
                best = (d, s, room.id)
    if best is None:
        return None, None
    return _facing(best[1], (cx, cy)), best[2]


def _facing(spot, centre) -> Pose:
    dx, dy = centre[0] - spot[0], centre[1] - spot[1]
    yaw = math.atan2(dy, dx) if math.hypot(dx, dy) > 0.3 else 0.0
    return Pose.planar(round(spot[0], 3), round(spot[1], 3), round(yaw, 4))
