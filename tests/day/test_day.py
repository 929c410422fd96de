"""A robot's day (docs/day.md): battery watch, emergencies over recharge, reminders on time,
missed slots. Simulated clock, demo home; each test a few seconds."""
from __future__ import annotations

import pytest
from hypothesis import given, settings, strategies as st

from hearth.executive.day import (BatteryPolicy, Entry, Schedule, ScheduleError, load_schedule)
from hearth.executive.daysim import Happening, simulate_day
from hearth.worldmodel.io import load_world
from hearth import demo_world_path



@pytest.fixture
def world():
    return load_world(str(demo_world_path()))


def kinds(events, kind):
    return [e for e in events if e["kind"] == kind]


def test_a_fetch_interrupted_by_low_battery_recharges_and_completes(world):
    events = []
    schedule = Schedule((), BatteryPolicy(low=0.30, critical=0.15, charge_to=0.95), start=8 * 3600)
    # a noise-free camera: this is about the day, not perception (and keeps the test short)
    report, day, robot = simulate_day(
        world, schedule, hours=3.0, battery_level=0.3004, user_room="kitchen",
        happenings=[Happening(8 * 3600, "request", "fetch_object", {"object": "pill box"})],
        on_event=events.append, robot_kwargs={"noise": None})
    interrupted = kinds(events, "interrupted")
    assert [e["mission"] for e in interrupted] == ["fetch_object"]
    assert interrupted[0]["robot_stopped"] and interrupted[0]["map_consistent"]
    assert "preempted by recharge" in interrupted[0]["reason"]
    ended = [(e["mission"], e["outcome"]) for e in kinds(events, "ended")]
    assert ended == [("recharge", "succeeded"), ("fetch_object", "succeeded")]
    assert [e["mission"] for e in kinds(events, "restarted")] == ["fetch_object"]
    assert report["interrupted_completed"] == 1 and report["battery_below_critical_s"] == 0
    assert report["battery_min"] > 0.15 and report["docked_h"] > 0.5
    assert robot.handed_over == ["pill_box"]


def test_an_emergency_during_recharge_takes_over_above_the_critical_level(world):
    events = []
    schedule = Schedule((), BatteryPolicy(low=0.30, critical=0.15), start=8 * 3600)
    # Low (not critical) at 08:00: the watch sends it to charge; the call comes while docked.
    report, day, robot = simulate_day(
        world, schedule, hours=3.0, battery_level=0.25, user_room="bathroom",
        happenings=[Happening(8 * 3600 + 600, "emergency", room="bathroom")],
        on_event=events.append)
    emergency = kinds(events, "emergency")[0]
    assert emergency["waits_for_charge"] is False
    interrupted = kinds(events, "interrupted")
    assert [e["mission"] for e in interrupted] == ["recharge"]
    assert interrupted[0]["reason"].startswith("preempted by go_to_user")
    ended = [(e["mission"], e["outcome"]) for e in kinds(events, "ended")]
    assert ended == [("go_to_user", "succeeded"), ("recharge", "succeeded")]
    assert report["emergency_response_s_median"] <= 2.0
    assert "I am here in the bathroom. Do you need help?" in robot.said


def test_below_the_critical_level_an_emergency_waits_for_the_charge(world):
    events = []
    schedule = Schedule((), BatteryPolicy(low=0.30, critical=0.15), start=8 * 3600)
    simulate_day(world, schedule, hours=1.0, battery_level=0.10, user_room="bathroom",
                 happenings=[Happening(8 * 3600 + 120, "emergency", room="bathroom")],
                 on_event=events.append)
    assert kinds(events, "emergency")[0]["waits_for_charge"] is True
    # held until the charge passes the critical level (docked within seconds of 08:00;
    # 0.10 -> 0.15 takes 6 min at 100 W), then it takes over the recharge
    sent = next(e for e in kinds(events, "submitted") if e["mission"] == "go_to_user")
    interrupted = kinds(events, "interrupted")
    assert [e["mission"] for e in interrupted] == ["recharge"]
    assert 330 <= sent["t"] <= 400
    ended = [(e["mission"], e["outcome"]) for e in kinds(events, "ended")]
    assert ended[0] == ("go_to_user", "succeeded")


def test_a_reminder_fires_once_at_its_time(world):
    events = []
    text = "time for your pills"
    schedule = Schedule((Entry("pills", "deliver_reminder", {"text": text}, 20, at=9 * 3600),),
                        start=8 * 3600)
    report, day, robot = simulate_day(world, schedule, hours=3.0, user_room="bathroom",
                                      on_event=events.append)
    slots = kinds(events, "slot")
    assert [(e["entry"], e["slot"], e["time"]) for e in slots] == [("pills", "09:00:00", "09:00:00")]
    assert robot.said.count(f"Reminder: {text}") == 1
    assert report["slots_missed"] == 0


