"""A robot's day (docs/day.md): simulated 24 h days with random reminders, requests,
emergencies, outings and the user moving between rooms, on each home.

Per home one day (seeded by ``--seed`` and the home): the user moves every 40-120 min; a
patrol every 2 h 09:00-21:00; 4 reminders (``deliver_reminder``, never during an outing),
two at random times 08:00-21:30 and two 10-60 s after a patrol starts (the patrol is
interrupted and resumes); 4 user requests (a fetch of a graspable object, or a patrol); 4
emergencies, two at random times and two 2-15 s after a request or a patrol started (half
with the call's room, the user's, half without); one outing of 1-3 h; the battery starts at
35-70 %.

Figures (medians over emergencies of every home; counts summed): ``battery_below_critical``
(days during which the level fell below the critical one, target 0),
``emergency_response_s_median`` (the call -> the robot driving towards the user, simulated
seconds, target <= 2), ``interrupted_missions`` with ``interrupted_completed``,
``interrupted_reported`` (ended failed or cancelled, with a reason) and ``interrupted_open``
(target 0), ``interrupted_by`` (interruptions by the mission that preempted),
``emergencies_preempting`` (calls that came while a mission ran) and
``emergency_response_preempting_s_median`` (the response to those alone),
``emergencies_joined`` (calls while the robot was already going to the user),
``missed_reminders`` (not delivered: slot missed or the run failed, target 0),
``map_inconsistent_after_preemption`` (the belief map failing validation right after a
preemption, target 0), ``robot_not_stopped_after_preemption``, ``docked_h`` and the wall
time per simulated day.
"""
from __future__ import annotations

import statistics
import sys
import time
import zlib


def add_arguments(parser) -> None:
    from hearth.benchmarks._worlds import add_arguments as worlds
    worlds(parser, homes=2)
    parser.add_argument("--hours", type=float, default=24.0, help="simulated hours a day")
    parser.add_argument("--verbose", action="store_true", help="a line per home on stderr")


def day_plan(world, rng, hours: float = 24.0):
    """(schedule, happenings, user's first room, battery level) of one random day."""
    from hearth.executive.day import REMINDER, BatteryPolicy, Entry, Schedule
    from hearth.executive.daysim import Happening
    start = 7 * 3600.0
    end = start + hours * 3600.0
    rooms = [r.id for r in world.rooms]
    hap = []
    t = start
    while t < end:
        t += rng.uniform(40, 120) * 60
        hap.append(Happening(t, "user_moves", room=str(rng.choice(rooms))))
    patrols = [h * 3600.0 for h in range(9, 22, 2)]
    # two reminders at random times, two 10-60 s after a patrol starts (it is interrupted and
    # resumes afterwards)
    reminder_times = sorted([float(x) for x in rng.uniform(8 * 3600, 21.5 * 3600, 2)]
                            + [float(rng.choice(patrols) + rng.uniform(10, 60))
                               for _ in range(2)])
    # one outing that keeps 20 min clear of every reminder
    out_at = out_back = None
    for _ in range(50):
        a = float(rng.uniform(9 * 3600, 19 * 3600))
        b = a + float(rng.uniform(1, 3)) * 3600
        if all(not (a - 1200 <= r <= b + 1200) for r in reminder_times):
            out_at, out_back = a, b
            break
    if out_at is not None:
        hap += [Happening(out_at, "away"), Happening(out_back, "home", room=str(rng.choice(rooms)))]
    graspable = [o.id for o in world.small_objects() if o.graspable]
    for _ in range(4):
        at = float(rng.uniform(8 * 3600, 21 * 3600))
        if out_at is not None and out_at - 600 <= at <= out_back:
            continue
        if graspable and rng.random() < 0.5:
            hap.append(Happening(at, "request", "fetch_object",
                                 {"object": str(rng.choice(graspable))}))
        else:
            hap.append(Happening(at, "request", "emergency_patrol"))
    busy = [h.t for h in hap if h.kind == "request"] + patrols
    for k in range(4):
        # two calls at random times, two 2-15 s after a request or a patrol started (while
        # the robot is busy: the call halts what runs)
        at = (float(rng.uniform(start + 600, end - 1800)) if k < 2
              else float(rng.choice(busy) + rng.uniform(2, 15)))
        if out_at is not None and out_at - 600 <= at <= out_back:
            continue
        hap.append(Happening(at, "emergency", room="" if rng.random() < 0.5 else "@user"))
    entries = [Entry(f"reminder{i + 1}", "deliver_reminder",
                     {"text": f"reminder number {i + 1}"}, REMINDER, at=r % 86400)
               for i, r in enumerate(reminder_times)]
    entries.append(Entry("patrol", "emergency_patrol", {}, 0, every=2 * 3600.0,  # = patrols
                         start=9 * 3600.0, end=21 * 3600.0))
    schedule = Schedule(tuple(entries), BatteryPolicy(low=0.30, critical=0.15, charge_to=0.95),
                        start=start)
    return schedule, _user_rooms(sorted(hap, key=lambda h: h.t), rooms[0]), rooms[0], \
        float(rng.uniform(0.35, 0.70))


