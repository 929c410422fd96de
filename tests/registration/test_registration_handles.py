"""Handle fine pose on synthetic views: a face, a round bar seen from the front."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.perception.errors import PerceptionError
from hearth.perception.handles import HandleConfig, estimate_handle, rotation_error_deg

R, LENGTH, STANDOFF = 0.01, 0.3, 0.05


def _view(visible_from=-0.15, visible_to=0.15, seed=0):
    """World = handle frame of the truth: face plane x = -STANDOFF (0.4 x 0.8 m), a vertical
    bar of radius R on the z axis. The camera at x = 1.2 sees the front half of the bar
    (as rays see it: evenly across its silhouette) between ``visible_from`` and ``visible_to``
    along z."""
    rng = np.random.default_rng(seed)
    y, z = np.meshgrid(np.arange(-0.2, 0.2, 0.002), np.arange(-0.4, 0.4, 0.002))
    face = np.stack([np.full(y.size, -STANDOFF), y.ravel(), z.ravel()], axis=1)
    face = face[~((np.abs(face[:, 1]) < R) & (np.abs(face[:, 2]) < LENGTH / 2))]
    yb, zb = np.meshgrid(np.arange(-R, R, 0.0015), np.linspace(visible_from, visible_to, 101))
    xb = np.sqrt(np.maximum(R ** 2 - yb ** 2, 0))
    bar = np.stack([xb.ravel(), yb.ravel(), zb.ravel()], axis=1)
    pts = np.concatenate([face, bar])
    return pts + rng.normal(0, 0.0008, pts.shape)


FACE = np.eye(4)
FACE[0, 3] = -STANDOFF                       # the face's outer surface, +x out of it


def _estimate(points, prior=np.eye(4), cfg=HandleConfig()):
    return estimate_handle(points, FACE, (0.2, 0.4), prior, R, LENGTH, STANDOFF,
                           np.array([1.2, 0.0, 0.0]), "h", cfg)


def test_a_fully_seen_bar_is_found_on_its_axis():
    est = _estimate(_view())
    assert np.linalg.norm(est.T_world_handle[:3, 3]) < 0.0015
    assert rotation_error_deg(est.T_world_handle, np.eye(4)) < 0.5
    assert est.standoff == pytest.approx(STANDOFF, abs=0.0015)
    assert not est.prior_used


def test_the_round_bar_correction_moves_the_centroid_back_to_the_axis():
    pts = _view()
    bar = pts[pts[:, 0] > -0.02]
    # Raw centroid sits ~pi/4 radius in front of the axis.
    assert bar[:, 0].mean() == pytest.approx(math.pi / 4 * R, abs=0.0015)
    assert abs(_estimate(pts).T_world_handle[0, 3]) < 0.0015


def test_a_bar_hidden_at_one_end_takes_its_centre_from_the_end_it_shows():
    pts = _view(visible_from=0.02, visible_to=0.15)       # the lower part hidden
    prior = np.eye(4)
    prior[:3, 3] = (0.003, -0.002, 0.012)                  # the registered model's guess
    est = _estimate(pts, prior)
    assert est.ends_seen == 1 and not est.prior_used
    assert np.linalg.norm(est.T_world_handle[:3, 3]) < 0.002


def test_a_bar_hidden_at_both_ends_takes_its_height_from_the_map():
    pts = _view(visible_from=-0.1, visible_to=0.1)
    prior = np.eye(4)
    prior[:3, 3] = (0.003, -0.002, 0.004)
    est = _estimate(pts, prior)
    assert est.prior_used and est.ends_seen == 0
    assert est.T_world_handle[2, 3] == pytest.approx(0.004, abs=5e-5)
    assert np.linalg.norm(est.T_world_handle[:2, 3]) < 0.002


def test_standoff_range_is_configurable_and_a_missing_bar_fails():
    pts = _view()
    with pytest.raises(PerceptionError, match="no handle"):
        _estimate(pts, cfg=HandleConfig(standoff_range=(0.07, 0.12)))
    face_only = pts[pts[:, 0] < -0.03]
    with pytest.raises(PerceptionError, match="no handle"):
        _estimate(face_only)
