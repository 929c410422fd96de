"""hearth.perception.mapping's registration on synthetic clouds (fast, no rendering)."""
from __future__ import annotations

import math

import numpy as np

from hearth.perception import mapping as pm


def _wall(x: float, facing: float = -1.0, y=(-1.5, 1.5), z=(0.2, 2.0), step=0.04):
    Y, Z = np.meshgrid(np.arange(*y, step), np.arange(*z, step))
    P = np.c_[np.full(Y.size, x), Y.ravel(), Z.ravel()]
    return P, np.tile([facing, 0.0, 0.0], (len(P), 1))


def _cloud(parts, T=np.eye(4)):
    P = np.vstack([p for p, _ in parts])
    N = np.vstack([n for _, n in parts])
    return pm.KeyframeCloud(P @ T[:3, :3].T + T[:3, 3], N @ T[:3, :3].T)


def test_icp_on_one_wall_corrects_across_it_and_keeps_the_prior_along_it():
    target = _cloud([_wall(2.0)])
    true = pm._planar(0.0, 0.0, 0.0)
    source = _cloud([_wall(2.0)], np.linalg.inv(true))
    prior = pm._planar(0.05, 0.10, 0.0)      # 5 cm off across the wall, 10 cm along it
    r = pm.register_pair(source, target, prior, pm.MotionPrior().information(prior))
    assert r.ok
    assert abs(r.T_target_source[0, 3]) < 0.01          # across: corrected by the points
    assert abs(r.T_target_source[1, 3] - 0.10) < 0.01   # along: nothing sees it, prior kept


def test_icp_in_a_corner_recovers_the_true_motion():
    target = _cloud([_wall(2.0), (np.c_[_wall(1.5)[0][:, [1, 0, 2]]],
                                  np.tile([0.0, -1.0, 0.0], (len(_wall(1.5)[0]), 1)))])
    true = pm._planar(0.3, -0.2, math.radians(8))
    source = _cloud([(target.points, target.normals)], np.linalg.inv(true))
    prior = pm._planar(0.33, -0.17, math.radians(6))
    r = pm.register_pair(source, target, prior, pm.MotionPrior().information(prior))
    assert r.ok
    err = np.linalg.inv(true) @ r.T_target_source
    assert np.hypot(err[0, 3], err[1, 3]) < 0.01 and abs(math.atan2(err[1, 0], err[0, 0])) < 0.005


def test_the_two_sides_of_a_wall_never_match():
    room_a = _cloud([_wall(2.0, facing=-1.0)])          # seen from x < 2
    room_b = _cloud([_wall(2.1, facing=+1.0)])          # its other side, seen from x > 2.1
    prior = np.eye(4)
    r = pm.register_pair(room_b, room_a, prior, pm.MotionPrior().information(prior))
    assert not r.ok and r.fitness == 0.0
