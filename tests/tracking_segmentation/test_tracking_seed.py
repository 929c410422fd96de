"""The particle tracker is reproducible from its own generator: NumPy's global generator
(which filterpy's resampler used to draw from) changes nothing."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.tracking import ParticleTracker, reference_from_view, scene_cloud, systematic_resample


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(0.0, 10.0), min_size=1, max_size=40).filter(lambda w: sum(w) > 1e-6),
       st.integers(1, 700), st.integers(0, 2**32 - 1))
def test_systematic_resampling_draws_each_particle_in_proportion_to_its_weight(weights, n, seed):
    w = np.array(weights)
    idx = systematic_resample(w, n, np.random.default_rng(seed))
    assert idx.shape == (n,) and idx.min() >= 0 and idx.max() < len(w)
    counts = np.bincount(idx, minlength=len(w))
    expected = n * w / w.sum()
    assert np.all(counts >= np.floor(expected - 1e-9)) and np.all(counts <= np.ceil(expected + 1e-9))
    assert np.all(counts[w == 0] == 0)


def _scene():
    from hearth import demo_world_path
    from hearth.benchmarks.tracking import PushScene, half_extents
    from hearth.worldmodel import load_world
    world = load_world(demo_world_path())
    K = Intrinsics.kinect(320, 240)
    T_cup = world.T_world("blue_cup")
    T_wc = look_at(T_cup[:3, 3] + [0.0, -1.1, 0.6], T_cup[:3, 3])
    sim = PushScene(world, K, T_wc, np.random.default_rng(0), "blue_cup")
    frames = []
    for i in range(4):
        T = T_cup.copy()
        T[0, 3] += 0.01 * i            # pushed 1 cm a frame
        frames.append(sim.frame(T))
    pts, cols = scene_cloud(frames[0].depth, frames[0].color, K, T_wc)
    ref = reference_from_view(pts, cols, T_cup, half_extents(world, "blue_cup"),
                              rng=np.random.default_rng(0))
    return ref, T_cup, K, T_wc, frames


def _track(scene, global_seed: int):
    ref, T_cup, K, T_wc, frames = scene
    np.random.seed(global_seed)
    tracker = ParticleTracker(ref, T_cup, rng=np.random.default_rng(7))
    out = []
    for r in frames[1:]:
        np.random.random(global_seed % 5 + 1)       # someone else drawing from the global generator
        est = tracker.update(r.depth, r.color, K, T_wc, 1 / 30)
        out.append((est.T_world_object, est.n_particles, tracker.particles.copy()))
    return out


def test_two_trackers_with_the_same_seed_agree_whatever_the_global_seed():
    scene = _scene()
    a, b = _track(scene, 1), _track(scene, 2024)
    for (Ta, na, pa), (Tb, nb, pb) in zip(a, b):
        assert na == nb
        assert np.array_equal(pa, pb)
        assert np.array_equal(Ta, Tb)