def test_a_missed_slot_is_reported_not_run_twice(world):
    events = []
    # every 10 min from 08:00; the user is out 08:05-08:35: the three slots in between are
    # missed (reported), none runs later, and the patrol goes on at 08:40.
    entry = Entry("patrol", "emergency_patrol", {}, 0, every=600, start=8 * 3600,
                  end=9 * 3600, grace=0.0)
    schedule = Schedule((entry,), start=8 * 3600)
    simulate_day(world, schedule, hours=0.75, user_room="kitchen",
                 happenings=[Happening(8 * 3600 + 300, "away"),
                             Happening(8 * 3600 + 2100, "home", room="kitchen")],
                 on_event=events.append)
    missed = [e["slot"] for e in kinds(events, "slot_missed")]
    run = [e["slot"] for e in kinds(events, "slot")]
    assert missed == ["08:10:00", "08:20:00", "08:30:00"]
    assert run == ["08:00:00", "08:40:00"]
    assert len(set(run + missed)) == len(run + missed)


def test_a_bad_schedule_is_one_line_with_file_and_line(tmp_path):
    path = tmp_path / "day.yaml"
    path.write_text("hearth: 1\nday:\n  entries:\n    - {mission: deliver_reminder, at: '25:00'}\n")
    with pytest.raises(ScheduleError) as err:
        load_schedule(path, {"deliver_reminder"})
    assert str(err.value) == f"{path}:4: '25:00' is not a time of day (HH:MM)"


def test_a_second_call_joins_the_robot_already_going_to_the_user(world):
    events = []
    schedule = Schedule((), start=8 * 3600)
    report, day, robot = simulate_day(
        world, schedule, hours=0.2, user_room="bathroom", on_event=events.append,
        happenings=[Happening(8 * 3600 + 60, "emergency", room="bathroom"),
                    Happening(8 * 3600 + 63, "emergency", room="bathroom")])
    calls = kinds(events, "emergency")
    runs = [e["run"] for e in kinds(events, "submitted") if e["mission"] == "go_to_user"]
    assert len(calls) == 2 and len(runs) == 1 and calls[1]["joins"] == runs[0]
    assert report["emergencies_joined"] == 1
    assert robot.said.count("I am coming.") == 1


def test_hearth_day_prints_the_days_figures(capsys):
    from hearth.cli.main import main
    from hearth import resource_dir
    schedule = resource_dir("data") / "demo_home" / "day.yaml"
    assert main(["day", "--schedule", str(schedule), "--hours", "2", "--battery", "0.31",
                 "--emergency", "08:30 bathroom"]) == 0
    out = capsys.readouterr().out
    assert "battery_low" in out and "08:00:00  slot" in out
    import re
    response = re.search(r"emergencies 1 \(response median ([0-9.]+) s\)", out)
    assert response and float(response.group(1)) <= 2.0
    assert "interrupted 1 (1 times): 0 resumed, 1 restarted; 1 completed" in out
    assert "below the critical 15%: never" in out


def test_hearth_day_refuses_a_world_without_a_charger_in_one_line(tmp_path, capsys):
    import re
    from hearth.cli.main import main
    text = demo_world_path().read_text()
    path = tmp_path / "world.xml"
    path.write_text(re.sub(r"<charger .*?</charger>\s*", "", text, flags=re.S))
    schedule = tmp_path / "day.yaml"
    schedule.write_text("hearth: 1\nday: {entries: []}\n")
    assert main(["day", "--world", str(path), "--schedule", str(schedule)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{path}:2: the map has no charger: a day needs one (a <charger> in a room, "
                   "docs/world-format.md)"]


def test_hearth_validate_checks_a_schedule(tmp_path, capsys):
    from hearth.cli.main import main
    from hearth import resource_dir
    assert main(["validate", str(resource_dir("data") / "demo_home" / "day.yaml")]) == 0
    path = tmp_path / "day.yaml"
    path.write_text("hearth: 1\nday:\n  entries:\n    - {mission: deliver_reminder, at: '08:00'}\n")
    assert main(["validate", str(path)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"{path}:4: deliver_reminder: parameter text: required by mission deliver_reminder "
        "but not given")


@settings(max_examples=200, deadline=None)
@given(every=st.integers(1, 1440), start=st.integers(0, 86_399), span=st.integers(1, 86_400),
       t0=st.floats(0, 3 * 86_400), a=st.floats(0, 86_400), b=st.floats(0, 86_400))
def test_schedule_slots_split_at_any_time_are_the_same_slots(every, start, span, t0, a, b):
    end = min(start + span, 86_400)
    entry = Entry("e", "m", {}, 0, every=every * 60.0, start=float(start), end=float(end))
    t1, t2 = t0 + a, t0 + a + b
    whole = entry.slots(t0, t2)
    assert entry.slots(t0, t1) + entry.slots(t1, t2) == whole      # never twice, none lost
    assert all(t0 < s <= t2 for s in whole)
    assert all(start <= s % 86_400 <= end or s % 86_400 == 0 and end == 86_400 for s in whole)


@given(st.integers(0, 86_399))
def test_a_time_of_day_reads_back_as_written(seconds):
    from hearth.executive.day import clock_text, parse_clock_time
    assert parse_clock_time(clock_text(seconds)) == seconds
