"""`hearth day`: run a simulated day of a schedule and report (docs/day.md).

Run a robot's day on the simulated clock: the schedule's missions at their times, the
battery watch sending the robot to its charger, emergencies first, interrupted missions
resumed or restarted, and what you add with --request, --emergency, --away and --user-moves.
Prints one line per event that matters (slots run or missed, interruptions, emergencies, the
battery), then the day's figures: missions run, interrupted, resumed, completed; the lowest
battery level against the critical one; hours docked. A 24 h day takes seconds to a minute
or two of wall time (the clock jumps when nothing runs and while the robot charges).
"""
from __future__ import annotations

import argparse
import json
import sys

from hearth.cli.util import DEFAULT_WORLD, add_command

#: Day events printed without --verbose.
SHOWN = {"slot", "slot_missed", "interrupted", "resumed", "restarted", "emergency",
         "emergency_response", "battery_low", "battery_critical", "away", "home", "ended"}


def _at(text: str) -> float:
    from hearth.executive.day import parse_clock_time
    try:
        return parse_clock_time(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _timed(text: str) -> tuple[float, list[str]]:
    """"HH:MM WORDS..." -> (day seconds, words)."""
    head, _, rest = text.strip().partition(" ")
    return _at(head), rest.split()


def _request(text: str):
    from hearth.executive.daysim import Happening
    t, words = _timed(text)
    if not words:
        raise argparse.ArgumentTypeError(f"{text!r}: HH:MM MISSION [NAME=VALUE ...]")
    params = {}
    for w in words[1:]:
        k, eq, v = w.partition("=")
        if not eq or not k:
            raise argparse.ArgumentTypeError(f"{text!r}: parameters are NAME=VALUE, not {w!r}")
        params[k] = v.replace("_", " ") if k == "object" else v
    return Happening(t, "request", words[0], params)


def _emergency(text: str):
    from hearth.executive.daysim import Happening
    t, words = _timed(text)
    return Happening(t, "emergency", room=words[0] if words else "")


def _moves(text: str):
    from hearth.executive.daysim import Happening
    t, words = _timed(text)
    if len(words) != 1:
        raise argparse.ArgumentTypeError(f"{text!r}: HH:MM ROOM")
    return Happening(t, "user_moves", room=words[0])


def _away(text: str):
    from hearth.executive.daysim import Happening
    a, sep, b = text.partition("-")
    if not sep:
        raise argparse.ArgumentTypeError(f"{text!r}: HH:MM-HH:MM")
    return (Happening(_at(a), "away"), Happening(_at(b), "home"))


def _level(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not 0.0 < v <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: a battery level 0..1")
    return v


def _hours(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not 0.0 < v <= 24 * 14:
        raise argparse.ArgumentTypeError(f"{text!r}: hours, more than 0 and at most 336")
    return v


def register(sub) -> None:
    p = add_command(sub, "day", __doc__, help="run a simulated day of a schedule and report")
    p.add_argument("--world", default=str(DEFAULT_WORLD),
                   help="world file (default: the demo home); it needs a charger")
    p.add_argument("--schedule", required=True, metavar="DAY.yaml",
                   help="the day's schedule (e.g. data/demo_home/day.yaml)")
    p.add_argument("--hours", type=_hours, default=24.0, help="simulated hours (default 24)")
    p.add_argument("--battery", type=_level, default=1.0,
                   help="battery level at the start, 0..1 (default 1)")
    p.add_argument("--user-room", default=None, metavar="ROOM",
                   help="room id the user starts in (default: the first room)")
    p.add_argument("--request", type=_request, action="append", default=[],
                   metavar="'HH:MM MISSION [K=V ...]'",
                   help="a user's request, e.g. '10:30 fetch_object object=reading_glasses' "
                        "(repeatable; '_' stands for a space in object=)")
    p.add_argument("--emergency", type=_emergency, action="append", default=[],
                   metavar="'HH:MM [ROOM]'",
                   help="the user calls for help (from ROOM when known; repeatable)")
    p.add_argument("--away", type=_away, action="append", default=[], metavar="HH:MM-HH:MM",
                   help="the user is out: the schedule pauses (repeatable)")
    p.add_argument("--user-moves", type=_moves, action="append", default=[],
                   metavar="'HH:MM ROOM'", help="the user goes to another room (repeatable)")
    p.add_argument("--runs-dir", default=None,
                   help="write each mission's execution log here (default: none)")
    p.add_argument("--day-log", default=None, metavar="FILE",
                   help="write the day's events here (JSON lines)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON only")
    p.add_argument("--verbose", action="store_true", help="print every day event")
    p.set_defaults(func=_run)


def _shown(e: dict) -> bool:
    if e["kind"] == "submitted":        # the schedule's are shown as slots
        return not str(e.get("source", "")).startswith("schedule")
    return e["kind"] in SHOWN


def _line(e: dict) -> str:
    kind = e["kind"]
    skip = {"e", "kind", "t", "time", "params"}
    if e.get("first") == e.get("run"):
        skip.add("first")
    rest = " ".join(f"{k}={v}" for k, v in e.items() if k not in skip and v not in ("", None))
    return f"{e['time']}  {kind:<18} {rest}"


def _check_requests(requests, world) -> None:
    """Every --request names a shipped mission with parameters it takes in this map
    (MissionError, one line, before the day starts)."""
    from hearth.executive.day import mission_paths
    from hearth.executive.errors import MissionError
    from hearth.executive.missionfile import load_mission, skill_registry
    paths = mission_paths()
    skills = None
    for h in requests:
        if h.mission not in paths:
            raise MissionError(f"--request: no mission named {h.mission!r} (known: "
                               f"{', '.join(sorted(paths))})")
        skills = skills or skill_registry()
        m = load_mission(paths[h.mission], skills)
        try:
            m.resolve_parameters(m.resolve_in_map(dict(h.params), world))
        except MissionError as err:
            raise MissionError(f"--request {h.mission}: {err}") from None


def _run(args) -> int:
    from hearth.executive.day import load_schedule
    from hearth.executive.day import mission_paths
    from hearth.executive.daysim import simulate_day
    from hearth.worldmodel.errors import WorldError
    from hearth.worldmodel.io import load_world

    world = load_world(args.world)
    if not world.chargers():
        raise WorldError("the map has no charger: a day needs one (a <charger> in a room, "
                         "docs/world-format.md)", file=args.world,
                         line=world.apartment.line or 1)
    if args.user_room is not None and args.user_room not in [r.id for r in world.rooms]:
        print(f"hearth day: --user-room {args.user_room}: not a room of {args.world} "
              f"(rooms: {', '.join(r.id for r in world.rooms)})", file=sys.stderr)
        return 2
    schedule = load_schedule(args.schedule, set(mission_paths()))
    _check_requests(args.request, world)
    rooms = {r.id for r in world.rooms}
    for h in list(args.emergency) + list(args.user_moves):
        if h.room and h.room not in rooms:
            print(f"hearth day: {h.room}: not a room of {args.world} (rooms: "
                  f"{', '.join(sorted(rooms))})", file=sys.stderr)
            return 2
    happenings = list(args.request) + list(args.emergency) + list(args.user_moves)
    for pair in args.away:
        happenings += list(pair)

    def show(e: dict) -> None:
        if not args.json and (args.verbose or _shown(e)):
            print(_line(e), flush=True)

    report, day, robot = simulate_day(world, schedule, args.hours, happenings,
                                      user_room=args.user_room, battery_level=args.battery,
                                      runs_dir=args.runs_dir, day_log=args.day_log,
                                      on_event=show)
    if args.json:
        print(json.dumps(report, sort_keys=True))
        return 0
    r = report
    ok = "never" if r["battery_below_critical_s"] == 0 else \
        f"{r['battery_below_critical_s']:.0f} s"
    print(f"missions run {r['missions_run']}: {r['succeeded']} completed, {r['failed']} failed, "
          f"{r['cancelled']} cancelled, {r['still_open']} still running at the end")
    print(f"interrupted {r['interrupted_missions']} ({r['interruptions']} times): "
          f"{r['resumed']} resumed, {r['restarted']} restarted; {r['interrupted_completed']} "
          f"completed, {r['interrupted_reported']} reported, {r['interrupted_open']} open")
    print(f"slots run {r['slots_run']}, missed {r['slots_missed']}; recharges {r['recharges']}; "
          f"emergencies {r['emergencies']} (response median "
          f"{r['emergency_response_s_median']} s)")
    print(f"battery lowest {r['battery_min']:.0%}, below the critical {r['battery_critical']:.0%}: "
          f"{ok}; docked {r['docked_h']:.2f} h")
    return 0
