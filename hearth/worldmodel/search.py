"""Where to look first: ordering search places by the HOBBIT cost.

    c(x, y) = c_bat(y) - k1 * c_prob(x, y) + k2 * c_pen(y)

for object x and place y (a large object that can hold small objects, seen from one of its
parking positions):

- ``c_bat(y)``: the path length in metres from the robot to the place's nearest reachable
  parking position, on the map's occupancy grid (walls, doorways, furniture, the robot's
  radius: hearth/worldmodel/navigation.py); the robot's battery and time go with it. A
  parking position no path reaches is not offered. On a map without rooms (no grid) it is
  the straight-line distance times a detour factor plus a fixed cost per room change.
- ``c_prob(x, y)``: the probability of finding x at y, learned from past searches kept with the
  map (``searchStats``): a Beta posterior ``(found + s * p0) / (searched + s)`` whose prior
  ``p0`` comes from the map (the believed parent, the object's default positions, other
  surfaces) with strength ``s``.
- ``c_pen(y)``: 1 when the place is in the room the user is in (searching there disturbs the
  user), else 0.

The weights are documented in docs/missions-end-to-end.md: k1 = 20 m (a place 20 m further away
is worth searching first when it is one whole unit of probability likelier), k2 = 1.5 m.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

from hearth.worldmodel.frames import room_at
from hearth.worldmodel.navigation import NoPath, nav_grid
from hearth.worldmodel.nodes import LargeObject, SmallObject
from hearth.worldmodel.pose import Pose


@dataclass(frozen=True)
class SearchWeights:
    k1: float = 20.0          # metres per unit of probability (at least; see k1_per_home_m)
    k2: float = 1.5           # metres of penalty for the user's room
    detour: float = 1.3       # path length / straight-line distance (maps without a grid)
    room_change_m: float = 2.0    # (maps without a grid)
    #: k1 grows with the home: at least this many times the largest path between two places
    #: (a place across a large flat is worth crossing it for when it is much likelier).
    k1_per_home_m: float = 1.5
    #: What looking at a place costs besides driving, in metres of path: a fixed part, each
    #: surface level looked at, each closed door opened (and closed again).
    effort_m: float = 1.0
    effort_per_level_m: float = 0.5
    effort_per_door_m: float = 1.5
    prior_parent: float = 0.6
    prior_default: float = 0.35
    prior_surface: float = 0.08
    prior_strength: float = 2.0


@dataclass(frozen=True)
class SearchPlace:
    """One place to look: a large object and the parking position to look from."""
    place: str
    parking: str
    pose: Pose
    cost: float
    probability: float
    path_m: float
    in_user_room: bool
    relation: str = "on"

    def as_dict(self) -> dict:
        return {"place": self.place, "parking": self.parking, "x": self.pose.x, "y": self.pose.y,
                "yaw": self.pose.yaw, "cost": round(self.cost, 4),
                "probability": round(self.probability, 4), "path_m": round(self.path_m, 3),
                "in_user_room": self.in_user_room, "relation": self.relation}


def effort(place: LargeObject, w: SearchWeights) -> float:
    """What searching a place costs besides the drive, in metres: looking at each of its
    surface levels (its drawers' too), opening (and closing) its closed doors and drawers
    (sliding doors: each half, one after the other)."""
    from hearth.worldmodel.containers import closed_to_open
    from hearth.worldmodel.validate import all_parts
    levels = len(place.surfaces) + sum(len(p.surfaces) for p in all_parts(place))
    return w.effort_m + w.effort_per_level_m * max(levels, 1) \
        + w.effort_per_door_m * closed_to_open(place)


def effective_k1(world, w: SearchWeights) -> float:
    """``k1`` for this home: the configured one, or ``k1_per_home_m`` times the longest path
    between two places' default parking positions when that is more (HOBBIT's weight was set
    for one flat; a larger home needs a larger one for probability to keep its say)."""
    poses = []
    for place in candidate_places(world):
        pp = world.parking_positions(place.id)
        if pp:
            poses.append((round(pp[0][1].x, 4), round(pp[0][1].y, 4)))
    grid = nav_grid(world)
    longest = _longest_path(grid, tuple(poses)) if grid is not None else None
    if longest is None:
        longest = 0.0
        for i, a in enumerate(poses):
            for b in poses[i + 1:]:
                longest = max(longest, math.hypot(a[0] - b[0], a[1] - b[1]) * w.detour)
    return max(w.k1, w.k1_per_home_m * longest)


def _longest_path(grid, poses: tuple) -> Optional[float]:
    """The longest grid path (m) between two of ``poses`` that a path joins (kept on the
    grid: one Dijkstra per pose); None when no two are joined."""
    cache = grid.memo.setdefault("longest_path", {})
    if poses in cache:
        return cache[poses]
    longest = None
    for i, a in enumerate(poses[:-1]):
        try:
            field = grid.distances_from(*a)
        except NoPath:
            continue
        for b in poses[i + 1:]:
            d = field.length_to(*b)
            if math.isfinite(d):
                longest = d if longest is None else max(longest, d)
    cache[poses] = longest
    return longest


def travel(world, robot_pose: Pose, weights: "SearchWeights" = None):
    """A function (x, y) -> metres of path from the robot to a floor point (inf: no path),
    and whether it is the grid's path length (True) or the straight-line estimate."""
    w = weights or SearchWeights()
    grid = nav_grid(world)
    if grid is not None:
        try:
            field = grid.distances_from(robot_pose.x, robot_pose.y)
            return field.length_to, True
        except NoPath:
            pass        # the robot is off the map's free floor: estimate as before
    return (lambda x, y: math.hypot(x - robot_pose.x, y - robot_pose.y) * w.detour), False


