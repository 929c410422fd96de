"""An "off" reading that passes every check but the off factor, from two places apart, makes
the knob off (hearth.perception.knobs.OffViews, ReadKnobs); from one place, or from one place twice,
it stays unknown, and a knob that is on is never made off so."""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import py_trees
import pytest

from hearth.perception.knobs import OffViews
from hearth.skills.knobs import ReadKnobs, TurnKnob
from tests.knobs.test_knobs_skills import OvenRobot, make

S = py_trees.common.Status
pytestmark = pytest.mark.usefixtures("clean_blackboard")
KNOB = "oven_knob_2"


def _reader_between(reader, margins):
    """``reader`` with its state gate set so that every margin in ``margins`` passes it but
    not 1.5 times it (the off factor)."""
    lo, hi = max(margins) / reader.config.off_margin_factor, min(margins)
    assert lo < hi, margins
    r = copy.copy(reader)
    r.config = replace(reader.config, margin_threshold=(lo + hi) / 2)
    return r


def _skill(world, robot, reader, memory):
    s = make(ReadKnobs, world, robot, reader, {"object": "oven", "knobs": [KNOB]},
             {"states": "/states", "unknown": "/unknown"})
    s.context["run_memory"] = memory
    return s


def test_off_read_from_two_places_apart_is_off_and_from_one_place_stays_unknown(demo_world, reader):
    world = demo_world
    assert world.get(KNOB).state == world.get(KNOB).off
    robot = OvenRobot(world, {}, depth=True)
    here = robot.T_wc.copy()
    there = here.copy()
    there[:3, 3] += 0.3 * here[:3, 0]                 # 30 cm to the camera's right
    margins = []
    from hearth.perception.knobs import knob_priors
    for T in (here, there):
        robot.T_wc = T
        f = robot.capture()
        r = [r for r in reader.read(f.color, f.intrinsics, T, knob_priors(world, "oven"), depth=f.depth)
             if r.knob_id == KNOB][0]
        assert r.state == "off", r.reason
        margins.append(r.evidence["margin"])
    strict = _reader_between(reader, margins)

    # from one place, twice: unknown both times, "from this view alone"
    memory: dict = {}
    robot.T_wc = here
    for _ in range(2):
        s = _skill(world, robot, strict, memory)
        s.tick_once()
        assert s.status == S.FAILURE
        assert "from this view alone" in s.feedback_message, s.feedback_message
    # then from 30 cm away: off, and said so
    robot.T_wc = there
    s = _skill(world, robot, strict, memory)
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    assert f"{KNOB} off" in s.feedback_message and "read off from two places" in s.feedback_message

    # a turn in between, of this knob or of another of the oven (it can nudge a neighbour),
    # forgets the first place
    for turned in (KNOB, "oven_knob_1"):
        memory = {}
        robot.T_wc = here
        _skill(world, robot, strict, memory).tick_once()
        turn = make(TurnKnob, world, robot, strict, {"knob": turned, "state": "off"})
        turn.context["run_memory"] = memory
        turn.tick_once()
        turn.tick_once()
        assert turn.status == S.SUCCESS
        robot.T_wc = there
        s = _skill(world, robot, strict, memory)
        s.tick_once()
        assert s.status == S.FAILURE and "from this view alone" in s.feedback_message, turned


def test_a_reading_leaning_to_another_state_forgets_the_off_seen_before(demo_world, reader):
    from hearth.perception.knobs import KnobReading
    views = OffViews(apart_m=0.25)
    off_alone = KnobReading("k", True, evidence=dict(leaning="off", off_one_view=True))
    leaning_on = KnobReading("k", True, evidence=dict(leaning="3"))
    not_found = KnobReading("k", False)
    assert not views.add(off_alone, "off", np.zeros(3))
    assert not views.add(not_found, "off", np.array([0.5, 0, 0]))      # no evidence either way
    assert views.add(off_alone, "off", np.array([0.3, 0, 0]))          # 30 cm apart: off
    assert not views.add(off_alone, "off", np.zeros(3))
    assert not views.add(leaning_on, "off", np.array([0.1, 0, 0]))     # leans to 3: forgotten
    assert not views.add(off_alone, "off", np.array([0.3, 0, 0]))
    assert not views.add(off_alone, "off", np.array([0.4, 0, 0]))      # 10 cm from the last
