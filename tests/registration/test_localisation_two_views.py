"""Two views of one base pose must agree along what each pins down (hearth.perception.localisation
``contradiction``; hearth.skills.registration RefineLocalisation ``earlier``/``views``)."""
from __future__ import annotations

import math

import numpy as np
import py_trees
import pytest
from hypothesis import given, settings, strategies as st

from hearth.benchmarks.registration import planar
from hearth.perception.localisation import contradiction
from hearth.skills.registration import RefineLocalisation

from tests.registration.test_registration_skills import FramedRobot, _in_front, make

S = py_trees.common.Status
pytestmark = pytest.mark.usefixtures("clean_blackboard")


def _view(pose, information, centre=(0.0, 0.0), radius=0.5, landmarks=("counter",)):
    return dict(landmarks=list(landmarks), pose=list(pose), centre=list(centre),
                radius=radius, information=np.asarray(information, dtype=float).tolist())


# A long front along world x seen square on: across it (y) and its turn are pinned down,
# along it (x) nothing (eigenvalue 0), as a worktop whose ends the view does not show.
FRONT_ALONG_X = np.diag([0.0, 0.6, 0.2])


def test_a_view_says_nothing_along_the_direction_it_leaves_free():
    earlier = _view((1.0, 2.0, 0.3), FRONT_ALONG_X, centre=(1.0, 3.0))
    along = _view((1.096, 2.0, 0.3), np.eye(3))         # 9.6 cm along the front
    across = _view((1.0, 2.03, 0.3), np.eye(3))          # 3 cm across it
    assert contradiction(earlier, along, 0.005) == pytest.approx(0.0, abs=1e-9)
    assert contradiction(earlier, across, 0.005) == pytest.approx(0.03, abs=1e-6)


def test_a_turn_about_the_landmarks_counts_by_how_far_it_moves_them():
    earlier = _view((0.0, 0.0, 0.0), np.eye(3), centre=(2.0, 0.0), radius=0.8)
    # the base turned 2 degrees about itself: the landmarks' centre 2 m away moves 7 cm
    turned = _view((0.0, 0.0, math.radians(2)), np.eye(3))
    assert contradiction(earlier, turned, 0.005) == pytest.approx(
        2.0 * math.radians(2), rel=0.01)


def test_a_view_that_pins_nothing_contradicts_nothing():
    earlier = _view((0.0, 0.0, 0.0), np.diag([0.001, 0.002, 0.0]))
    assert contradiction(earlier, _view((0.2, 0.2, 0.1), np.eye(3)), 0.005) == 0.0


@settings(max_examples=50, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-3.0, 3.0),
       st.floats(-0.1, 0.1), st.floats(-0.1, 0.1), st.floats(-0.05, 0.05))
def test_a_fully_pinned_view_measures_the_whole_difference(x, y, a, dx, dy, da):
    """With every direction pinned down (isotropic information), the contradiction is the
    largest component of the move about the centre, whatever the pose and the frame."""
    earlier = _view((x, y, a), np.eye(3), centre=(x + 1.0, y), radius=0.5)
    T = planar(dx, dy, da) @ planar(x, y, a)              # a world-frame move of the pose
    later = _view((T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])), np.eye(3))
    c = np.array([x + 1.0, y, 0.0, 1.0])
    moved = (planar(dx, dy, da) @ c)[:2] - c[:2]
    expect = max(abs(moved[0]), abs(moved[1]), 0.5 * abs(da))
    assert contradiction(earlier, later, 0.005) == pytest.approx(expect, abs=1e-9)


def _fix(world, robot):
    from hearth.perception.localisation import refine_localisation
    frame = robot.capture()
    return refine_localisation(world, frame.depth, frame.intrinsics, frame.T_world_camera,
                               robot.T_bel)


def _drawer_unit_robot(demo_world):
    T_true = _in_front(demo_world, "drawer_unit", 1.9)
    return T_true, FramedRobot(demo_world, T_true, T_true @ planar(0.07, -0.05, math.radians(4)))


