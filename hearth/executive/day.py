"""A robot's day, as HOBBIT's behaviour control runs it (docs/day.md).

A :class:`Day` sits over an :class:`~hearth.executive.executive.Executive` and adds what a day needs
on top of its priorities and preemption:

- a **schedule** (:class:`Schedule`, from a ``day.yaml``): missions at times of day or every N
  minutes; a slot that cannot run (too late, the user away, the entry's last run still going)
  is reported missed, and no slot ever runs twice;
- a **battery watch**: below ``battery.low`` (a runtime value, :meth:`Day.set_battery`) it
  submits ``recharge`` above every routine mission, which the executive's preemption halts
  cleanly (robot stopped, map consistent);
- **emergencies** (:meth:`Day.emergency`): ``go_to_user`` above everything, a recharge too,
  unless the battery is below ``battery.critical`` while recharging: then it waits for the
  charge to pass the critical level;
- **resuming**: a preempted mission is submitted again, as its file declares
  (``interrupted: restart`` or ``{then: resume, progress: KEY, param: NAME}``);
- **away** (:meth:`Day.set_away`): the schedule pauses (its slots are reported missed).

Everything it decides is a day event: a JSON line in the day log, a callback (the command
service's event hub, so the monitor shows it) and a line for a person.

Time of day: on a simulated clock, ``start`` (seconds after midnight) plus the clock's
seconds; on a wall clock, the local time. Slot times are "day seconds": seconds after the
midnight the day started at (the second day's 08:00 is 86400 + 28800).
"""
from __future__ import annotations

import json
import math
import threading
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional

from hearth.executive.errors import MissionError
from hearth.executive.events import TERMINAL, EventKind, RunState

#: Submission priorities: routine (schedule) < user requests < reminders < recharge < emergency.
ROUTINE, REQUEST, REMINDER, RECHARGE, EMERGENCY = 0, 10, 20, 50, 100
#: The missions a day runs (the shipped ones of these names).
DAY_MISSIONS = ("recharge", "go_to_user", "deliver_reminder", "emergency_patrol",
                "fetch_object", "go_to_rest")


def mission_paths(names=DAY_MISSIONS) -> dict[str, str]:
    from hearth import missions_dir
    base = Path(missions_dir())
    return {n: str(base / f"{n}.yaml") for n in names if (base / f"{n}.yaml").exists()}


DAY_S = 86_400.0


class ScheduleError(MissionError):
    """A bad day schedule file (file and line)."""


# -- the schedule ---------------------------------------------------------------------------
@dataclass(frozen=True)
class BatteryPolicy:
    """Levels 0..1: below ``low`` recharge; below ``critical`` not even an emergency
    interrupts the recharge; charge to ``charge_to``."""
    low: float = 0.30
    critical: float = 0.15
    charge_to: float = 0.95

    def check(self) -> Optional[str]:
        if not 0.0 < self.critical < self.low < self.charge_to <= 1.0:
            return (f"battery levels must be 0 < critical ({self.critical}) < low ({self.low}) "
                    f"< charge_to ({self.charge_to}) <= 1")
        return None


@dataclass(frozen=True)
class Entry:
    """One line of the schedule: ``mission`` with ``params`` at ``at`` (day seconds, one slot
    a day) or every ``every`` seconds from ``start`` to ``end`` (seconds of the day)."""
    name: str
    mission: str
    params: dict[str, Any]
    priority: int
    at: Optional[float] = None
    every: Optional[float] = None
    start: float = 0.0
    end: float = DAY_S
    grace: float = 900.0
    line: int = 0

    def slots(self, t0: float, t1: float) -> list[float]:
        """Slot times (day seconds) in (t0, t1]."""
        out: list[float] = []
        day = math.floor(max(t0, 0.0) / DAY_S)
        while day * DAY_S <= t1:
            base = day * DAY_S
            if self.at is not None:
                times = [base + self.at]
            else:
                n0 = max(math.ceil((t0 - base - self.start) / self.every), 0)
                times = []
                k = n0
                while True:
                    t = base + self.start + k * self.every
                    if t > base + self.end or t > t1:
                        break
                    times.append(t)
                    k += 1
            out += [t for t in times if t0 < t <= t1]
            day += 1
        return out


