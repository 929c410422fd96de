"""Structured feedback: a skill reports a sentence and its values (Skill.report); the events
and the execution log carry the values as JSON values, the sentence stays plain text, and a
skill that sets a plain string still works."""
from __future__ import annotations

import json
import pickle

import numpy as np
from py_trees import common

from hearth.executive.events import EventKind
from hearth.executive.replay import format_event
from hearth.executive.testing import test_skills
from hearth.skills.base import Feedback, Port, Skill, values_of, words
from hearth.skills.errors import SkillError
from hearth.worldmodel.pose import Pose


class Weigh(Skill):
    """Reports a sentence with values of the kinds skills have at hand (numpy, a Pose)."""
    NAME = "Weigh"

    def update(self):
        self.report("fix on fridge not trusted: too weak (fitness 0.86)",
                    fitness=np.float64(0.8612), rmse_mm=4.1, points=np.int64(812),
                    landmarks=("fridge", "oven"), pose=Pose(1.5, 2.0, 0.0, 0.0, 0.0, 0.5),
                    spread=np.array([0.1, 0.2]), gap=float("nan"))
        return common.Status.SUCCESS


class OldStyle(Skill):
    """A third-party skill of before: a plain string, nothing else."""
    NAME = "OldStyle"

    def update(self):
        self.feedback_message = "done the old way"
        return common.Status.SUCCESS


class Fails(Skill):
    """Fails with an error raised with a Feedback (as the registration skills do)."""
    NAME = "Fails"

    def update(self):
        try:
            raise SkillError(Feedback("the fridge moved 12.0 cm", moved_cm=12.0))
        except SkillError as err:
            self.report_error(err)
        return common.Status.FAILURE


def _skills():
    return {**test_skills(), **{c.NAME: c for c in (Weigh, OldStyle, Fails)}}


WANT = {"fitness": 0.8612, "rmse_mm": 4.1, "points": 812, "landmarks": ["fridge", "oven"],
        "pose": {"x": 1.5, "y": 2.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.5},
        "spread": [0.1, 0.2], "gap": None}


def test_reported_values_reach_the_event_and_the_run_log_as_json_values(make_executive,
                                                                        mission_file):
    path = mission_file("name: x\ntree:\n  sequence:\n    - {skill: Weigh, name: weigh}\n"
                        "    - {skill: OldStyle, name: old}\n")
    ex = make_executive(skills=_skills())
    seen = []
    ex.subscribe(seen.append)
    h = ex.submit(path)
    ex.run_until_idle(100)
    assert h.result.outcome == "succeeded", h.result.reason
    fb = {e.path: e.data for e in seen if e.kind is EventKind.FEEDBACK}
    assert fb["/x/weigh"] == {"message": "fix on fridge not trusted: too weak (fitness 0.86)",
                              "values": WANT}
    assert type(fb["/x/weigh"]["message"]) is str
    assert fb["/x/old"] == {"message": "done the old way"}          # no values: no key
    lines = [json.loads(line) for line in open(h.result.log_path, encoding="utf-8")]
    logged = {e["path"]: e for e in lines if e["e"] == "feedback"}
    assert logged["/x/weigh"]["values"] == WANT
    assert isinstance(logged["/x/weigh"]["values"]["fitness"], float)
    assert "values" not in logged["/x/old"]
    # `hearth log show` prints the values after the sentence.
    shown = format_event(logged["/x/weigh"])
    assert "not trusted: too weak (fitness 0.86)  values={fitness: 0.861, rmse_mm: 4.1" in shown


def test_the_same_sentence_with_new_values_is_a_new_event_and_unchanged_feedback_is_not(
        make_executive, mission_file):
    class Count(Skill):
        NAME = "Count"

        def initialise(self):
            self.n = 0

        def update(self):
            self.n += 1
            self.report("counting", n=min(self.n, 3))
            return common.Status.RUNNING if self.n < 6 else common.Status.SUCCESS

    path = mission_file("name: x\ntree: {skill: Count, name: count}\n")
    ex = make_executive(skills={**test_skills(), "Count": Count})
    seen = []
    ex.subscribe(seen.append)
    ex.submit(path)
    ex.run_until_idle(100)
    said = [e.data["values"]["n"] for e in seen if e.kind is EventKind.FEEDBACK]
    assert said == [1, 2, 3]


def test_an_error_raised_with_a_feedback_keeps_its_values(make_executive, mission_file):
    path = mission_file("name: x\ntree: {skill: Fails, name: fails}\n")
    ex = make_executive(skills=_skills())
    h = ex.submit(path)
    ex.run_until_idle(100)
    assert h.result.reason.endswith("failed: Fails: the fridge moved 12.0 cm")
    lines = [json.loads(line) for line in open(h.result.log_path, encoding="utf-8")]
    assert [e["values"] for e in lines if e["e"] == "feedback"] == [{"moved_cm": 12.0}]


