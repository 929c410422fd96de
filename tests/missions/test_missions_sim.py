"""The named missions end to end on the simulated robot (rendering, perception, the real
skills), one seeded scenario each; and record-then-replay reaching the same outcome."""
from __future__ import annotations

import re

import pytest

from hearth.executive.scenarios import Case, run_case


def test_fetch_finds_the_moved_cup_grasps_it_and_says_where_it_was():
    r = run_case(Case("fetch_object", seed=0, warmup=0, target="blue_cup"))
    assert r.outcome == "succeeded", r.reason
    assert re.match(r"the blue cup was (on|in) the \w", r.said[-1]), r.said[-1]
    moved = [c for c in r.map_changes if c.startswith("blue_cup parent")]
    assert moved or r.positions_visited == 1
    if moved:   # the sentence names the place the map now has it at
        from hearth.worldmodel import load_world
        from hearth import demo_world_path
        new_parent = moved[0].rsplit("-> ", 1)[1]   # where it was found (the last: handed over)
        assert load_world(demo_world_path()).label(new_parent) in r.said[-1]


def test_fetch_of_an_absent_cup_ends_not_found_with_the_places_counted():
    # Two known places and no segmentation fallback keep it short; the bench runs it all.
    r = run_case(Case("fetch_object", seed=3, achievable=False, warmup=0, target="blue_cup",
                      params={"max_places": 2, "propose_new": False}))
    assert r.outcome == "failed"
    assert r.category == "not_found", r.reason
    assert r.reason == "no blue cup at the 2 places searched"


def test_turn_off_oven_turns_off_the_knobs_that_are_on():
    r = run_case(Case("turn_off_oven", seed=0))
    assert r.outcome == "succeeded", r.reason
    assert "it is off now" in r.said[-1]


def test_a_stuck_oven_knob_ends_with_cannot():
    r = run_case(Case("turn_off_oven", seed=3, achievable=False))
    assert r.outcome == "failed"
    assert r.reason.startswith("I cannot turn off oven knob"), r.reason


def test_refine_localisation_removes_the_drift():
    r = run_case(Case("refine_localisation", seed=1))
    assert r.outcome == "succeeded", r.reason
    assert r.residual_cm < 2.0


@pytest.mark.parametrize("case", [Case("fetch_object", seed=0, warmup=0, target="blue_cup"),
                                  Case("turn_off_oven", seed=0),
                                  Case("refine_localisation", seed=1)],
                         ids=lambda c: c.mission)
def test_a_recorded_run_replays_to_the_same_outcome(case, tmp_path):
    recorded = run_case(case, record_to=str(tmp_path / "rec"))
    replayed = run_case(case, replay_from=str(tmp_path / "rec"))
    assert recorded.outcome == "succeeded", recorded.reason
    assert (replayed.outcome, replayed.reason) == (recorded.outcome, recorded.reason), replayed.reason
    assert replayed.said == recorded.said