@dataclass(frozen=True)
class Schedule:
    entries: tuple[Entry, ...]
    battery: BatteryPolicy = BatteryPolicy()
    start: float = 7 * 3600.0        # a simulated day's time of day at clock 0
    file: str = "<schedule>"


def parse_clock_time(text: Any) -> float:
    """"HH:MM" (or "HH:MM:SS") -> seconds after midnight; ValueError otherwise."""
    parts = str(text).split(":")
    if len(parts) not in (2, 3) or not all(p.isdigit() for p in parts):
        raise ValueError(f"{text!r} is not a time of day (HH:MM)")
    h, m, s = (int(p) for p in parts + ["0"] * (3 - len(parts)))
    if not (h <= 24 and m < 60 and s < 60 and h * 3600 + m * 60 + s <= DAY_S):
        raise ValueError(f"{text!r} is not a time of day (HH:MM)")
    return float(h * 3600 + m * 60 + s)


def clock_text(day_s: float) -> str:
    """Day seconds -> "HH:MM:SS" (with "+Nd" from the second day on)."""
    d, s = divmod(int(round(day_s)), int(DAY_S))
    text = f"{s // 3600:02d}:{s % 3600 // 60:02d}:{s % 60:02d}"
    return text + (f" +{d}d" if d else "")


def load_schedule(path: str | Path, known_missions: Optional[set[str]] = None) -> Schedule:
    """Read and check a day schedule (docs/day.md); ScheduleError with file and line."""
    from hearth.executive.missionfile import load_yaml
    path = str(path)
    try:
        data = load_yaml(path)
    except MissionError as err:
        raise ScheduleError(err.message, file=err.file or path, line=err.line) from None

    def bad(msg: str, node: Any = None, key: Any = None) -> ScheduleError:
        line = getattr(node, "line", 0) or 0
        if key is not None and hasattr(node, "key_lines"):
            line = node.key_lines.get(key, line)
        return ScheduleError(msg, file=path, line=line)

    if not isinstance(data, dict) or not isinstance(data.get("day"), dict):
        raise bad("a schedule is a mapping with a 'day:' section (docs/day.md)", data)
    day = data["day"]
    unknown = set(day) - {"start", "battery", "entries"}
    if unknown:
        raise bad(f"unknown key {sorted(unknown)[0]!r} (known: start, battery, entries)", day)
    try:
        start = parse_clock_time(day.get("start", "07:00"))
    except ValueError as err:
        raise bad(f"start: {err}", day, "start") from None
    b = day.get("battery") or {}
    if not isinstance(b, dict) or set(b) - {"low", "critical", "charge_to"}:
        raise bad("battery: a mapping of low, critical, charge_to (levels 0..1)", day, "battery")
    try:
        battery = BatteryPolicy(**{k: float(v) for k, v in b.items()})
    except (TypeError, ValueError):
        raise bad("battery: levels are numbers 0..1", day, "battery") from None
    why = battery.check()
    if why:
        raise bad(f"battery: {why}", day, "battery")
    entries = []
    raw = day.get("entries") or []
    if not isinstance(raw, list):
        raise bad("entries: a list of {mission, at | every, ...}", day, "entries")
    names: set[str] = set()
    for i, e in enumerate(raw):
        line = raw.item_lines[i] if hasattr(raw, "item_lines") else 0
        where = ScheduleError
        if not isinstance(e, dict):
            raise where("an entry is a mapping {mission, at | every, ...}", file=path, line=line)
        extra = set(e) - {"mission", "at", "every", "from", "until", "params", "priority",
                          "grace", "name"}
        if extra:
            raise bad(f"unknown key {sorted(extra)[0]!r} in an entry", e)
        mission = e.get("mission")
        if not isinstance(mission, str):
            raise bad("an entry needs mission: NAME", e)
        if known_missions is not None and mission not in known_missions:
            raise bad(f"no mission named {mission!r} (known: {', '.join(sorted(known_missions))})",
                      e, "mission")
        if ("at" in e) == ("every" in e):
            raise bad("an entry has either at: HH:MM or every: MINUTES", e)
        try:
            at = parse_clock_time(e["at"]) if "at" in e else None
            lo = parse_clock_time(e.get("from", "00:00"))
            hi = parse_clock_time(e.get("until", "24:00"))
        except ValueError as err:
            raise bad(str(err), e) from None
        every = None
        if "every" in e:
            if not isinstance(e["every"], (int, float)) or isinstance(e["every"], bool) \
                    or not 1 <= e["every"] <= 1440:
                raise bad("every: minutes, 1 to 1440", e, "every")
            every = float(e["every"]) * 60.0
            if lo >= hi:
                raise bad("from must be before until", e, "from")
        params = e.get("params") or {}
        if not isinstance(params, dict):
            raise bad("params: a mapping name: value", e, "params")
        priority = e.get("priority", REMINDER if mission == "deliver_reminder" else ROUTINE)
        if not isinstance(priority, int) or isinstance(priority, bool) \
                or not 0 <= priority < RECHARGE:
            raise bad(f"priority: a whole number 0..{RECHARGE - 1} (recharge and emergencies "
                      "are above the schedule)", e, "priority")
        grace = e.get("grace", 15)
        if not isinstance(grace, (int, float)) or isinstance(grace, bool) or not 0 <= grace <= 1440:
            raise bad("grace: minutes a slot may start late, 0 to 1440", e, "grace")
        name = str(e.get("name") or f"{mission}@{e.get('at', 'every ' + str(e.get('every')))}")
        if name in names:
            raise bad(f"two entries are named {name!r}", e)
        names.add(name)
        entries.append(Entry(name, mission, {str(k): v for k, v in params.items()}, priority,
                             at=at, every=every, start=lo, end=hi, grace=float(grace) * 60.0,
                             line=line))
    return Schedule(tuple(entries), battery, start, path)


