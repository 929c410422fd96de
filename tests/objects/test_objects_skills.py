"""DetectObject, VerifyObject and PlanNextBestView against the simulated robot."""
from __future__ import annotations

import math

import numpy as np
import py_trees
import pytest

from hearth.benchmarks.objects import box_object
from hearth.skills.base import Bindings, Key, Literal
from hearth.skills.objects import DetectObject, PlanNextBestView, VerifyObject
from hearth.worldmodel.pose import Pose


# py_trees' blackboard is global: each test here starts and ends with an empty one.
pytestmark = pytest.mark.usefixtures("clean_blackboard")


def make(cls, world, robot, inputs=None, outputs=None):
    b = Bindings({k: v if isinstance(v, Key) else Literal(v) for k, v in (inputs or {}).items()},
                 {k: Key(v) for k, v in (outputs or {}).items()})
    skill = cls(bindings=b)
    skill.setup(world=world, robot=robot)
    return skill


def robot_at_table(truth):
    from hearth.robot.simulated import SimulatedRobot
    robot = SimulatedRobot(truth, start_pose=(3.0, 1.2, math.pi / 2), seed=0)
    robot.look_at(truth.T_world("kitchen_table")[:3, 3] + (0, 0, 0.75))
    return robot


def tick(skill):
    skill.tick_once()
    return skill.status


def bb(key):
    return py_trees.blackboard.Blackboard.get(key)


def test_detect_object_finds_the_moved_blue_cup_and_updates_the_map(demo_world):
    truth = demo_world.copy()
    truth.move_object("blue_cup", "kitchen_table", Pose(0.1, -0.05, 0.75, 0, 0, 1.0))
    skill = make(DetectObject, demo_world, robot_at_table(truth), {"object": "the blue cup"},
                 {"pose": "/pose", "confidence": "/conf", "hypotheses": "/hyps"})
    assert tick(skill) == py_trees.common.Status.SUCCESS, skill.feedback_message
    assert "blue_cup" in skill.feedback_message
    assert np.linalg.norm(bb("/pose").matrix()[:2, 3] - truth.T_world("blue_cup")[:2, 3]) < 0.015
    assert bb("/conf") > 0.5
    assert {h["object"] for h in bb("/hyps")} >= {"blue_cup", "red_cup"}
    moved = demo_world.get("blue_cup").pose
    assert math.hypot(moved.x - 0.1, moved.y + 0.05) < 0.015
    assert demo_world.history("blue_cup")[-1].source == "DetectObject"


def test_detect_object_fails_when_the_object_is_hidden_but_still_gives_hypotheses(demo_world):
    truth = demo_world.copy()
    p = truth.get("blue_cup").pose
    truth.add_small_object(box_object("wall", (0.03, 0.2, 0.22), (0.3, 0.6, 0.3),
                                      Pose(p.x, p.y - 0.12, p.z, 0, 0, math.pi / 2)),
                           "kitchen_table")
    skill = make(DetectObject, demo_world, robot_at_table(truth), {"object": "blue_cup"},
                 {"hypotheses": "/hyps"})
    assert tick(skill) == py_trees.common.Status.FAILURE
    assert "not recognised" in skill.feedback_message
    assert bb("/hyps")  # the other objects on the table

    plan = make(PlanNextBestView, demo_world, robot_at_table(truth),
                {"object": "blue cup", "hypotheses": Key("/hyps")},
                {"pose": "/view", "look_at": "/look", "visible_fraction": "/vis"})
    assert tick(plan) == py_trees.common.Status.SUCCESS, plan.feedback_message
    view = bb("/view")
    assert bb("/vis") > 0.8
    # Not from behind the wall (south of the cup).
    cup = truth.T_world("blue_cup")[:2, 3]
    assert view.y > cup[1] - 0.3 or abs(view.x - cup[0]) > 0.5
    assert len(bb("/look")) == 3


def test_verify_object_accepts_the_right_place_and_rejects_a_wrong_one(demo_world):
    robot = robot_at_table(demo_world.copy())
    ok = make(VerifyObject, demo_world, robot, {"object": "red_cup"}, {"confidence": "/c"})
    assert tick(ok) == py_trees.common.Status.SUCCESS, ok.feedback_message
    assert bb("/c") > 0.5
    wrong = demo_world.world_pose("blue_cup")  # the red cup is not where the blue one stands
    bad = make(VerifyObject, demo_world, robot, {"object": "red_cup", "pose": wrong},
               {"confidence": "/c2"})
    assert tick(bad) == py_trees.common.Status.FAILURE
    assert bb("/c2") < 0.3


def test_unknown_object_words_fail_with_a_message(demo_world):
    skill = make(DetectObject, demo_world, robot_at_table(demo_world.copy()),
                 {"object": "purple teapot"})
    assert tick(skill) == py_trees.common.Status.FAILURE
    assert "purple teapot" in skill.feedback_message
