"""Where a charging station goes in a home that has none (the home generator, and homes
generated before chargers were part of the map).

Deterministic from the map alone (no random numbers), so a home's furniture and objects stay
those it had: the first room (a generated home's kitchen) is walked wall by wall, every
0.1 m, for a spot whose dock pose (``DOCK_DISTANCE`` in front of the wall, the robot backed
onto the charger) leaves ``CLEARANCE`` to every large object's footprint and ``AWAY`` to
every parking position, on the room's floor and ``DOORWAY_AWAY`` from every doorway; the
next room is tried when none is free.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from hearth.worldmodel.frames import T_world_room, transform_xy
from hearth.worldmodel.nodes import Charger
from hearth.worldmodel.outline import outline_contains, room_openings, room_outline
from hearth.worldmodel.pose import Pose

#: How far from its charger (m) the robot stands docked.
DOCK_DISTANCE = 0.4
#: Free floor (m) between the docked robot's centre and any furniture: its radius and a margin.
CLEARANCE = 0.35
#: Distance (m) kept from every parking position, so the docked robot is in nobody's way.
AWAY = 0.7
#: Distance (m) from the dock pose to the centre of any doorway.
DOORWAY_AWAY = 1.3


def place_charger(world) -> Optional[Charger]:
    """Add a charger to ``world`` (in place) unless it has one; the charger added, or None
    (it had one, or no room has a free wall)."""
    if world.chargers():
        return None
    boxes = [world.bounds_world(o.id) for o in world.large_objects()]
    parkings = [(p.x, p.y) for o in world.large_objects() for _, p in world.parking_positions(o.id)]
    for room in world.rooms:
        if room.bounds is None:
            continue
        T = T_world_room(room)
        floor = room_outline(room)
        doors = [np.mean(rect, axis=0) for rect in room_openings(world, room)]
        for (cx, cy, yaw) in _wall_spots(room.bounds):
            dx, dy = cx + DOCK_DISTANCE * math.cos(yaw), cy + DOCK_DISTANCE * math.sin(yaw)
            # On this room's floor (an L-shaped room's bounds hold floor it lacks) and out
            # of every doorway's way.
            if not (outline_contains(floor, cx, cy) and outline_contains(floor, dx, dy, -0.3)):
                continue
            if any(math.hypot(dx - d[0], dy - d[1]) < DOORWAY_AWAY for d in doors):
                continue
            wx, wy = transform_xy(T, [(dx, dy)])[0]
            if any(_box_distance(b, wx, wy) < CLEARANCE for b in boxes):
                continue
            if any(math.hypot(wx - px, wy - py) < AWAY for px, py in parkings):
                continue
            charger = Charger(f"{room.id}_charger", Pose(round(cx, 3), round(cy, 3), 0, 0, 0, yaw),
                              Pose.planar(DOCK_DISTANCE, 0.0, 0.0), name="charging station")
            room.chargers.append(charger)
            world._reindex()
            return charger
    return None


def _wall_spots(bounds):
    """(x, y, inward yaw) in the room frame along each wall, every 0.1 m, 0.5 m from corners."""
    x0, y0, x1, y1 = bounds
    ys = np.arange(y0 + 0.5, y1 - 0.45, 0.1)
    xs = np.arange(x0 + 0.5, x1 - 0.45, 0.1)
    yield from ((x0 + 0.05, float(y), 0.0) for y in ys)
    yield from ((x1 - 0.05, float(y), math.pi) for y in ys)
    yield from ((float(x), y0 + 0.05, math.pi / 2) for x in xs)
    yield from ((float(x), y1 - 0.05, -math.pi / 2) for x in xs)


def _box_distance(box, x: float, y: float) -> float:
    """Distance (m) from the floor point (x, y) to a (2, 3) world box's footprint."""
    (lx, ly, _), (hx, hy, _) = box
    return math.hypot(max(lx - x, 0.0, x - hx), max(ly - y, 0.0, y - hy))
