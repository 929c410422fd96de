"""ReadKnobs and TurnKnob ticked against a robot that serves rendered frames of the oven."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
import py_trees
import pytest

from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.knob_data import KnobScenes
from hearth.perception.knobs import knob_priors
from hearth.skills.base import Bindings, Key, Literal
from hearth.skills.knobs import ReadKnobs, TurnKnob

S = py_trees.common.Status
K = Intrinsics.kinect()


@dataclass
class Frame:
    color: np.ndarray
    intrinsics: Intrinsics
    T_world_camera: np.ndarray
    depth: Optional[np.ndarray] = None


class Action:
    def __init__(self, ticks=2):
        self.ticks, self.cancelled = ticks, False

    def status(self):
        if self.cancelled:
            return "cancelled"
        self.ticks -= 1
        return "running" if self.ticks > 0 else "succeeded"

    def cancel(self):
        self.cancelled = True


class OvenRobot:
    """Renders the oven with the true knob angles from a camera in front of it."""

    def __init__(self, world, truth_angles, ticks=2, depth=False):
        self.world, self.truth, self.ticks, self.depth = world, dict(truth_angles), ticks, depth
        self.scenes = KnobScenes(world)
        priors = knob_priors(world, "oven")
        mid = np.mean([p.T_world_face()[:3, 3] for p in priors], axis=0)
        self.T_wc = look_at(mid + 0.9 * priors[0].T_world_knob[:3, 2] + [0, 0, 0.45], mid)
        self.turned = []

    def capture(self):
        r = self.scenes.scene("oven", self.truth).render(K, self.T_wc)
        return Frame(r.color, K, self.T_wc, r.depth if self.depth else None)

    def turn_knob(self, knob_id, angle):
        self.turned.append((knob_id, angle))
        self.truth[knob_id] = angle
        return Action(self.ticks)


# py_trees' blackboard is global: each test here starts and ends with an empty one.
pytestmark = pytest.mark.usefixtures("clean_blackboard")


def make(cls, world, robot, reader, inputs=None, outputs=None):
    b = Bindings({k: Literal(v) for k, v in (inputs or {}).items()},
                 {k: Key(v) for k, v in (outputs or {}).items()})
    skill = cls(bindings=b)
    skill.setup(world=world, robot=robot, knob_reader=reader)
    return skill


@pytest.mark.parametrize("depth", [False, True], ids=["colour", "colour+depth"])
def test_read_knobs_writes_each_state_to_the_map(demo_world, reader, depth):
    k3 = demo_world.get("oven_knob_3")
    robot = OvenRobot(demo_world, {"oven_knob_3": k3.state_angle("4")}, depth=depth)
    s = make(ReadKnobs, demo_world, robot, reader, {"object": "oven"},
             {"states": "/states", "on": "/on"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    states = py_trees.blackboard.Blackboard.get("/states")
    assert states["oven_knob_3"] == "4"
    assert py_trees.blackboard.Blackboard.get("/on") == ["oven_knob_3"]
    assert demo_world.get("oven_knob_3").state == "4"
    assert demo_world.history("oven_knob_3")[-1].source == "ReadKnobs"


def test_turn_knob_turns_through_the_robot_and_updates_the_map(demo_world, reader):
    k1 = demo_world.get("oven_knob_1")
    demo_world.set_knob_state("oven_knob_1", "2")
    robot = OvenRobot(demo_world, {"oven_knob_1": k1.state_angle("2")})
    s = make(TurnKnob, demo_world, robot, reader, {"knob": "oven_knob_1"}, {"state": "/state"})
    s.tick_once()
    assert s.status == S.RUNNING
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    assert robot.turned == [("oven_knob_1", k1.state_angle("off"))]
    assert demo_world.get("oven_knob_1").state == "off"


def test_a_halted_turn_cancels_the_robot_action(demo_world, reader):
    robot = OvenRobot(demo_world, {}, ticks=10)
    s = make(TurnKnob, demo_world, robot, reader, {"knob": "oven_knob_2", "state": "3"})
    s.tick_once()
    assert s.status == S.RUNNING
    s.stop(S.INVALID)
    assert s.action.cancelled
    assert demo_world.get("oven_knob_2").state == "off"


def test_turning_to_an_unknown_state_fails_with_the_reason(demo_world, reader):
    s = make(TurnKnob, demo_world, OvenRobot(demo_world, {}), reader,
             {"knob": "oven_knob_2", "state": "11"})
    s.tick_once()
    assert s.status == S.FAILURE
    assert "11" in s.feedback_message
