"""A simulated day (``hearth day``, ``hearth bench day``): a :class:`~hearth.executive.day.Day` over a
simulated robot on a simulated clock, with the user's requests, emergencies, outings and
moves between rooms as timed :class:`Happening` s.

Fast: the executive ticks at its rate only while a mission runs; with nothing to do the clock
jumps to the next thing due (a happening, a schedule slot) in steps of at most ``IDLE_STEP``
seconds (so the battery watch still looks), and while every running skill says when it will
next have news (``idle_until``: a robot charging on its dock) the clock jumps to then. Nothing
the missions see differs from ticking through: the battery and every robot action are
integrated from the clock.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

from hearth.executive.day import DAY_S, Day, Schedule, mission_paths

#: The longest clock jump (s) with nothing running.
IDLE_STEP = 300.0


@dataclass(frozen=True)
class Happening:
    """Something outside the robot at ``t`` (day seconds): ``request`` (``mission`` with
    ``params``), ``emergency`` (``room``: where the call came from, "" unknown), ``away`` /
    ``home``, ``user_moves`` (to ``room``)."""
    t: float
    kind: str
    mission: str = ""
    params: dict = field(default_factory=dict)
    room: str = ""


def simulate_day(world: Any, schedule: Schedule, hours: float = 24.0,
                 happenings: list[Happening] = (), user_room: Optional[str] = None,
                 tick_hz: float = 10.0, runs_dir: Optional[str] = None,
                 day_log: Optional[str] = None, battery_level: float = 1.0,
                 on_event: Optional[Callable[[dict], None]] = None,
                 robot_kwargs: Optional[dict] = None,
                 finish_s: float = 0.0) -> tuple[dict, Day, Any]:
    """Run ``hours`` of a simulated day on ``world`` (the belief; the truth is a copy), then
    up to ``finish_s`` more seconds (no new slots or happenings) for the missions still
    running or queued to end. Returns (the day's report, the Day, the simulated robot)."""
    from hearth.executive.executive import Executive
    from hearth.robot.battery import Battery
    from hearth.robot.clock import SimClock
    from hearth.robot.simulated import SimulatedRobot

    clock = SimClock()
    truth = world.copy()
    start = _start_pose(world)
    robot = SimulatedRobot(truth, clock=clock, start_pose=start,
                           battery=Battery(level=battery_level),
                           person_room=user_room or world.rooms[0].id, **(robot_kwargs or {}))
    ex = Executive(world, robot, clock=clock, tick_hz=tick_hz, runs_dir=runs_dir,
                   background=False)
    day = Day(ex, robot, mission_paths(), schedule, on_event=on_event, log_path=day_log)
    pending = sorted(happenings, key=lambda h: h.t)
    end = hours * 3600.0
    try:
        while clock.now() < end:
            now_day = day.day_seconds()
            while pending and pending[0].t <= now_day:
                _apply(day, robot, pending.pop(0))
            day.step()
            if ex.tick():
                wake = _idle_until(ex)
                awaited = day.level_awaited()
                if wake is not None and awaited is not None:
                    b = robot.battery
                    wake = min(wake, b.t + b.model.seconds_to(b.level, awaited) + 1.0)
                if wake is not None:
                    jump = min(wake, _next_due(day, pending, now_day, end)) - clock.now()
                    if jump > 0:
                        clock.advance(jump)
                continue
            nxt = _next_due(day, pending, now_day, end)
            clock.advance(max(min(nxt - clock.now(), IDLE_STEP), 1.0 / tick_hz))
        day.step()
        day.schedule = Schedule((), day.schedule.battery, day.schedule.start, day.schedule.file)
        last = clock.now() + finish_s
        while clock.now() < last and not ex.idle():
            day.step()
            if ex.tick():
                wake = _idle_until(ex)
                if wake is not None and wake > clock.now():
                    clock.advance(min(wake, last) - clock.now())
            else:
                clock.advance(1.0 / tick_hz)
        report = day.report()     # before the shutdown cancels what still runs: "open"
    finally:
        ex.shutdown()
        day.close()
    return report, day, robot


def _start_pose(world):
    chargers = world.chargers()
    return world.dock_pose(chargers[0].id) if chargers else None


def _apply(day: Day, robot: Any, h: Happening) -> None:
    if h.kind == "request":
        day.submit(h.mission, dict(h.params), source="user request")
    elif h.kind == "emergency":
        day.emergency(h.room, source="call")
    elif h.kind == "away":
        robot.person_room_before_away = robot.person_room
        robot.person_room = None
        day.set_away(True)
    elif h.kind == "home":
        robot.person_room = h.room or getattr(robot, "person_room_before_away", None)
        day.set_away(False)
    elif h.kind == "user_moves":
        robot.person_room = h.room
    else:
        raise ValueError(f"unknown happening {h.kind!r}")


def _next_due(day: Day, pending: list[Happening], now_day: float, end: float) -> float:
    """The clock time of the next happening or schedule slot (or the end)."""
    offset = day.schedule.start           # day seconds at clock 0
    best = end
    if pending:
        best = min(best, pending[0].t - offset)
    for e in day.schedule.entries:
        slots = e.slots(now_day, now_day + DAY_S)
        if slots:
            best = min(best, slots[0] - offset)
    return best


def _idle_until(ex: Any) -> Optional[float]:
    """The clock time until which every running leaf of the current tree says nothing will
    change (its ``idle_until()``), or None when one cannot say."""
    tree = ex.current_tree
    if tree is None:
        return None
    from py_trees.common import Status
    wake = None
    for node in tree.root.iterate():
        if node.status != Status.RUNNING or getattr(node, "children", None):
            continue
        fn = getattr(node, "idle_until", None)
        t = fn() if callable(fn) else None
        if t is None:
            return None
        wake = t if wake is None else min(wake, t)
    return wake
