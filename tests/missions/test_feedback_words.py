"""What the named missions say in their feedback is words: no Python repr of a dict, a list,
an array or a Pose in any node's sentence; the values travel beside it, as JSON values in the
execution log (hearth.skills.base.Feedback)."""
from __future__ import annotations

import json
import re

import pytest

from missions_helpers import MISSIONS, mission_skills
from test_missions_logic import ROBOT_SCRIPTS, FakeRobot, on_top_of
from hearth.executive.executive import Executive
from hearth.executive.testing import Script, Substitution
from hearth.robot.clock import SimClock
from hearth.worldmodel import load_world

#: Python's repr of a dict, a list or tuple of values, a numpy value or a Pose.
PY_REPR = re.compile(r"""\{\s*['"][^'"]*['"]\s*:|\{\}|\[\]|[\[(]\s*['"{\[(]|\[-?\d[\d.e+-]*,\s"""
                     r"""|array\(|np\.\w+\(|Pose\(x=""")


def test_the_repr_pattern_catches_what_skills_used_to_write():
    for bad in ("item 0: {'place': 'kitchen_table', 'x': 1.8}", "looking at [3.0, 2.2, 0.87]",
                "not a place in the map: {}", "{x} == 1: ['a', 'b'] == 1 is False",
                "at Pose(x=1.0, y=2.0, z=0.0)", "fitness np.float64(0.86)"):
        assert PY_REPR.search(bad), bad
    for fine in ("{closed_count} == 0: 2 == 0 is False", "success is failure [not found at hall]",
                 "looking at (3.00, 2.20, 0.87) m", "item 1: kitchen_table from kitchen_table_west (p 0.6)"):
        assert not PY_REPR.search(fine), fine


def _run(world, mission, scripts, tmp_path, robot=None, **params):
    ex = Executive(world=world, robot=robot or FakeRobot(), clock=SimClock(), tick_hz=10,
                   runs_dir=str(tmp_path), skills=mission_skills(),
                   make_skill=Substitution(scripts, default=None), background=False)
    handle = ex.submit(str(MISSIONS / mission), **params)
    ex.run_until_idle(20_000)
    lines = [json.loads(line) for line in open(handle.result.log_path, encoding="utf-8")]
    return handle.result, [e for e in lines if e["e"] == "feedback"]


@pytest.fixture
def world(demo_world_path):
    return load_world(demo_world_path)


def test_the_fetch_missions_feedback_is_words_with_the_search_places_as_values(world, tmp_path):
    # found at the first place (one item of the for_each is enough, and quick)
    seen = on_top_of(world, "kitchen_table")
    result, feedback = _run(world, "fetch_object.yaml", ROBOT_SCRIPTS + [
        Script("DetectObject", outputs={"pose": seen})], tmp_path, object="blue cup")
    assert result.outcome == "succeeded", result.reason
    said = [(e["path"], e["message"]) for e in feedback if PY_REPR.search(e["message"])]
    assert said == []
    # The for_each over the search places: "item 1: kitchen_table from ..." with the place
    # itself, a dict, as a value.
    items = [e for e in feedback if e["path"].endswith("/search_known_places/for_each")]
    assert items and items[0]["message"].startswith("item 1: ")
    assert isinstance(items[0]["values"]["item"], dict) and "place" in items[0]["values"]["item"]
    looks = [e for e in feedback if e["message"].startswith("looking at (")]
    assert looks and all(len(e["values"]["point"]) == 3 for e in looks)


@pytest.mark.parametrize("mission", ["turn_off_oven.yaml", "refine_localisation.yaml"])
def test_the_oven_and_localisation_missions_feedback_is_words(world, tmp_path, mission):
    robot = FakeRobot(knobs={"oven_knob_1": 1.5})
    result, feedback = _run(world, mission, ROBOT_SCRIPTS + [
        Script("TurnKnob"), Script("RegisterLargeObject")], tmp_path, robot=robot)
    assert feedback
    said = [(e["path"], e["message"]) for e in feedback if PY_REPR.search(e["message"])]
    assert said == [], result.reason


def test_say_words_lists_and_places_it_is_given(world):
    from hearth.skills.base import Bindings, Literal
    from hearth.skills.speech import Say
    given = dict(text="{detail}; near {place}; tried {tries}",
                 detail=[{"knob": 2, "state": "off"}, "stuck"],
                 place={"x": 1.0, "y": 2.0}, values={"tries": [1, 2]})
    say = Say("say", Bindings(inputs={k: Literal(v) for k, v in given.items()}))
    say.setup(world=world)
    text = say.sentence()
    assert not PY_REPR.search(text), text
    assert "stuck" in text and "1, 2" in text and "1.0, 2.0" in text