def _user_rooms(hap, first):
    """An emergency's call comes from the user's room ("@user"): fill it in."""
    from hearth.executive.daysim import Happening
    room, out = first, []
    for h in hap:
        if h.kind in ("user_moves", "home") and h.room:
            room = h.room
        if h.kind == "emergency" and h.room == "@user":
            h = Happening(h.t, "emergency", room=room)
        out.append(h)
    return out


def run(args) -> dict:
    import numpy as np
    from hearth.executive.daysim import simulate_day
    from hearth.benchmarks._worlds import load, world_specs
    from hearth.worldmodel.chargers import place_charger

    specs = world_specs(args, homes=2)
    per_world, responses, preempting, walls = {}, [], [], []
    totals: dict = {}
    interrupted_by: dict = {}
    added = []
    for i, spec in enumerate(specs):
        world = load(spec)
        if place_charger(world) is not None:
            added.append(spec)       # a home cached before chargers were in the map
        # seeded by the home, not its place in the list (--no-demo gives the same days)
        rng = np.random.default_rng([int(args.seed), zlib.crc32(spec.encode())])
        schedule, hap, first, level = day_plan(world, rng, args.hours)
        events: list = []
        t0 = time.perf_counter()
        report, day, robot = simulate_day(world, schedule, args.hours, hap, user_room=first,
                                          battery_level=level, on_event=events.append,
                                          finish_s=3600.0)
        wall = time.perf_counter() - t0
        walls.append(wall)
        responses += day.stats.emergency_response_s
        preempting += day.stats.emergency_response_preempting_s
        reminders = [c for c in day.chains() if c.mission == "deliver_reminder"]
        missed = (sum(1 for m in day.missed if m["mission"] == "deliver_reminder")
                  + sum(c.outcome != "succeeded" for c in reminders))
        fig = {k: report[k] for k in (
            "missions_run", "succeeded", "failed", "cancelled", "still_open", "interruptions",
            "interrupted_missions", "interrupted_completed", "interrupted_reported",
            "interrupted_open", "resumed", "restarted", "recharges", "emergencies",
            "emergencies_preempting", "emergencies_joined",
            "slots_run", "slots_missed", "map_inconsistent_after_preemption",
            "robot_not_stopped_after_preemption", "docked_h")}
        fig.update(missed_reminders=missed, reminders=len(reminders),
                   battery_min=report["battery_min"],
                   battery_below_critical=int(report["battery_below_critical_s"] > 0),
                   emergency_response_s_median=report["emergency_response_s_median"],
                   start_battery=round(level, 3), wall_s=round(wall, 1))
        fig["interrupted_by"] = report["interrupted_by"]
        for k, v in report["interrupted_by"].items():
            interrupted_by[k] = interrupted_by.get(k, 0) + v
        per_world[spec] = fig
        for k, v in fig.items():
            if isinstance(v, (int, float)) and not isinstance(v, bool) and k not in (
                    "battery_min", "emergency_response_s_median", "start_battery", "wall_s"):
                totals[k] = round(totals.get(k, 0) + v, 3)
        if getattr(args, "verbose", False):
            print(f"day {spec}: {fig}", file=sys.stderr, flush=True)
    out = dict(totals)
    out.update(
        days=len(specs), hours=args.hours, seed=args.seed, worlds=specs,
        interrupted_by=dict(sorted(interrupted_by.items())),
        emergency_response_s_median=(round(statistics.median(responses), 3) if responses
                                     else None),
        emergency_response_s_max=round(max(responses), 3) if responses else None,
        emergency_response_preempting_s_median=(round(statistics.median(preempting), 3)
                                                if preempting else None),
        emergency_responses_preempting=len(preempting),
        battery_min=min(f["battery_min"] for f in per_world.values()),
        wall_s_per_day_median=round(statistics.median(walls), 1),
        chargers_added=added, per_world=per_world)
    return out