def candidate_places(world) -> list[LargeObject]:
    """Large objects that can hold small objects: those with surfaces (their own or their
    parts', a drawer's floor) or that hold some now."""
    from hearth.worldmodel.world import holds_small_objects
    return [o for o in world.large_objects() if holds_small_objects(o)]


def prior(world, obj: SmallObject, place: LargeObject, w: SearchWeights,
          believed_parent: Optional[str]) -> float:
    if place.id == believed_parent:
        return w.prior_parent
    if any(d.parent == place.id for d in obj.default_positions):
        return w.prior_default
    return w.prior_surface


def probability(world, object_id: str, place_id: str, w: SearchWeights = SearchWeights(),
                believed_parent: Optional[str] = None) -> float:
    obj = world.get(object_id)
    place = world.get(place_id)
    p0 = prior(world, obj, place, w, believed_parent)
    stat = world.search_stats(object_id).get(place_id)
    n, k = (stat.searched, stat.found) if stat else (0, 0)
    return (k + w.prior_strength * p0) / (n + w.prior_strength)


def search_order(world, object_id: str, robot_pose: Pose, user_room: Optional[str] = None,
                 weights: SearchWeights = SearchWeights(), exclude: tuple[str, ...] = (),
                 believed_parent: Optional[str] = None, learned: bool = True) -> list[SearchPlace]:
    """Places to search for ``object_id``, cheapest first.

    ``believed_parent`` defaults to the object's parent in the map. With ``learned=False`` the
    statistics are ignored (the fixed order the benchmark compares against).
    """
    obj = world.get(object_id)
    if believed_parent is None:
        p = world.parent(object_id)
        believed_parent = p.id if p is not None else None
    here = room_at(world, robot_pose.x, robot_pose.y)
    robot_room = here.id if here is not None else None
    k1 = effective_k1(world, weights)
    length_to, on_grid = travel(world, robot_pose, weights)
    out = []
    for place in candidate_places(world):
        if place.id in exclude:
            continue
        best = None
        for pk, pose in world.parking_positions(place.id):
            d = length_to(pose.x, pose.y)
            if math.isfinite(d) and (best is None or d < best[2]):
                best = (pk, pose, d)
        if best is None:
            continue
        room = world.room_of(place.id).id
        path = best[2] + (weights.room_change_m if not on_grid and robot_room
                          and room != robot_room else 0.0)
        if learned:
            prob = probability(world, object_id, place.id, weights, believed_parent)
        else:
            prob = prior(world, obj, place, weights, believed_parent)
        pen = 1.0 if user_room is not None and room == user_room else 0.0
        cost = path + effort(place, weights) - k1 * prob + weights.k2 * pen
        relation = place.surfaces[0].relation if place.surfaces else "on"
        out.append(SearchPlace(place.id, best[0].id, best[1], cost, prob, path, pen > 0, relation))
    out.sort(key=lambda s: (s.cost, s.place))
    return out
