"""Next best view: candidates, collisions, occlusion and hypothesis separation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.benchmarks._worlds import places
from hearth.benchmarks.nbv import occluded_scene
from hearth.benchmarks.objects import box_object, observe, visible_fractions
from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.errors import PerceptionError
from hearth.worldmodel.pose import Pose
from hearth.perception.nbv import (NBVConfig, footprints, from_map, occupancy_voxels,
                            plan_next_best_view, _box_distance)

K = Intrinsics.kinect()


def _blocked_cup(world):
    """The blue cup with a tall box right in front of it as seen from the south."""
    truth = world.copy()
    p = truth.get("blue_cup").pose
    truth.add_small_object(box_object("wall", (0.03, 0.16, 0.2), (0.3, 0.6, 0.3),
                                      Pose(p.x, p.y - 0.13, p.z, 0, 0, math.pi / 2)),
                           "kitchen_table")
    T = truth.T_world("kitchen_table")
    T_wc = look_at(T[:3, 3] + (-0.1, -1.3, 1.3), truth.T_world("blue_cup")[:3, 3])
    return truth, T_wc


def test_best_view_sees_an_occluded_cup_unoccluded(demo_world):
    truth, T1 = _blocked_cup(demo_world)
    rng = np.random.default_rng(0)
    depth, _, r1 = observe(truth, T1, rng, K)
    vis1 = visible_fractions(truth, r1, T1, K, ["blue_cup"])["blue_cup"]
    assert vis1 < 0.3
    views = plan_next_best_view(demo_world, from_map(demo_world, "blue_cup"), depth, K, T1)
    _, _, r2 = observe(truth, views[0].T_world_camera, rng, K)
    vis2 = visible_fractions(truth, r2, views[0].T_world_camera, K, ["blue_cup"])["blue_cup"]
    assert vis2 > 0.9
    assert views[0].visible_fraction > 0.9
    # The views straight behind the wall (south) are predicted occluded.
    south = [v for v in views if abs(v.base_pose[0] - 2.9) < 0.25 and v.base_pose[1] < 2.0]
    assert south and max(v.visible_fraction for v in south) < 0.5


def test_views_are_sorted_best_first_and_stand_clear_of_furniture(demo_world):
    truth, T1 = _blocked_cup(demo_world)
    depth, _, _ = observe(truth, T1, np.random.default_rng(1), K)
    views = plan_next_best_view(demo_world, from_map(demo_world, "blue_cup"), depth, K, T1)
    scores = [v.score for v in views]
    assert scores == sorted(scores, reverse=True)
    xy = np.array([v.base_pose[:2] for v in views])
    for T, box in footprints(demo_world, "kitchen"):
        assert (_box_distance(xy, T, box) > NBVConfig().robot_radius).all()
    # Every candidate faces the object.
    cup = demo_world.T_world("blue_cup")[:2, 3]
    for v in views:
        x, y, yaw = v.base_pose
        assert abs(math.remainder(math.atan2(cup[1] - y, cup[0] - x) - yaw, 2 * math.pi)) < 0.15


def test_an_observed_obstacle_removes_the_candidates_near_it(demo_world):
    T1 = look_at((3.0, 0.6, 1.3), (3.0, 2.2, 0.75))
    depth = np.zeros((K.height, K.width))
    views = plan_next_best_view(demo_world, from_map(demo_world, "blue_cup"), depth, K, T1)
    truth = demo_world.copy()
    # A crate on the floor south of the table, in view, where some candidates stood.
    from hearth.worldmodel.nodes import Model, SmallObject, Visual
    from hearth.worldmodel.pose import Pose
    truth.add_small_object(SmallObject("crate", "box", Pose(0.25, -0.85, 0, 0, 0, 0),
                                       model=Model([Visual("box", Pose(0, 0, 0.3),
                                                           size=(0.3, 0.3, 0.6))])),
                           "kitchen_table")
    depth2, _, _ = observe(truth, T1, np.random.default_rng(2), K)
    views2 = plan_next_best_view(demo_world, from_map(demo_world, "blue_cup"), depth2, K, T1)
    T = truth.T_world("crate")
    box = np.array([-0.15, -0.15, 0.15, 0.15])
    # Only the crate's seen faces are known: allow a few centimetres at its hidden corners.
    near = lambda vs: [v for v in vs if _box_distance(np.array([v.base_pose[:2]]), T, box)[0]
                       < NBVConfig().robot_radius - 0.05]
    assert near(views) and not near(views2)


def test_the_view_that_shows_the_handle_separates_yaw_hypotheses(demo_world):
    # Two hypotheses of the red cup: handle towards +x or towards -x.
    hs = from_map(demo_world, "red_cup", yaws=(0.0, math.pi))
    T1 = look_at((2.65, 1.0, 1.3), demo_world.T_world("red_cup")[:3, 3])
    views = plan_next_best_view(demo_world, hs, np.zeros((K.height, K.width)), K, T1)
    best = views[0]
    assert best.separation > 0
    cup = demo_world.T_world("red_cup")[:2, 3]
    # Looking along x (either side) shows one handle in front of or behind the body, from
    # +-y it shows both possibilities side by side: the best view is not along the x axis.
    d = np.array(best.base_pose[:2]) - cup
    assert abs(d[1]) > 0.3 * np.linalg.norm(d)
    assert best.separation >= np.median([v.separation for v in views])


def test_occupancy_extrudes_surfaces_away_from_the_camera():
    pts = np.array([[1.0, 0.0, 0.0]])
    vox = occupancy_voxels(pts, np.zeros(3), 0.02, 0.1)
    assert vox[:, 0].min() == 50 and vox[:, 0].max() >= 54
    assert (vox[:, 1:] == 0).all()


def test_no_hypothesis_is_an_error(demo_world):
    with pytest.raises(PerceptionError):
        plan_next_best_view(demo_world, [], np.zeros((K.height, K.width)), K, np.eye(4))


def test_generated_nbv_scenes_hide_the_target_from_the_first_view(demo_world):
    rng = np.random.default_rng(5)
    table = next(p for p in places(demo_world) if p.name == "kitchen_table/top")
    truth, T1, target, _ = occluded_scene(rng, table, demo_world)
    _, _, r = observe(truth, T1, rng, K)
    assert visible_fractions(truth, r, T1, K, [target])[target] < 0.6