def test_a_trusted_fix_5_cm_off_that_an_earlier_view_contradicts_is_not_a_correction(
        demo_world, monkeypatch):
    """The fix on the drawer unit is trusted by every figure of its own (as a wrong fix on a
    flat front was, 9.6 cm off); an earlier view of the same pose, which pins down the
    direction the fix is wrong in, contradicts it: the skill fails and leaves the pose."""
    import hearth.perception.localisation as localisation
    real = localisation.refine_localisation
    T_true, robot = _drawer_unit_robot(demo_world)
    right = _fix(demo_world, robot)
    assert right.ok and not right.loose and right.evidence is not None

    def five_cm_off(*args, **kwargs):
        fix = real(*args, **kwargs)
        fix.T_world_base = planar(0.05 * math.cos(1.0), 0.05 * math.sin(1.0), 0.0) \
            @ fix.T_world_base
        T = fix.T_world_base
        fix.evidence = dict(fix.evidence, pose=[T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])])
        return fix
    monkeypatch.setattr(localisation, "refine_localisation", five_cm_off)
    before = robot.T_bel.copy()
    s = make(RefineLocalisation, demo_world, robot, inputs={"earlier": [right.evidence]},
             outputs={"correction": "/c", "quality": "/q", "views": "/v"})
    s.tick_once()
    assert s.status == S.FAILURE
    assert robot.corrections == [] and np.allclose(robot.T_bel, before)
    assert "the view of cupboard, drawer_unit puts the robot 4.5 cm away" in s.feedback_message
    assert "pose left unchanged" in s.feedback_message
    views = py_trees.blackboard.Blackboard.get("/v")
    assert len(views) == 2 and views[0] == right.evidence


def test_a_fix_the_earlier_views_agree_with_is_a_correction(demo_world):
    """The same view again (the earlier estimate within millimetres) and a degenerate view
    whose free direction is the only difference: both agree, the fix is applied."""
    T_true, robot = _drawer_unit_robot(demo_world)
    right = _fix(demo_world, robot)
    x, y, a = right.evidence["pose"]
    slid = _view((x + 0.08, y, a), FRONT_ALONG_X, centre=right.evidence["centre"],
                 landmarks=("worktop",))
    s = make(RefineLocalisation, demo_world, robot,
             inputs={"earlier": [right.evidence, slid]},
             outputs={"correction": "/c", "quality": "/q", "views": "/v"})
    s.tick_once()
    assert s.status == S.SUCCESS, s.feedback_message
    E = np.linalg.inv(T_true) @ robot.corrections[0].matrix()
    assert math.hypot(E[0, 3], E[1, 3]) < 0.01


def test_a_view_that_fails_leaves_the_earlier_views_not_a_stale_list(demo_world):
    """The views output is written before the capture: a registration that raises (no
    landmark in view) passes on what came before it, never a list from another place."""
    robot = FramedRobot(demo_world, planar(50.0, 50.0, 0.0), planar(50.0, 50.0, 0.0))
    py_trees.blackboard.Blackboard.set("/v", ["from another place"])
    earlier = [_view((0.0, 0.0, 0.0), np.eye(3))]
    s = make(RefineLocalisation, demo_world, robot, inputs={"earlier": earlier},
             outputs={"views": "/v"})
    s.tick_once()
    assert s.status == S.FAILURE
    assert py_trees.blackboard.Blackboard.get("/v") == earlier


def _long_front_scene():
    """A 4 m front (a worktop run) 1.5 m ahead, wider than the image: nothing along it but
    where the image cuts it. The believed camera is 9 cm along it from the true one."""
    import open3d as o3d
    from hearth.perception.camera import Intrinsics, look_at
    from hearth.perception.registration import render_reference
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import LabelledMesh
    box = o3d.geometry.TriangleMesh.create_box(4.0, 0.6, 0.9).translate((-2.0, 1.5, 0.0))
    box.compute_triangle_normals()
    meshes = [LabelledMesh("counter", "counter", box, (0.6, 0.6, 0.6))]
    K = Intrinsics.kinect()
    T_true = look_at((0.0, 0.0, 1.2), (0.0, 1.5, 0.6))
    T_bel = planar(0.09, 0.0, 0.0) @ T_true
    depth = Scene(meshes).render(K, T_true).depth
    ref = render_reference(meshes, K, T_bel)
    return K, T_true, T_bel, depth, ref


def test_a_front_cut_by_the_image_is_scored_on_the_points_both_poses_see():
    """On all points the wrong fix (the believed pose, 9 cm along the front) outscores the
    right correction, whose points at the image's edge fall off it; on the points on a
    reading at both, the two tie, so the ring finds the fix loose."""
    from hearth.perception.localisation import LocalisationConfig, _ring_drop
    from hearth.perception.registration import DepthAgreement
    K, T_true, T_bel, depth, ref = _long_front_scene()
    agree = DepthAgreement(ref.points, depth, K, T_bel)
    wrong, right = np.eye(4), T_true @ np.linalg.inv(T_bel)
    s_all = agree(np.stack([wrong, right]))
    at_wrong, at_right = agree.against(wrong, right[None])
    assert s_all[0] > 1.03 * s_all[1]
    assert abs(at_wrong[0] - at_right[0]) <= 0.01 * at_wrong[0]
    drop, _ = _ring_drop(wrong, agree, ref.points.mean(axis=0), LocalisationConfig())
    assert drop < LocalisationConfig().min_ring_drop