def is_schedule_file(path: str | Path) -> bool:
    """Whether a YAML file is a day schedule (a top-level ``day:`` key, no ``tree:``)."""
    import yaml
    try:
        with open(path, encoding="utf-8") as f:
            head = f.read(1 << 16)
        keys = [ln.split(":", 1)[0] for ln in head.splitlines()
                if ln and not ln[0].isspace() and not ln.startswith("#") and ":" in ln]
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return False
    return "day" in keys and "tree" not in keys


def schedule_problems(path: str | Path) -> list[ScheduleError]:
    """The problems of a schedule file, checked against the shipped missions (their
    parameters' names and types; what they name in a map is checked when a day starts on
    it). Empty: fine."""
    from hearth.executive.missionfile import load_mission, skill_registry
    paths = mission_paths()
    try:
        schedule = load_schedule(path, set(paths))
    except ScheduleError as err:
        return [err]
    problems: list[ScheduleError] = []
    skills = skill_registry()
    for e in schedule.entries:
        try:
            load_mission(paths[e.mission], skills).resolve_parameters(dict(e.params))
        except MissionError as err:
            what = f"parameter {err.param}: " if err.param else ""
            problems.append(ScheduleError(f"{e.mission}: {what}{err.message}", file=str(path),
                                          line=e.line))
    return problems


# -- the day --------------------------------------------------------------------------------
@dataclass
class Chain:
    """A mission and its resubmissions after interruptions."""
    first: str
    mission: str
    interrupted: int = 0
    outcome: Optional[str] = None      # the last run's, once it has ended
    reason: str = ""


@dataclass
class Stats:
    """Counts of one day (the report reads them, and the chains)."""
    succeeded: int = 0
    failed: int = 0
    cancelled: int = 0
    interrupted: int = 0
    resumed: int = 0
    restarted: int = 0
    slots_run: int = 0
    slots_missed: int = 0
    recharges: int = 0
    emergencies: int = 0
    emergencies_preempting: int = 0
    emergencies_joined: int = 0
    emergency_response_s: list[float] = field(default_factory=list)
    #: the responses to calls that came while another mission ran (it had to be halted)
    emergency_response_preempting_s: list[float] = field(default_factory=list)
    #: interruptions by the mission that preempted (recharge, go_to_user, a reminder...)
    interrupted_by: dict[str, int] = field(default_factory=dict)
    map_inconsistent: int = 0
    robot_not_stopped: int = 0
    battery_min: float = 1.0
    below_critical_s: float = 0.0
    docked_s: float = 0.0


