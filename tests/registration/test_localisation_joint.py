"""Views registered together (hearth.perception.localisation ``refine_localisation_views``;
RefineLocalisation registering every view so far when its own is not a correction;
LookAtLandmark ``seen``): two long fronts at right angles, each leaving the direction
along it free, pin the base pose down together."""
from __future__ import annotations

import math

import numpy as np
import py_trees
import pytest

from hearth.benchmarks.registration import T_BASE_CAMERA, planar, simulate_depth
from hearth.perception.camera import Intrinsics
from hearth.perception.localisation import (
    LocalisationConfig, LocalisationView, refine_localisation, refine_localisation_views,
)
from hearth.skills.registration import RefineLocalisation

from tests.registration.test_registration_skills import FramedRobot, make

S = py_trees.common.Status
K = Intrinsics.kinect()
pytestmark = pytest.mark.usefixtures("clean_blackboard")

# An L of worktops in a corner, each 5 m long (far wider than the image at 1.5 m): one along
# x with its front facing -y, one along y with its front facing -x.
_KITCHEN = """<?xml version='1.0' encoding='UTF-8'?>
<apartment id="flat" version="1">
  <room id="kitchen" name="kitchen" bounds="-4 -4 6 6">
    <LargeObject id="worktop_x" type="counter" static="true">
      <pose x="0" y="2.3"/>
      <model><box size="5.0 0.6 0.9" color="0.6 0.6 0.6"><pose z="0.45"/></box></model>
      <parking default="p"><position id="p" x="0" y="-1.2" yaw="1.5708"/></parking>
    </LargeObject>
    <LargeObject id="worktop_y" type="counter" static="true">
      <pose x="2.3" y="0" yaw="1.5708"/>
      <model><box size="5.0 0.6 0.9" color="0.6 0.6 0.6"><pose z="0.45"/></box></model>
      <parking default="p"><position id="p" x="0" y="1.2" yaw="-1.5708"/></parking>
    </LargeObject>
  </room>
</apartment>
"""


@pytest.fixture
def kitchen(tmp_path):
    from hearth.worldmodel import load_world
    path = tmp_path / "kitchen.xml"
    path.write_text(_KITCHEN)
    return load_world(path)


# The robot stands at the origin facing +x (the worktop along y ahead); its belief is 6 cm
# and 5 cm off and turned 2 degrees. The head pans to +90 degrees for the other worktop.
T_TRUE = planar(0.0, 0.0, 0.0)
T_BELIEVED = T_TRUE @ planar(0.06, -0.05, math.radians(2.0))


def _camera(pan_deg: float) -> np.ndarray:
    return planar(0.0, 0.0, math.radians(pan_deg)) @ T_BASE_CAMERA


def _view(world, pan_deg: float, landmark: str, seed: int = 0) -> LocalisationView:
    depth = simulate_depth(world, K, T_TRUE @ _camera(pan_deg), np.random.default_rng(seed))
    return LocalisationView(depth, K, T_BELIEVED @ _camera(pan_deg), T_BELIEVED, (landmark,))


def _off_cm(T_world_base: np.ndarray) -> float:
    E = np.linalg.inv(T_TRUE) @ T_world_base
    return 100 * math.hypot(E[0, 3], E[1, 3])


def test_two_fronts_that_each_leave_a_direction_free_pin_the_pose_down_together(kitchen):
    cfg = LocalisationConfig()
    ahead, left = _view(kitchen, 0.0, "worktop_y"), _view(kitchen, 90.0, "worktop_x", 1)
    for v in (ahead, left):
        alone = refine_localisation(kitchen, v.depth, K, v.T_world_camera, v.T_world_base, cfg,
                                    landmarks=list(v.landmarks))
        assert not (alone.ok and not alone.loose), (v.landmarks, alone.quality)
    joint = refine_localisation_views(kitchen, [ahead, left], cfg)
    assert joint.ok and not joint.loose, joint.quality
    assert joint.quality["views"] == 2 and joint.landmarks == ["worktop_y", "worktop_x"]
    assert _off_cm(joint.T_world_base) < 1.0
    assert abs(math.degrees(math.atan2(*(np.linalg.inv(T_TRUE) @ joint.T_world_base)[[1, 0], 0])))\
        < 0.5


def test_a_view_taken_before_a_correction_is_registered_as_the_robot_saw_it(kitchen):
    """A correction applied between two views moves the belief, not the robot: the earlier
    view, taken at the old belief, still registers to the same true pose."""
    ahead = _view(kitchen, 0.0, "worktop_y")
    moved = planar(0.03, 0.02, math.radians(-1.0)) @ T_BELIEVED      # a loose fix applied
    depth = simulate_depth(kitchen, K, T_TRUE @ _camera(90.0), np.random.default_rng(1))
    left = LocalisationView(depth, K, moved @ _camera(90.0), moved, ("worktop_x",))
    joint = refine_localisation_views(kitchen, [ahead, left], LocalisationConfig())
    assert joint.ok and not joint.loose, joint.quality
    assert _off_cm(joint.T_world_base) < 1.0
    assert np.allclose(joint.views[0].T_world_base, moved)


class _HeadRobot(FramedRobot):
    """FramedRobot whose head is panned (degrees) before a capture."""
    pan = 0.0

    def capture(self):
        frame = super().capture()
        depth = simulate_depth(self.truth, K, self.T_true @ _camera(self.pan),
                               np.random.default_rng(int(self.pan)))
        return type(frame)(depth, K, self.T_bel @ _camera(self.pan))


def test_the_skill_corrects_on_the_views_together_when_no_view_pins_the_pose_alone(kitchen):
    robot = _HeadRobot(kitchen, T_TRUE, T_BELIEVED.copy())
    first = make(RefineLocalisation, kitchen, robot,
                 outputs={"correction": "/c", "quality": "/q", "views": "/v"})
    first.tick_once()
    assert first.status == S.FAILURE and robot.corrections == []
    views = py_trees.blackboard.Blackboard.get("/v")
    assert [v["landmarks"] for v in views] == [["worktop_y"]]
    robot.pan = 90.0
    second = make(RefineLocalisation, kitchen, robot, inputs={"earlier": views},
                  outputs={"correction": "/c", "quality": "/q", "views": "/v"})
    second.tick_once()
    assert second.status == S.SUCCESS, second.feedback_message
    assert "on worktop_y, worktop_x together (2 views)" in second.feedback_message
    assert len(robot.corrections) == 1 and _off_cm(robot.corrections[0].matrix()) < 1.0
    assert py_trees.blackboard.Blackboard.get("/q")["views"] == 2


def test_further_looks_go_to_the_landmark_the_views_have_shown_least(demo_world):
    from hearth.skills.missions_support import LookAtLandmark
    from tests.registration.test_registration_skills import _in_front

    class Head:
        def __init__(self, T):
            self.T, self.looked = T, []

        def base_pose(self):
            from hearth.worldmodel.pose import Pose
            return Pose.from_matrix(self.T)

        def look_at(self, p):
            self.looked.append(p)

    robot = Head(_in_front(demo_world, "cupboard", 1.2))
    picks = []
    for seen in ([], [{"landmarks": ["cupboard"]}]):
        s = make(LookAtLandmark, demo_world, robot, inputs={"index": 0, "seen": seen},
                 outputs={"landmark": "/l"})
        s.tick_once()
        assert s.status == S.SUCCESS, s.feedback_message
        picks.append(py_trees.blackboard.Blackboard.get("/l"))
    assert picks[0] == "cupboard" and picks[1] != "cupboard"
    room = demo_world.room_of("cupboard").id
    assert demo_world.room_of(picks[1]).id == room
