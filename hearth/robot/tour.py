"""A tour of a simulated home for mapping it (`hearth tour`, docs/mapping.md): stops on the free
floor of every room, a full turn of views at each at two head tilts, recorded with drifting
odometry.

- ``plan_tour(world, options)``: the stops, room by room. In each room a grid of candidate
  stops (``spacing`` apart, ``wall_margin`` from the walls) keeps those whose robot disc
  (``robot_radius`` + ``clearance``) is clear of every furniture footprint (the convex hull of
  the object's meshes on the floor), at most ``max_stops_per_room`` of them spread by farthest
  point sampling; a room with no free grid point gets its freest point, a room with none at
  all is skipped (and said so). Rooms are visited nearest first, stops in a room nearest first.
- ``drive_tour(robot, sim, stops, ...)``: at every stop the base turns through a full circle
  in ``yaw_step_deg`` steps from the yaw it arrived with (it drives between stops without
  turning, so every stop's views share one set of directions) and the head takes a frame at each tilt (zig-zag: the two tilts
  alternate so that consecutive frames differ by one move, which keeps them overlapping for
  the mapping's odometry); at the end of a room the robot goes back to its first stop for one
  more pair of frames (a revisit: the loop closure the pose graph corrects drift with).
- Odometry drift (``OdometryDrift``): after every drive the believed pose moves by the true
  motion plus an error drawn per drive: a translation error of ``distance`` times the distance
  driven (standard deviation, each axis of the base frame) and a yaw error of ``rotation``
  times the angle turned. The believed pose is what the recording's ``base_pose`` and
  ``T_world_camera`` carry; the truth goes in the capture's ``truth``.

The simulated robot drives in straight lines and through walls (the generated homes have no
doorways); the tour never stops inside furniture but may drive through it. A real robot's
manual drive-through is the same input to `hearth map build`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from hearth.robot.adapter import wait
from hearth.worldmodel.frames import planar_T, transform_xy
from hearth.worldmodel.pose import Pose, wrap_angle


@dataclass(frozen=True)
class TourOptions:
    """Where the tour stops and what it looks at (metres, radians)."""
    spacing: float = 1.5              #: between candidate stops on a room's grid
    wall_margin: float = 0.45         #: stops keep this far from the walls
    robot_radius: float = 0.30
    clearance: float = 0.10           #: beyond the robot radius, from furniture footprints
    max_stops_per_room: int = 4
    yaw_step_deg: float = 30.0        #: base turn between views at a stop
    tilts: tuple[float, ...] = (0.20, 0.62)   #: head tilts (positive looks down)
    revisit: bool = True              #: back to a room's first stop at its end


@dataclass(frozen=True)
class OdometryDrift:
    """Dead-reckoning error per drive: standard deviations as fractions of the distance driven
    (translation, each axis of the base frame) and of the angle turned (yaw)."""
    distance: float = 0.015
    rotation: float = 0.015

    def apply(self, believed: Pose, start_true: Pose, end_true: Pose,
              rng: np.random.Generator) -> Pose:
        """The believed pose after driving from ``start_true`` to ``end_true``."""
        delta = np.linalg.inv(start_true.matrix()) @ end_true.matrix()
        d = math.hypot(delta[0, 3], delta[1, 3])
        turn = abs(wrap_angle(end_true.yaw - start_true.yaw))
        ex, ey = rng.normal(0.0, self.distance * d, 2) if d > 0 else (0.0, 0.0)
        eyaw = rng.normal(0.0, self.rotation * turn) if turn > 0 else 0.0
        noisy = planar_T(delta[0, 3] + ex, delta[1, 3] + ey,
                         math.atan2(delta[1, 0], delta[0, 0]) + eyaw)
        return Pose.from_matrix(believed.matrix() @ noisy)


@dataclass
class Stop:
    """A place the tour stops (world frame, metres) in a room."""
    room: str
    x: float
    y: float


@dataclass
class TourPlan:
    stops: list[Stop]
    skipped_rooms: list[str] = field(default_factory=list)


def footprints(world, room) -> list[np.ndarray]:
    """Convex floor polygons (world frame) of every large object of ``room``."""
    from hearth.worldmodel.geometry import object_meshes
    from hearth.worldmodel.homegen_geometry import convex_hull_xy
    out = []
    for obj in room.objects:
        meshes = object_meshes(world, obj, children=False)
        pts = np.vstack([np.asarray(m.mesh.vertices) for m in meshes if len(m.mesh.vertices)])
        if len(pts) >= 3:
            out.append(convex_hull_xy(pts))
    return out


def _free(p, hulls, r) -> bool:
    from hearth.worldmodel.homegen_geometry import disc_clear
    return all(disc_clear(p, h, r) for h in hulls)


def _grid(lo: float, hi: float, step: float) -> np.ndarray:
    n = max(1, int(math.ceil((hi - lo) / step)))
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def room_stops(world, room, options: TourOptions = TourOptions()) -> list[Stop]:
    """The stops of one room (world frame), or [] when no robot fits on its free floor."""
    if room.bounds is None:
        return []
    x0, y0, x1, y1 = room.bounds
    m = options.wall_margin
    hulls = footprints(world, room)
    r = options.robot_radius + options.clearance
    T = room.pose.matrix()
    if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
        return []
    gx, gy = _grid(x0 + m, x1 - m, options.spacing), _grid(y0 + m, y1 - m, options.spacing)
    cand = transform_xy(T, [(x, y) for x in gx for y in gy])
    free = [p for p in cand if _free(p, hulls, r)]
    if not free:
        # the freest point of a fine grid where at least the robot fits
        fine = transform_xy(T, [(x, y) for x in _grid(x0 + m, x1 - m, 0.1)
                                for y in _grid(y0 + m, y1 - m, 0.1)])
        fits = [p for p in fine if _free(p, hulls, options.robot_radius)]
        if not fits:
            return []
        free = [fits[len(fits) // 2]]
    # farthest point sampling from the point nearest the room's centre
    centre = transform_xy(T, [((x0 + x1) / 2, (y0 + y1) / 2)])[0]
    pts = np.asarray(free)
    chosen = [int(np.argmin(np.linalg.norm(pts - centre, axis=1)))]
    while len(chosen) < min(options.max_stops_per_room, len(pts)):
        d = np.min(np.linalg.norm(pts[:, None] - pts[chosen][None], axis=2), axis=1)
        chosen.append(int(np.argmax(d)))
    return [Stop(room.id, float(pts[i][0]), float(pts[i][1])) for i in chosen]


def _nearest_first(items, xy, key) -> list:
    left, out = list(items), []
    here = np.asarray(xy, float)
    while left:
        k = min(range(len(left)), key=lambda i: float(np.linalg.norm(key(left[i]) - here)))
        item = left.pop(k)
        out.append(item)
        here = key(item)
    return out


def plan_tour(world, options: TourOptions = TourOptions(), start_xy=None) -> TourPlan:
    """The tour's stops: every room with free floor, nearest room first from ``start_xy``
    (default: the first room's first stop), stops in a room nearest first."""
    by_room, skipped = {}, []
    for room in world.rooms:
        stops = room_stops(world, room, options)
        if stops:
            by_room[room.id] = stops
        else:
            skipped.append(room.id)
    if not by_room:
        return TourPlan([], skipped)
    first = next(iter(by_room.values()))[0]
    here = np.array(start_xy if start_xy is not None else (first.x, first.y), float)
    centre = {rid: np.mean([(s.x, s.y) for s in st], axis=0) for rid, st in by_room.items()}
    out: list[Stop] = []
    for rid in _nearest_first(list(by_room), here, lambda r: centre[r]):
        stops = _nearest_first(by_room[rid], here, lambda s: np.array((s.x, s.y)))
        out += stops
        here = np.array((stops[-1].x, stops[-1].y))
    return TourPlan(out, skipped)


@dataclass
class TourSummary:
    frames: int = 0
    stops: int = 0
    rooms: list[str] = field(default_factory=list)
    skipped_rooms: list[str] = field(default_factory=list)
    path_m: float = 0.0
    turned_deg: float = 0.0
    final_drift_m: float = 0.0
    final_drift_deg: float = 0.0

    def as_dict(self) -> dict:
        return dict(frames=self.frames, stops=self.stops, rooms=self.rooms,
                    skipped_rooms=self.skipped_rooms, path_m=round(self.path_m, 2),
                    turned_deg=round(self.turned_deg, 1),
                    final_drift_m=round(self.final_drift_m, 3),
                    final_drift_deg=round(self.final_drift_deg, 2))


def drive_tour(robot, sim, plan: TourPlan, options: TourOptions = TourOptions(),
               drift: OdometryDrift = OdometryDrift(), seed: int = 0,
               progress: Optional[Callable[[str], None]] = None) -> TourSummary:
    """Drive ``plan`` with ``robot`` (the simulated robot ``sim``, or a ``RecordingRobot``
    around it that records every capture), drifting the believed pose by ``drift``. The robot
    must already stand at the first stop."""
    rng = np.random.default_rng(seed)
    summary = TourSummary(stops=len(plan.stops), skipped_rooms=list(plan.skipped_rooms))
    n_yaw = max(1, int(round(360.0 / options.yaw_step_deg)))
    step = 2 * math.pi / n_yaw

    def drive(x: float, y: float, yaw: float) -> None:
        start_true, believed = sim.true_pose(), sim.base_pose()
        goal_true = Pose.planar(x, y, yaw)
        # the goal in the believed frame that ends at the planned true pose
        goal = Pose.from_matrix(goal_true.matrix() @ sim.localisation_error().matrix())
        status = wait(robot.navigate_to(goal), sim.clock)
        if status != "succeeded":
            return
        end_true = sim.true_pose()
        summary.path_m += start_true.planar_distance(end_true)
        summary.turned_deg += abs(math.degrees(wrap_angle(end_true.yaw - start_true.yaw)))
        sim.drift_odometry(drift.apply(believed, start_true, end_true, rng))

    def look(tilts) -> None:
        for t in tilts:
            robot.set_head(0.0, t)
            robot.capture()
            summary.frames += 1

    rooms_seen: list[str] = []
    for k, stop in enumerate(plan.stops):
        here = sim.true_pose()
        new_room = stop.room not in rooms_seen
        if new_room:
            rooms_seen.append(stop.room)
            if progress:
                progress(f"room {stop.room} ({len(rooms_seen)}/{len({s.room for s in plan.stops})})")
        # The sweep starts at the yaw the robot arrives with: it drives between stops without
        # turning, so a drive into another room (no view links the rooms of a generated home:
        # they have no doorways) adds no turning error the map cannot see.
        heading = here.yaw
        for i in range(n_yaw):
            drive(stop.x, stop.y, wrap_angle(heading + i * step))
            look(options.tilts if i % 2 == 0 else options.tilts[::-1])
        last_in_room = k + 1 == len(plan.stops) or plan.stops[k + 1].room != stop.room
        if options.revisit and last_in_room:
            first = next(s for s in plan.stops if s.room == stop.room)
            if first is not stop:
                drive(first.x, first.y, sim.true_pose().yaw)
                look(options.tilts)
    summary.rooms = rooms_seen
    err = sim.localisation_error()
    summary.final_drift_m = math.hypot(err.x, err.y)
    summary.final_drift_deg = abs(math.degrees(err.yaw))
    return summary


def record_tour(world, out, options: TourOptions = TourOptions(),
                drift: OdometryDrift = OdometryDrift(), seed: int = 0, format: str = "hearth",
                intrinsics=None, info: Optional[dict] = None,
                progress: Optional[Callable[[str], None]] = None) -> TourSummary:
    """Plan and drive a tour of ``world`` (the truth; not changed) on a simulated robot and
    record it to ``out`` (a Hearth recording, or with ``format="mcap"`` a ROS 2 bag). The
    robot starts at the first stop facing +x with no localisation error, so the recording's
    map frame is the world's. Raises RobotError when no room has free floor."""
    from hearth.robot.clock import SimClock
    from hearth.robot.errors import RobotError
    from hearth.robot.recording import RecordingRobot
    from hearth.robot.simulated import SimulatedRobot

    plan = plan_tour(world, options)
    if not plan.stops:
        raise RobotError("nothing to tour: no room has free floor for the robot "
                         f"({len(world.rooms)} room{'s' if len(world.rooms) != 1 else ''})")
    first = plan.stops[0]
    sim = SimulatedRobot(world.copy(), clock=SimClock(), start_pose=(first.x, first.y, 0.0),
                         intrinsics=intrinsics, seed=seed)
    meta = dict(tour=True, seed=seed, drift=dict(distance=drift.distance, rotation=drift.rotation),
                tilts=list(options.tilts), yaw_step_deg=options.yaw_step_deg) | dict(info or {})
    robot = RecordingRobot(sim, out, info=meta, format=format)
    try:
        summary = drive_tour(robot, sim, plan, options, drift, seed, progress)
    finally:
        robot.close()
    return summary