class Day:
    """See the module docstring. ``missions``: name -> mission file path (or loaded Mission).
    ``on_event(event_dict)``: called for each day event (also written to ``log_path``)."""

    def __init__(self, executive: Any, robot: Any, missions: dict[str, Any],
                 schedule: Optional[Schedule] = None,
                 on_event: Optional[Callable[[dict], None]] = None,
                 log_path: Optional[str | Path] = None,
                 submit: Optional[Callable[[str, dict, int, str], Any]] = None):
        self.ex = executive
        #: how a mission is submitted: (name, params, priority, source) -> handle; by default
        #: straight to the executive (the command service's, so the API lists the runs)
        self._submit_fn = submit
        self.robot = robot
        self.schedule = schedule or Schedule(())
        self.battery = self.schedule.battery
        self.missions = {n: executive.load(m) for n, m in missions.items()}
        self.on_event = on_event
        self.stats = Stats()
        self.away = False
        self._lock = threading.RLock()
        self._chains: dict[str, Chain] = {}          # run id -> its chain
        self._runs: dict[str, Any] = {}              # run id -> handle (ours, live or ended)
        self._given: dict[str, dict] = {}            # run id -> the parameters submitted
        self._entry_run: dict[str, str] = {}         # schedule entry -> its last run id
        self._fired: set[tuple[str, float]] = set()
        self._missed: list[dict] = []
        self._emergency_at: dict[str, float] = {}    # go_to_user run -> request time (clock)
        self._moving_paths: dict[str, set[str]] = {}
        self._critical = False
        self._held: list[tuple[float, str, str]] = []   # emergencies waiting for charge
        self._preempting: set[str] = set()              # emergency runs that halted another
        self._last_check: Optional[float] = None
        self._last_t = self.ex.clock.now()
        self._origin_wall = None
        self.check_schedule()
        self._log = open(log_path, "a", encoding="utf-8") if log_path is not None else None
        self.log_path = str(log_path) if log_path is not None else None
        self._unsubscribe = executive.subscribe(self._on_run_event)

    def check_schedule(self) -> None:
        """Every entry names a mission of this day with parameters it accepts in this map
        (ScheduleError with the schedule's file and the entry's line), so a bad entry is
        found when the day starts, not at its time."""
        for needed in ("recharge", "go_to_user"):
            if needed not in self.missions:
                raise ScheduleError(f"a day needs the {needed} mission", file=self.schedule.file)
        for e in self.schedule.entries:
            m = self.missions.get(e.mission)
            if m is None:
                raise ScheduleError(f"no mission named {e.mission!r} (known: "
                                    f"{', '.join(sorted(self.missions))})",
                                    file=self.schedule.file, line=e.line)
            try:
                m.resolve_parameters(m.resolve_in_map(dict(e.params), self.ex.world))
            except MissionError as err:
                what = f"parameter {err.param}: " if err.param else ""
                raise ScheduleError(f"{e.mission}: {what}{err.message}",
                                    file=self.schedule.file, line=e.line) from None

    def close(self) -> None:
        self._unsubscribe()
        if self._log is not None:
            self._log.close()
            self._log = None

    # -- time --------------------------------------------------------------------------
    def day_seconds(self) -> float:
        """Now in day seconds (see the module docstring)."""
        clock = self.ex.clock
        if getattr(clock, "simulated", False):
            return self.schedule.start + clock.now()
        wall = clock.wall()
        if self._origin_wall is None:
            lt = _time.localtime(wall)
            self._origin_wall = wall - (lt.tm_hour * 3600 + lt.tm_min * 60 + lt.tm_sec)
        return wall - self._origin_wall

    def now_text(self) -> str:
        return clock_text(self.day_seconds())

    # -- requests ------------------------------------------------------------------------
    def submit(self, mission: str, params: Optional[dict] = None, priority: int = REQUEST,
               source: str = "request") -> Any:
        """Submit a mission the day watches (resubmitted after an interruption)."""
        m = self.missions.get(mission)
        if m is None:
            raise MissionError(f"no mission named {mission!r} in this day "
                               f"(known: {', '.join(sorted(self.missions))})")
        # Held across the submission: the run's events (another thread) wait for its record.
        with self._lock:
            h = self._send(mission, params or {}, priority, source)
            self._runs[h.id] = h
            self._given[h.id] = dict(params or {})
            self._chains[h.id] = Chain(h.id, mission)
        self._emit("submitted", run=h.id, mission=mission, priority=priority, source=source,
                   params=params or {})
        return h

    def _send(self, mission: str, params: dict, priority: int, source: str) -> Any:
        if self._submit_fn is not None:
            return self._submit_fn(mission, dict(params), priority, source)
        return self.ex.submit(self.missions[mission], priority=priority, **params)

    def emergency(self, user_room: str = "", source: str = "user") -> Any:
        """The user called for help: ``go_to_user`` above everything; its handle. While the
        robot recharges below the critical level the call is held (None is returned) and
        submitted as soon as the level is back above it. A call while a ``go_to_user`` is
        queued or running joins it (its handle is returned)."""
        with self._lock:
            level = self._level()
            current = self.ex.current
            held = (level < self.battery.critical and current is not None
                    and current.mission.name == "recharge")
            self.stats.emergencies += 1
            t = self.ex.clock.now()
            going = next((h for h in self._runs.values() if h.mission.name == "go_to_user"
                          and h.status not in TERMINAL), None)
            if going is not None:
                # The robot is already on its way to the user (a second call, another
                # button): the call joins that run rather than queueing a second one.
                self.stats.emergencies_joined += 1
                self._emit("emergency", user_room=user_room, source=source,
                           battery=round(level, 4), joins=going.id)
                return going
            self.stats.emergencies_preempting += current is not None
            self._emit("emergency", user_room=user_room, source=source,
                       battery=round(level, 4), waits_for_charge=held)
            if held:
                self._held.append((t, user_room, source))
                return None
            h = self._send_emergency(t, user_room, source)
            if current is not None:
                self._preempting.add(h.id)
            return h

    def level_awaited(self) -> Optional[float]:
        """The battery level a held emergency waits for (None: nothing held)."""
        with self._lock:
            return self.battery.critical if self._held else None

    def _send_emergency(self, t: float, user_room: str, source: str) -> Any:
        h = self.submit("go_to_user", {"user_room": user_room} if user_room else {},
                        priority=EMERGENCY, source=f"emergency ({source})")
        self._emergency_at[h.id] = t
        self._moving_paths[h.id] = {n.path for n in h.mission.nodes()
                                    if n.kind == "skill" and n.skill_name == "GoToRoom"}
        return h

    def set_away(self, away: bool) -> None:
        """The user is out (True) or back: the schedule pauses while away."""
        with self._lock:
            self.away = bool(away)
        try:
            self.ex.set_parameter("presence", "away" if away else "home")
        except MissionError:
            pass
        self._emit("away" if away else "home")

    def set_battery(self, low: Optional[float] = None, critical: Optional[float] = None,
                    charge_to: Optional[float] = None) -> BatteryPolicy:
        """Change the battery levels at run time (ValueError when out of order)."""
        b = self.battery
        new = BatteryPolicy(b.low if low is None else float(low),
                            b.critical if critical is None else float(critical),
                            b.charge_to if charge_to is None else float(charge_to))
        why = new.check()
        if why:
            raise MissionError(why, param="battery")
        self.battery = new
        self._emit("battery_policy", low=new.low, critical=new.critical, charge_to=new.charge_to)
        return new

    # -- the watch -------------------------------------------------------------------------
    def _level(self) -> float:
        state = self.robot.battery_state()
        return float(state.level)

    def step(self) -> None:
        """Check the battery and the schedule (call it often: every tick in simulation)."""
        now_clock = self.ex.clock.now()
        state = self.robot.battery_state()
        with self._lock:
            dt = max(now_clock - self._last_t, 0.0)
            self._last_t = now_clock
            s = self.stats
            s.battery_min = min(s.battery_min, state.level)
            if state.docked:
                s.docked_s += dt
            if state.level < self.battery.critical:
                s.below_critical_s += dt
                if not self._critical:
                    self._critical = True
                    self._emit("battery_critical", level=round(state.level, 4))
            elif self._critical and state.level >= self.battery.critical:
                self._critical = False
            if self._held and (state.level >= self.battery.critical
                               or not self._live("recharge")):
                held, self._held = self._held, []
                for t, room, source in held:
                    self._send_emergency(t, room, source)
            if state.level < self.battery.low and not state.docked and not self._live("recharge"):
                self._emit("battery_low", level=round(state.level, 4), threshold=self.battery.low)
                self.stats.recharges += 1
                self.submit("recharge", {"level": self.battery.charge_to}, priority=RECHARGE,
                            source="battery watch")
            self._run_schedule()

    def _live(self, mission: str) -> bool:
        return any(h.mission.name == mission and h.status not in TERMINAL
                   for h in self._runs.values())

    def _run_schedule(self) -> None:
        now = self.day_seconds()
        last = self._last_check if self._last_check is not None else now - 1e-6
        self._last_check = now
        for entry in self.schedule.entries:
            slots = entry.slots(last - entry.grace, now)
            for slot in slots:
                key = (entry.name, slot)
                if key in self._fired:
                    continue
                self._fired.add(key)
                late = now - slot
                if self.away:
                    self._miss(entry, slot, "the user is away")
                elif late > entry.grace:
                    self._miss(entry, slot, f"{late / 60:.0f} min late (grace "
                                            f"{entry.grace / 60:.0f} min)")
                elif slot != slots[-1]:
                    self._miss(entry, slot, "a later slot of the same entry is due")
                elif self._entry_busy(entry):
                    self._miss(entry, slot, f"its last run ({self._entry_run[entry.name]}) "
                                            "has not ended")
                else:
                    h = self.submit(entry.mission, dict(entry.params), entry.priority,
                                    source=f"schedule {entry.name} {clock_text(slot)}")
                    self._entry_run[entry.name] = h.id
                    self.stats.slots_run += 1
                    self._emit("slot", entry=entry.name, slot=clock_text(slot), run=h.id)

    def _entry_busy(self, entry: Entry) -> bool:
        rid = self._entry_run.get(entry.name)
        if rid is None:
            return False
        chain = self._chains.get(rid)
        return chain is not None and chain.outcome is None

    def _miss(self, entry: Entry, slot: float, why: str) -> None:
        self.stats.slots_missed += 1
        item = {"entry": entry.name, "mission": entry.mission, "slot": clock_text(slot),
                "why": why}
        self._missed.append(item)
        self._emit("slot_missed", **item)

    @property
    def missed(self) -> list[dict]:
        with self._lock:
            return list(self._missed)

    def chains(self) -> list[Chain]:
        with self._lock:
            seen, out = set(), []
            for c in self._chains.values():
                if id(c) not in seen:
                    seen.add(id(c))
                    out.append(c)
            return out

    # -- runs ending ----------------------------------------------------------------------
    def _on_run_event(self, ev: Any) -> None:
        if ev.kind is EventKind.STATUS:
            # The first drive towards the user starting (or finding the robot already at the
            # place it would drive to: a drive that ends in the tick it starts). Under the
            # lock: the run's events may come before emergency() has filed its request.
            if ev.data.get("status") not in ("RUNNING", "SUCCESS"):
                return
            with self._lock:
                if ev.path in self._moving_paths.get(ev.run, ()):
                    t0 = self._emergency_at.pop(ev.run, None)
                    self._moving_paths.pop(ev.run, None)
                    if t0 is not None:
                        self.stats.emergency_response_s.append(ev.time - t0)
                        if ev.run in self._preempting:
                            self.stats.emergency_response_preempting_s.append(ev.time - t0)
                        self._emit("emergency_response", run=ev.run,
                                   seconds=round(ev.time - t0, 3))
            return
        if ev.kind is not EventKind.RUN or ev.data.get("state") not in TERMINAL:
            return
        with self._lock:
            h = self._runs.get(ev.run)
            chain = self._chains.get(ev.run)
            if h is None or chain is None:
                return
            state = RunState(ev.data["state"])
            reason = str(ev.data.get("reason", ""))
            s = self.stats
            if state is RunState.PREEMPTED:
                s.interrupted += 1
                chain.interrupted += 1
                by = reason.split("preempted by ", 1)[-1].split(" (", 1)[0] \
                    if "preempted by " in reason else "other"
                s.interrupted_by[by] = s.interrupted_by.get(by, 0) + 1
                problems = self._map_problems()
                s.map_inconsistent += bool(problems)
                stopped = ev.data.get("robot_stopped", True) is not False
                s.robot_not_stopped += not stopped
                self._emit("interrupted", run=ev.run, mission=chain.mission, reason=reason,
                           robot_stopped=stopped, map_consistent=not problems,
                           **({"map_problems": problems[:3]} if problems else {}))
                self._again(h, chain, reason)
                return
            chain.outcome, chain.reason = state.value, reason
            if state is RunState.SUCCEEDED:
                s.succeeded += 1
            elif state is RunState.FAILED:
                s.failed += 1
            else:
                s.cancelled += 1
            self._emit("ended", run=ev.run, mission=chain.mission, outcome=state.value,
                       reason=reason, first=chain.first)

    def _again(self, h: Any, chain: Chain, reason: str) -> None:
        """Submit an interrupted mission again, resumed or restarted (lock held)."""
        mission = h.mission
        if mission.name == "recharge" and any(
                x.mission.name == "recharge" and x.status is RunState.QUEUED
                for x in self._runs.values()):
            chain.outcome, chain.reason = "replaced", "another recharge is queued"
            return
        how = mission.interrupted
        params = dict(self._given.get(h.id, {}))
        then = how.get("then", "restart")
        if then == "resume":
            outputs = h.result.outputs if h.result is not None else {}
            done = outputs.get(how["progress"])
            if done is not None:
                params[how["param"]] = list(done)
        new = self._send(mission.name, params, h.priority,  # (lock held)
                         f"{'resumed' if then == 'resume' else 'restarted'} after {h.id}")
        self._runs[new.id] = new
        self._given[new.id] = params
        self._chains[new.id] = chain
        if then == "resume":
            self.stats.resumed += 1
        else:
            self.stats.restarted += 1
        if self._emergency_at.pop(h.id, None) is not None:
            # an emergency interrupted by another: its response is the new run's
            self._emergency_at[new.id] = self.ex.clock.now()
            self._moving_paths[new.id] = self._moving_paths.get(h.id, set())
        for name, rid in self._entry_run.items():
            if rid == h.id:
                self._entry_run[name] = new.id
        self._emit("resumed" if then == "resume" else "restarted", run=new.id, previous=h.id,
                   mission=mission.name, params=params)

    def _map_problems(self) -> list[str]:
        """What is wrong with the belief map now (hearth.worldmodel.validate), in words."""
        world = getattr(self.ex, "world", None)
        if world is None or not hasattr(world, "apartment"):
            return []
        from hearth.worldmodel.validate import semantic_problems
        with world.lock:
            return [str(p) for p in semantic_problems(world.apartment, None, world.base_dir)]

    # -- reporting --------------------------------------------------------------------------
    def _emit(self, kind: str, **data: Any) -> None:
        event = {"e": "day", "kind": kind, "t": round(self.ex.clock.now(), 3),
                 "time": clock_text(self.day_seconds()), **data}
        if self._log is not None:
            self._log.write(json.dumps(event, default=str) + "\n")
            self._log.flush()
        if self.on_event is not None:
            try:
                self.on_event(event)
            except Exception:  # noqa: BLE001 - a listener must not stop the day
                pass

    def report(self) -> dict[str, Any]:
        """What happened so far, as the CLI and the bench print it."""
        import statistics
        s = self.stats
        chains = self.chains()
        interrupted = [c for c in chains if c.interrupted]
        resp = s.emergency_response_s
        return {
            "missions_run": len(chains),
            "succeeded": sum(c.outcome == "succeeded" for c in chains),
            "failed": sum(c.outcome == "failed" for c in chains),
            "cancelled": sum(c.outcome == "cancelled" for c in chains),
            "still_open": sum(c.outcome is None for c in chains),
            "interruptions": s.interrupted,
            "interrupted_by": dict(sorted(s.interrupted_by.items())),
            "interrupted_missions": len(interrupted),
            "interrupted_completed": sum(c.outcome == "succeeded" for c in interrupted),
            "interrupted_reported": sum(c.outcome in ("failed", "cancelled", "replaced")
                                        for c in interrupted),
            "interrupted_open": sum(c.outcome is None for c in interrupted),
            "resumed": s.resumed,
            "restarted": s.restarted,
            "recharges": s.recharges,
            "emergencies": s.emergencies,
            "emergencies_preempting": s.emergencies_preempting,
            "emergencies_joined": s.emergencies_joined,
            "emergency_response_s_median": (round(statistics.median(resp), 3) if resp else None),
            "emergency_response_s_max": round(max(resp), 3) if resp else None,
            "emergency_response_preempting_s": [round(x, 3) for x in
                                                s.emergency_response_preempting_s],
            "slots_run": s.slots_run,
            "slots_missed": s.slots_missed,
            "map_inconsistent_after_preemption": s.map_inconsistent,
            "robot_not_stopped_after_preemption": s.robot_not_stopped,
            "battery_min": round(s.battery_min, 4),
            "battery_critical": self.battery.critical,
            "battery_below_critical_s": round(s.below_critical_s, 1),
            "docked_h": round(s.docked_s / 3600.0, 3),
        }
