"""The registration skills ticked once against a robot that serves rendered frames."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import py_trees
import pytest

from hearth.benchmarks.registration import T_BASE_CAMERA, planar, simulate_depth
from hearth.perception.camera import Intrinsics
from hearth.skills.base import Bindings, Key, Literal
from hearth.skills.registration import (
    EstimateHandle, RefineLocalisation, RegisterArticulated, RegisterLargeObject,
)
from hearth.worldmodel.pose import Pose

S = py_trees.common.Status
K = Intrinsics.kinect()


@dataclass
class Frame:
    depth: np.ndarray
    intrinsics: Intrinsics
    T_world_camera: np.ndarray


class FramedRobot:
    """Renders the truth from its true pose; reports a believed pose (drifted)."""

    def __init__(self, truth, T_true_base, T_believed_base):
        self.truth, self.T_true, self.T_bel = truth, T_true_base, T_believed_base
        self.corrections = []

    def capture(self):
        depth = simulate_depth(self.truth, K, self.T_true @ T_BASE_CAMERA, np.random.default_rng(0))
        return Frame(depth, K, self.T_bel @ T_BASE_CAMERA)

    def base_pose(self):
        return Pose.from_matrix(self.T_bel)

    def apply_correction(self, pose):
        self.corrections.append(pose)
        self.T_bel = pose.matrix()


# py_trees' blackboard is global: each test here starts and ends with an empty one.
pytestmark = pytest.mark.usefixtures("clean_blackboard")


def make(cls, world, robot, inputs=None, outputs=None):
    b = Bindings({k: Literal(v) for k, v in (inputs or {}).items()},
                 {k: Key(v) for k, v in (outputs or {}).items()})
    skill = cls(bindings=b)
    skill.setup(world=world, robot=robot)
    return skill


def _in_front(world, oid, distance=1.6):
    To = world.T_world(oid)
    p = To @ np.array([distance, 0.1, 0, 1])
    return planar(p[0], p[1], math.atan2(To[1, 3] - p[1], To[0, 3] - p[0]))


def test_refine_localisation_applies_the_correction_through_the_robot(demo_world):
    T_true = _in_front(demo_world, "drawer_unit", 1.9)
    robot = FramedRobot(demo_world, T_true, T_true @ planar(0.07, -0.05, math.radians(4)))
    s = make(RefineLocalisation, demo_world, robot, outputs={"correction": "/c", "quality": "/q"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    assert len(robot.corrections) == 1
    E = np.linalg.inv(T_true) @ robot.corrections[0].matrix()
    assert math.hypot(E[0, 3], E[1, 3]) < 0.01
    assert "localisation corrected" in s.feedback_message
    assert py_trees.blackboard.Blackboard.get("/q")["residual_mm"] < 5


def test_a_fix_that_is_not_pinned_down_is_applied_but_the_skill_fails(demo_world, monkeypatch):
    """A trusted fix that a pose 3 cm away explains nearly as well (``loose``: a long front
    sliding along itself) moves the believed pose, the best the view gives, but the skill
    fails, so that no mission says "corrected" on it and the missions try other landmarks."""
    import hearth.perception.localisation as localisation
    real = localisation.refine_localisation

    def loose(*args, **kwargs):
        fix = real(*args, **kwargs)
        assert fix.ok and not fix.loose           # the drawer unit pins the pose down ...
        fix.quality.update(loose=True, ring_drop=0.012, ring_m=0.05)   # ... this one does not,
        # on a ring of 5 cm (the sentence names the ring the fix was probed on)
        return fix
    monkeypatch.setattr(localisation, "refine_localisation", loose)
    T_true = _in_front(demo_world, "drawer_unit", 1.9)
    robot = FramedRobot(demo_world, T_true, T_true @ planar(0.07, -0.05, math.radians(4)))
    s = make(RefineLocalisation, demo_world, robot, outputs={"correction": "/c", "quality": "/q"})
    s.tick_once()
    assert s.status == S.FAILURE
    assert len(robot.corrections) == 1
    assert "not pinned down: a pose 5 cm away explains the view nearly as well" in s.feedback_message
    assert py_trees.blackboard.Blackboard.get("/q")["loose"] is True


def test_register_articulated_writes_door_states_with_history(demo_world):
    truth = demo_world.copy()
    truth.set_joint_state("cupboard_door_left", math.radians(40))
    T = _in_front(demo_world, "cupboard")
    robot = FramedRobot(truth, T, T)
    s = make(RegisterArticulated, demo_world, robot, inputs={"object": "cupboard"},
             outputs={"states": "/states", "unknown": "/unknown"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    states = py_trees.blackboard.Blackboard.get("/states")
    assert abs(states["cupboard_door_left"] - 40) < 1
    assert abs(math.degrees(demo_world.get("cupboard_door_left").joint.state) - 40) < 1
    h = demo_world.history("cupboard_door_left")
    assert h and h[-1].source == "RegisterArticulated"


def test_estimate_handle_outputs_the_handle_pose(demo_world):
    truth = demo_world.copy()
    truth.set_joint_state("cupboard_door_right", math.radians(25))
    T = _in_front(demo_world, "cupboard")
    s = make(EstimateHandle, demo_world, FramedRobot(truth, T, T),
             inputs={"handle": "cupboard_handle_right"}, outputs={"pose": "/pose"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    pose = py_trees.blackboard.Blackboard.get("/pose")
    assert np.linalg.norm(pose.position - truth.T_world("cupboard_handle_right")[:3, 3]) < 0.005


def test_register_large_object_updates_a_moved_object(demo_world):
    truth = demo_world.copy()
    p = demo_world.get("drawer_unit").pose
    truth.set_pose("drawer_unit", Pose(p.x - 0.04, p.y + 0.03, 0, 0, 0, p.yaw))
    T = _in_front(demo_world, "drawer_unit")
    s = make(RegisterLargeObject, demo_world, FramedRobot(truth, T, T),
             inputs={"object": "drawer_unit"}, outputs={"pose": "/pose"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    got = demo_world.get("drawer_unit").pose
    assert math.hypot(got.x - (p.x - 0.04), got.y - (p.y + 0.03)) < 0.003
    assert demo_world.history("drawer_unit")[-1].source == "RegisterLargeObject"


def test_an_object_out_of_view_fails_with_one_line(demo_world):
    T = _in_front(demo_world, "fridge")
    s = make(RegisterArticulated, demo_world, FramedRobot(demo_world, T, T),
             inputs={"object": "cupboard"})
    s.tick_once()
    assert s.status == S.FAILURE
    assert "cupboard" in s.feedback_message and "\n" not in s.feedback_message


def test_simulated_robot_with_a_door_ajar_is_relocalised_and_reads_the_door(demo_world):
    from hearth.robot.simulated import SimulatedRobot
    truth = demo_world.copy()
    truth.set_joint_state("cupboard_door_left", math.radians(30))     # the map says closed
    start = demo_world.parking_pose("cupboard", "cupboard_front")
    # Seed 0: with this door ajar and this error, the fix is trusted for about half of the
    # noise seeds (seeds 0-11: 6 of 12; 7 of 12 with the noise drawn in its earlier order);
    # the refused ones (seeds 0-7 checked) are within 0.7 cm and 0.4 degrees of the trusted
    # ones but "did not converge" (ICP restarted from the fix turns it by 0.31-0.5 degrees,
    # over settle_deg): refusals, not wrong fixes.
    robot = SimulatedRobot(truth, start_pose=start, seed=0,
                           localisation_error=Pose.planar(0.08, -0.06, math.radians(5)))
    look = robot.look_at(demo_world.T_world("cupboard")[:3, 3] + np.array([0, 0, 0.45]))
    while look.status() == "running":
        robot.clock.advance(0.1)
    s = make(RefineLocalisation, demo_world, robot, outputs={"correction": "/c"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    b = robot.base_pose()
    assert math.hypot(b.x - start.x, b.y - start.y) < 0.01
    assert abs(math.degrees(b.yaw - start.yaw)) < 0.5
    s = make(RegisterArticulated, demo_world, robot, inputs={"object": "cupboard"},
             outputs={"states": "/states"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    assert abs(py_trees.blackboard.Blackboard.get("/states")["cupboard_door_left"] - 30) < 1
