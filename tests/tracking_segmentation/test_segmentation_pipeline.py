"""Semantic segmentation: patches and their features, the Potts MRF, the forest in
scikit-learn shape, ground truth from the map, the trained pipeline on held-out rooms, and
model storage (stale models retrain)."""
from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone

from hearth.perception.camera import Intrinsics
from hearth.perception.errors import PerceptionError
from hearth.perception.segmentation import (
    LABELS, N_FEATURES, PatchClassifier, accuracy, extract_patches, potts_lbp, segment,
)

K = Intrinsics.kinect()


@pytest.fixture(scope="module")
def room_view():
    from hearth.skills.segmentation_model import render_random
    return render_random(424245, K)   # floor, walls, table, chair, cabinet, objects


def test_patches_cover_every_reading_and_are_nearly_pure(room_view):
    _, r, gt, T = room_view
    p = extract_patches(r.depth, r.color, K, T)
    assert p.features.shape == (len(p.sizes), N_FEATURES)
    assert np.all(np.isfinite(p.features))
    assert np.array_equal(p.ids >= 0, r.depth > 0)
    assert 200 < len(p.sizes) < 5000
    maj = p.majority(gt)
    ok = (p.ids >= 0) & (gt >= 0)
    assert (maj[p.ids[ok]] == gt[ok]).mean() > 0.9
    assert len(p.edges) > len(p.sizes)          # an adjacency graph, not a forest


def test_floor_patches_lie_flat_at_zero_height(room_view):
    _, r, gt, T = room_view
    p = extract_patches(r.depth, r.color, K, T)
    floor = p.majority(gt) == LABELS.index("floor")
    f = p.features[floor]
    assert np.median(np.abs(f[:, 3])) < 0.02               # centroid height
    assert np.median(f[:, 6]) < np.radians(10)              # normal angle to up
    wall = p.majority(gt) == LABELS.index("wall")
    assert abs(np.median(p.features[wall, 6]) - np.pi / 2) < np.radians(10)


def test_segment_refuses_an_empty_frame():
    clf = PatchClassifier(n_estimators=2).fit(np.random.default_rng(0).random((20, N_FEATURES)),
                                               np.arange(20) % 3)
    with pytest.raises(PerceptionError):
        segment(np.zeros((48, 64)), np.zeros((48, 64, 3), np.uint8), Intrinsics.kinect(64, 48),
                np.eye(4), clf)


def test_potts_lbp_without_coupling_is_the_unary_argmin():
    rng = np.random.default_rng(0)
    u = rng.random((30, 5))
    edges = np.array([[i, i + 1] for i in range(29)])
    assert np.array_equal(potts_lbp(u, edges, np.zeros(29)), u.argmin(axis=1))


def test_potts_lbp_smooths_a_lone_disagreeing_node():
    u = np.tile([0.0, 1.0], (9, 1))
    u[4] = [0.6, 0.4]                         # mildly prefers label 1, its neighbours label 0
    edges = np.array([[i, i + 1] for i in range(8)])
    assert potts_lbp(u, edges, np.full(8, 0.5)).tolist() == [0] * 9
    u[4] = [1.0, 0.0]                         # strongly prefers 1: stays
    assert potts_lbp(u, edges, np.full(8, 0.2))[4] == 1


def test_patch_classifier_has_scikit_learn_estimator_shape():
    rng = np.random.default_rng(0)
    X, y = rng.random((60, N_FEATURES)), np.array([0, 1, 3] * 20)
    X[:, 3] += y                               # learnable
    clf = PatchClassifier(n_estimators=5, random_state=0)
    assert clone(clf).get_params() == clf.get_params()
    from sklearn.exceptions import NotFittedError
    for method in (clf.predict_proba, clf.predict):
        with pytest.raises(NotFittedError):
            method(X)                          # predict never trains
    assert clf.fit(X, y) is clf
    p = clf.predict_proba(X)
    assert p.shape == (60, len(LABELS))        # a column for every label, seen or not
    assert np.allclose(p[:, [2, 4, 5, 6, 7]], 0)
    assert (clf.predict(X) == y).mean() > 0.9
    with pytest.raises(ValueError):
        clf.fit(X[:, :5], y)


def test_ground_truth_classes_come_from_the_map(demo_world):
    from hearth.perception.camera import look_at
    from hearth.perception.render import Scene
    from hearth.skills.segmentation_model import ground_truth
    from hearth.worldmodel.geometry import scene_meshes
    T = look_at((3.0, 0.9, 1.4), (3.0, 2.6, 0.6))
    r = Scene(scene_meshes(demo_world)).render(K, T)
    gt = ground_truth(demo_world, r)
    for node, label in (("kitchen_table", "table"), ("blue_cup", "object"), ("chair", "chair"),
                        ("oven", "cabinet")):
        m = r.owner_mask([node])
        if m.any():
            assert (gt[m] == LABELS.index(label)).all(), node
    assert LABELS.index("floor") in gt and LABELS.index("wall") in gt


def test_trained_pipeline_labels_held_out_rooms(small_forest):
    from hearth.skills.segmentation_model import render_random
    right, total = 0, 0
    for seed in (5151, 5152):
        _, r, gt, T = render_random(seed, K)
        seg = segment(r.depth, r.color, K, T, small_forest)
        assert seg.labels.shape == gt.shape
        a = accuracy(seg.labels, gt)
        right, total = right + a["right"], total + a["total"]
        assert a["per_class"]["floor"] > 0.9
    per = right[total > 0] / total[total > 0]
    assert right.sum() / total.sum() > 0.85     # global accuracy
    assert per.mean() > 0.6                     # a small forest; the benchmark uses the full one


def test_model_is_stored_with_its_configuration_and_retrained_when_stale(tmp_path, monkeypatch):
    """A trained over-segmentation field (cell_px) makes the stored forest stale; an MRF weight
    (read-time) does not."""
    from hearth.perception.segmentation import SegmentationConfig
    from hearth.skills import segmentation_model as sm
    from hearth.worldmodel import model_store
    tiny = sm.TrainingConfig(frames=2, n_estimators=3, seed=5, homes=1, views_per_home=1)
    calls = []
    real = sm.train
    monkeypatch.setattr(sm, "train", lambda cfg, seg, progress=None: calls.append(cfg) or real(cfg, seg))
    a, info = sm.get(tiny, SegmentationConfig(), tmp_path)
    assert info.source == "trained" and info.path == tmp_path / sm.MODEL_FILE
    assert info.path.exists() and len(calls) == 1
    model_store.forget()
    b, info = sm.get(tiny, SegmentationConfig(pair_weight=0.9, bp_iterations=5), tmp_path)
    assert info.source == "disk" and len(calls) == 1 and b.get_params() == a.get_params()
    stale = sm.check(tiny, SegmentationConfig(cell_px=12), tmp_path)
    assert not stale.ok and stale.reason == "stale: trained with other segmentation.cell_px"
    sm.get(tiny, SegmentationConfig(cell_px=12), tmp_path)
    assert len(calls) == 2
    model_store.forget()
    assert list(tmp_path.iterdir()) == [tmp_path / sm.MODEL_FILE]    # no temporary files left