def test_a_feedback_is_its_sentence_for_code_that_reads_text():
    fb = Feedback("3 knobs read", on=["k1"], angle=np.float32(12.5))
    assert fb == "3 knobs read" and f"{fb}!" == "3 knobs read!" and fb.text == "3 knobs read"
    assert fb.values == {"on": ["k1"], "angle": 12.5}
    assert json.dumps(fb) == '"3 knobs read"'
    again = pickle.loads(pickle.dumps(fb))           # suites send results between processes
    assert again == fb and again.values == fb.values
    assert values_of("plain") == {} and values_of(SkillError(fb)) == fb.values


def test_words_write_values_as_the_monitor_page_does_never_as_python_reprs():
    place = {"place": "kitchen_table", "parking": "kitchen_table_west", "x": 1.8, "y": 2.2,
             "yaw": 0.0, "cost": -8.4511, "probability": 0.6}
    assert words(place) == "kitchen_table from kitchen_table_west (p 0.6)"
    assert words({"part": "door_left", "handle": "handle_left"}) == "part door_left, handle handle_left"
    assert words(Pose(1.0, 2.25, 0.0, 0.0, 0.0, np.pi / 2)) == "(1, 2.25) m, yaw 90°"
    assert words([1, 2, 3, 4, 5, 6]) == "1, 2, 3, 4 … (6 in all)"
    assert words(np.float64(0.123456)) == "0.123" and words(True) == "yes" and words(None) == "none"


def test_a_condition_says_its_list_operands_in_words_and_carries_them_as_values(make_executive,
                                                                                 mission_file):
    path = mission_file("""\
        name: x
        blackboard: {unread: [k1, k2], done: []}
        tree:
          sequence:
            - condition: "{done} == {unread}"
              name: none_done
            - {skill: Act, name: after}
        """)
    ex = make_executive()
    seen = []
    ex.subscribe(seen.append)
    h = ex.submit(path)
    ex.run_until_idle(100)
    said = {e.path.rsplit("/", 1)[1]: e.data for e in seen if e.kind is EventKind.FEEDBACK}
    assert said["none_done"] == {"message": "{done} == {unread}: nothing == (k1, k2) is False",
                                 "values": {"left": [], "right": ["k1", "k2"]}}
    assert h.result.outcome == "failed"


class OnePlace(Skill):
    """Writes one search place where a list of them is wanted (its output is of type any,
    so loading cannot tell)."""
    NAME = "OnePlace"
    OUTPUTS = (Port("place", "any"),)

    def update(self):
        self.set_output("place", {"place": "hall", "x": 1.0})
        return common.Status.SUCCESS


def test_a_for_each_over_something_not_a_list_fails_saying_what_it_is(make_executive,
                                                                       mission_file):
    path = mission_file("""\
        name: x
        tree:
          sequence:
            - {skill: OnePlace, outputs: {place: places}}
            - for_each: {skill: Act, name: visit}
              in: "{places}"
              as: place
              name: each
        """)
    ex = make_executive(skills={**test_skills(), "OnePlace": OnePlace})
    seen = []
    ex.subscribe(seen.append)
    h = ex.submit(path)
    ex.run_until_idle(100)
    assert h.result.outcome == "failed"
    assert h.result.reason == "/x/each failed: the source is not a list but a dict: hall"
    said = [e.data for e in seen if e.kind is EventKind.FEEDBACK and e.path.endswith("/each")]
    assert said == [{"message": "the source is not a list but a dict: hall",
                     "values": {"source": {"place": "hall", "x": 1.0}}}]


class Unknown(Skill):
    """Fails on a KeyError raised with a message, as the object skills do."""
    NAME = "Unknown"

    def update(self):
        try:
            raise KeyError('no small object matches "green mug"')
        except KeyError as err:
            self.report_error(err)
        return common.Status.FAILURE


def test_a_key_error_is_reported_as_its_message_and_a_robot_action_keeps_its_values(
        make_executive, mission_file):
    from hearth.skills.navigation import NavigateTo
    path = mission_file("""\
        name: x
        tree:
          selector:
            - {skill: Unknown, name: unknown}
            - skill: NavigateTo
              name: go
              inputs: {target: {room: hall}}
        """)
    ex = make_executive(skills={**_skills(), "Unknown": Unknown, "NavigateTo": NavigateTo})
    seen = []
    ex.subscribe(seen.append)
    h = ex.submit(path)
    ex.run_until_idle(100)
    assert h.result.outcome == "failed"
    said = {e.path.rsplit("/", 1)[1]: e.data for e in seen if e.kind is EventKind.FEEDBACK}
    # str(KeyError) would be the message's repr, in quotes
    assert said["unknown"] == {"message": 'Unknown: no small object matches "green mug"'}
    assert said["go"] == {"message": "not a pose: room hall", "values": {"value": {"room": "hall"}}}
