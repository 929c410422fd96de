"""Particle-filter tracking: the KLD bound, pose conversions, HSV similarity, following a cup
pushed across the demo home's kitchen table, and the TrackObject skill."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import py_trees
import pytest
from hypothesis import given, settings, strategies as st

from hearth.perception.camera import Intrinsics
from hearth.perception.errors import PerceptionError
from hearth.perception.tracking import (
    ParticleTracker, TrackerConfig, hsv_cone, kld_bound, pose_matrix, pose_vector,
    reference_from_view, scene_cloud,
)


def test_kld_bound_needs_more_particles_for_more_occupied_bins():
    n = kld_bound(np.array([1, 2, 10, 100, 1000]), 0.08, 2.326)
    assert n[0] == 1
    assert np.all(np.diff(n) > 0)
    # Fox (2003): roughly linear in k for many bins
    assert 0.8 < (n[4] / n[3]) / 10 < 1.1


@settings(max_examples=50, deadline=None)
@given(st.floats(-2, 2), st.floats(-2, 2), st.floats(0, 1.5), st.floats(-1.4, 1.4),
       st.floats(-1.4, 1.4), st.floats(-3.1, 3.1))
def test_pose_vector_inverts_pose_matrix(x, y, z, roll, pitch, yaw):
    p = np.array([x, y, z, roll, pitch, yaw])
    T = pose_matrix(p)
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
    assert np.allclose(pose_matrix(pose_vector(T)), T, atol=1e-9)


def test_hsv_similarity_tells_blue_from_red_and_ignores_hue_of_greys():
    c = hsv_cone(np.array([[25, 50, 200], [200, 25, 25], [30, 60, 190],
                           [120, 120, 122], [122, 120, 120]], dtype=np.uint8))
    blue, red, blue2, grey1, grey2 = c
    assert np.linalg.norm(blue - blue2) < 0.1 < 0.5 < np.linalg.norm(blue - red)
    assert np.linalg.norm(grey1 - grey2) < 0.02


def _sequence(seed=3, frames=24):
    from hearth.benchmarks import _worlds
    from hearth.benchmarks.tracking import run_scenario
    world = _worlds.load("demo")
    table = next(p for p in _worlds.places(world) if p.name == "kitchen_table/top")
    return run_scenario(world, table, "blue_cup", seed, frames)


def test_tracker_follows_a_cup_pushed_across_the_table():
    r = _sequence()
    errs = np.array(r["errs"])
    assert np.median(errs) < 0.02
    assert errs.max() < 0.05
    assert r["lost"] == 0


def test_particle_count_adapts_to_how_spread_the_belief_is():
    from hearth.benchmarks.tracking import PushScene, half_extents
    from hearth.perception.camera import look_at
    from hearth.worldmodel import load_world
    from hearth import demo_world_path
    world = load_world(demo_world_path())
    rng = np.random.default_rng(0)
    K = Intrinsics.kinect(320, 240)
    T_cup = world.T_world("blue_cup")
    T_wc = look_at(T_cup[:3, 3] + [0.0, -1.1, 0.6], T_cup[:3, 3])
    sim = PushScene(world, K, T_wc, rng, "blue_cup")
    r = sim.frame(T_cup)
    pts, cols = scene_cloud(r.depth, r.color, K, T_wc)
    ref = reference_from_view(pts, cols, T_cup, half_extents(world, "blue_cup"))
    cfg = TrackerConfig()
    tr = ParticleTracker(ref, T_cup, cfg, np.random.default_rng(1))
    seen = [tr.update(r.depth, r.color, K, T_wc).n_particles for _ in range(5)]
    blind = np.zeros_like(r.depth)
    unseen = [tr.update(blind, r.color, K, T_wc).n_particles for _ in range(8)]
    assert max(seen) < cfg.max_particles
    assert unseen[-1] > max(seen)      # no evidence: the belief spreads, more particles
    est = tr.update(blind, r.color, K, T_wc)
    assert not est.ok                  # and the tracker says it lost the object


def test_reference_needs_points_of_the_object():
    with pytest.raises(PerceptionError):
        reference_from_view(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.uint8), np.eye(4),
                            (0.05, 0.05, 0.05))


# -- the skill ----------------------------------------------------------------------------------

@dataclass
class Frame:
    depth: np.ndarray
    color: np.ndarray
    intrinsics: Intrinsics
    T_world_camera: np.ndarray
    stamp: float


class PushingRobot:
    """Serves frames of the blue cup sliding 0.2 m/s along the table's x axis at 30 Hz."""

    def __init__(self, world):
        from hearth.benchmarks.tracking import PushScene
        from hearth.perception.camera import look_at
        self.K = Intrinsics.kinect(320, 240)
        self.T0 = world.T_world("blue_cup")
        self.T_wc = look_at(self.T0[:3, 3] + [0.2, -1.2, 0.6], self.T0[:3, 3])
        self.sim = PushScene(world, self.K, self.T_wc, np.random.default_rng(2), "blue_cup")
        self.i = 0

    def truth(self, i):
        T = self.T0.copy()
        T[0, 3] += 0.2 * i / 30
        return T

    def capture(self):
        r = self.sim.frame(self.truth(self.i))
        f = Frame(r.depth, r.color, self.K, self.T_wc, self.i / 30)
        self.i += 1
        return f


def test_track_object_skill_follows_the_cup_and_moves_it_in_the_map(demo_world):
    from hearth.skills.base import Bindings, Key, Literal
    from hearth.skills.tracking import TrackObject
    py_trees.blackboard.Blackboard.clear()
    robot = PushingRobot(demo_world)
    skill = TrackObject(bindings=Bindings({"object": Literal("blue_cup"), "frames": Literal(12)},
                                          {"pose": Key("/pose")}))
    skill.setup(world=demo_world, robot=robot)
    status = None
    for _ in range(20):
        status = skill.tick_once() or skill.status
        if skill.status != py_trees.common.Status.RUNNING:
            break
    assert skill.status == py_trees.common.Status.SUCCESS, skill.feedback_message
    truth = robot.truth(robot.i - 1)
    est = demo_world.T_world("blue_cup")
    assert np.linalg.norm(est[:2, 3] - truth[:2, 3]) < 0.02
    assert demo_world.history("blue_cup")[-1].source == "TrackObject"
    py_trees.blackboard.Blackboard.clear()
