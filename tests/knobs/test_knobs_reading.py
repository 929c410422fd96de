"""Knob detection and reading on rendered views of the demo oven, with tiny models trained
here (seconds) in a temporary model directory."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from sklearn.base import clone

from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.knob_data import KnobScenes
from hearth.perception.knobs import CalibratedThreshold, KnobPrior, KnobTemplates, knob_priors, snap_to_state
from hearth.skills.knob_models import TrainingConfig, load_or_train
from hearth.worldmodel import model_store

K = Intrinsics.kinect()


@pytest.fixture(scope="module")
def world():
    from hearth.worldmodel import load_world
    from tests.conftest import DEMO_WORLD
    return load_world(DEMO_WORLD)


@pytest.fixture(scope="module")
def model_dir(knob_model_dir, reader):
    return knob_model_dir


@pytest.fixture(scope="module")
def scenes(world):
    return KnobScenes(world)


def front_view(world, knob_id, distance=0.8, off_axis_deg=20.0, up_deg=15.0):
    """A camera ``distance`` m from a knob, turned ``off_axis_deg`` sideways and raised."""
    p = knob_priors(world, "oven")
    pr = next(x for x in p if x.knob_id == knob_id)
    T = pr.T_world_face()
    a, b = math.radians(off_axis_deg), math.radians(up_deg)
    d = np.array([math.sin(a) * math.cos(b), math.sin(b), math.cos(a) * math.cos(b)])
    eye = T[:3, 3] + distance * (T[:3, :3] @ d)
    return look_at(eye, T[:3, 3]), p


def test_knob_at_a_known_state_is_read_within_tolerance(world, reader, scenes):
    T_wc, priors = front_view(world, "oven_knob_2", 0.9, 25.0)
    k2 = world.get("oven_knob_2")
    angles = {p.knob_id: p.state_angles[0] for p in priors}
    angles["oven_knob_2"] = k2.state_angle("3")
    img = scenes.scene("oven", angles).render(K, T_wc).color
    r = {x.knob_id: x for x in reader.read(img, K, T_wc, priors)}["oven_knob_2"]
    assert r.found
    assert r.state == "3"
    assert abs(math.degrees(math.remainder(r.angle - angles["oven_knob_2"], 2 * math.pi))) < 10
    assert 0.5 <= r.confidence <= 1.0


def test_every_oven_knob_in_one_frame_is_read(world, reader, scenes):
    T_wc, priors = front_view(world, "oven_knob_2", 1.1, 10.0, 25.0)
    rng = np.random.default_rng(5)
    truth = {}
    angles = {}
    for p in priors:
        i = int(rng.integers(len(p.state_names)))
        truth[p.knob_id], angles[p.knob_id] = p.state_names[i], p.state_angles[i]
    img = scenes.scene("oven", angles).render(K, T_wc).color
    got = {r.knob_id: r.state for r in reader.read(img, K, T_wc, priors)}
    # tiny test models: a knob may be "unknown", never confidently wrong
    assert all(got[k] in (truth[k], "unknown") for k in truth), (got, truth)
    assert sum(got[k] == truth[k] for k in truth) >= 3, (got, truth)


def test_no_knob_in_the_region_gives_no_detection(world, reader, scenes):
    T_wc, priors = front_view(world, "oven_knob_3", 0.8, 30.0)
    angles = {p.knob_id: 0.0 for p in priors}
    img = scenes.scene("oven", angles, missing=("oven_knob_3",)).render(K, T_wc).color
    r = {x.knob_id: x for x in reader.read(img, K, T_wc, priors)}
    assert not r["oven_knob_3"].found
    assert r["oven_knob_3"].state == "unknown"
    assert r["oven_knob_2"].found   # its neighbour is still there


def test_a_knob_seen_edge_on_is_not_read(world, reader, scenes):
    T_wc, priors = front_view(world, "oven_knob_1", 1.0, 80.0, 0.0)
    img = scenes.scene("oven", {p.knob_id: 0.0 for p in priors}).render(K, T_wc).color
    r = {x.knob_id: x for x in reader.read(img, K, T_wc, priors)}["oven_knob_1"]
    assert r.state == "unknown" and "obliquely" in r.reason


def test_a_model_trained_with_another_configuration_is_stale(world, reader, model_dir):
    from hearth.perception.errors import PerceptionError
    other = TrainingConfig().tiny()
    other = type(other)(**{**other.__dict__, "validation_views": 81})
    with pytest.raises(PerceptionError, match="stale: trained with other training.validation_views"):
        load_or_train(world, other, directory=model_dir, retrain=False)
    # the current one loads from disk without retraining
    model_store.forget()
    _, info = load_or_train(world, TrainingConfig().tiny(), directory=model_dir, retrain=False)
    assert info.source == "disk"


def test_changing_a_trained_reader_field_makes_the_model_stale_and_a_read_time_one_does_not(
        world, reader, model_dir):
    from hearth.perception.errors import PerceptionError
    from hearth.perception.knobs import KnobConfig
    model_store.forget()
    with pytest.raises(PerceptionError, match="stale: trained with other reader.px_per_radius"):
        load_or_train(world, TrainingConfig().tiny(), KnobConfig(px_per_radius=14.0),
                      directory=model_dir, retrain=False)
    r, info = load_or_train(world, TrainingConfig().tiny(), KnobConfig(threshold=0.5, search_m=0.03),
                            directory=model_dir, retrain=False)
    assert info.source == "disk" and r.config.threshold == 0.5
    # with every gate it was calibrated with, of colour alone too: a reader rebuilt from its
    # state gates alone read without its half-turn gates
    for mine, stored in ((r, reader), (r.colour_gates, reader.colour_gates)):
        assert mine.config.threshold == 0.5
        assert stored.half_turn_gates is not None
        assert mine.half_turn_gates == stored.half_turn_gates
        assert mine.state_gate_very_hard.threshold_ == stored.state_gate_very_hard.threshold_
        assert mine.dot_gates == stored.dot_gates and mine.dot_rival_gates == stored.dot_rival_gates


def test_knob_config_fields_are_trained_unless_declared_read_time():
    from hearth.perception.knobs import KnobConfig
    assert set(KnobConfig().trained_fields()) == {"px_per_radius", "window_radii", "alpha_step_deg",
                                                  "theta_step_deg", "max_theta_deg"}
    from dataclasses import dataclass
    from hearth.perception.trained import read_time, trained_fields

    @dataclass(frozen=True)
    class Later:
        old: float = 1.0
        added_later: int = 3              # nobody decided: it invalidates models
        gain: float = read_time(0.5)
    assert trained_fields(Later()) == {"old": 1.0, "added_later": 3}


def test_estimators_have_the_scikit_learn_shape(world):
    from sklearn.exceptions import NotFittedError
    from hearth.perception.knob_training import shapes_of
    gate = CalibratedThreshold("fewest_errors")
    with pytest.raises(NotFittedError):
        gate.predict(np.zeros((3, 1)))
    assert clone(CalibratedThreshold(safety=2.0)).get_params()["safety"] == 2.0
    x = np.array([[0.1], [0.2], [0.7], [0.9]])
    assert gate.fit(x, [0, 0, 1, 1]) is gate and 0.2 < gate.threshold_ < 0.7
    assert list(gate.predict(x)) == [0, 0, 1, 1]
    strict = CalibratedThreshold("no_false_accepts", safety=1.25).fit(x, [0, 1, 0, 1])
    assert strict.threshold_ == pytest.approx(0.7 * 1.25) and list(strict.predict(x)) == [0, 0, 0, 1]
    tm = KnobTemplates(alpha_step_deg=30.0, theta_step_deg=35.0, max_theta_deg=70.0)
    assert clone(tm).get_params()["alpha_step_deg"] == 30.0
    shapes = shapes_of(world)
    assert tm.fit(shapes) is tm and set(tm.templates_) == {s.key for s in shapes}


def test_detector_predict_uses_the_calibrated_threshold(reader):
    """``predict`` answers what the reader uses: a region holds the knob when its fit scores
    over ``threshold_`` (calibrated on validation views)."""
    det = reader.detect_gate
    rng = np.random.default_rng(1)
    score = rng.uniform(0, 1, (200, 1))
    assert np.array_equal(det.predict(score), (score[:, 0] > det.threshold_).astype(int))
    import copy
    t = float(np.median(score))
    shifted = copy.deepcopy(det)
    shifted.threshold_ = t
    assert shifted.predict(score).sum() == int((score[:, 0] > t).sum()) == 100
    assert reader.detect_threshold == det.threshold_


PRIOR = KnobPrior("k", np.eye(4), 0.02, 0.02, tuple(f"s{i}" for i in range(9)),
                  tuple(-i * math.radians(270 / 8) for i in range(9)))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 8), st.floats(-0.45, 0.45))
def test_an_angle_within_half_a_step_snaps_to_its_state(i, frac):
    step = math.radians(270 / 8)
    state, conf = snap_to_state(PRIOR.state_angles[i] + frac * step, PRIOR)
    assert state == f"s{i}"
    assert conf == pytest.approx(1 - abs(frac) / 0.5, abs=1e-6)


def test_read_time_settings_do_not_make_the_model_stale(world, reader, model_dir):
    from hearth.perception.knobs import KnobConfig
    r, info = load_or_train(world, TrainingConfig().tiny(), KnobConfig(min_confidence=0.9),
                            directory=model_dir, retrain=False)
    assert info.source in ("memory", "disk")
    assert r.config.min_confidence == 0.9


def test_hearth_train_check_reports_a_missing_model(tmp_path, capsys):
    from hearth.cli.main import main
    assert main(["train", "knobs", "--check", "--model-dir", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "knob models for demo_home: missing" in out and "knobs-" in out


def test_the_canvas_turns_so_that_the_camera_is_up():
    from hearth.perception.knobs import rotate_xy
    pr = KnobPrior("k", np.eye(4), 0.02, 0.02, ("off",), (0.0,))
    for cam in ([0.4, 0.0, 0.8], [0.0, -0.5, 0.6], [-0.3, 0.3, 1.0]):
        T_wc = look_at(np.array(cam), np.array([0.0, 0.0, 0.02]))
        T_c, psi = pr.canvas_frame(T_wc)
        toward = np.array([cam[0], cam[1]]) / np.hypot(cam[0], cam[1])
        assert np.allclose(T_c[:2, 1], toward, atol=1e-9)       # canvas up = towards the camera
        assert np.allclose(T_c[:3, 2], [0, 0, 1])                 # same face plane
        # a marker at knob angle a shows at a - psi on the canvas
        a = 0.7
        marker = rotate_xy((0.0, 1.0), a)
        on_canvas = rotate_xy(marker, -psi)
        assert math.atan2(-on_canvas[0], on_canvas[1]) == pytest.approx(math.remainder(a - psi, 2 * math.pi))
    assert pr.canvas_frame(T_wc, aligned=False)[1] == 0.0


def test_a_knob_is_read_from_every_side(world, reader, scenes):
    """Seen 40 degrees off-axis from the left, right, above and below, the same knob gives the
    same state (the canvas turns with the view; the angle is given back in the knob's frame)."""
    pr = next(p for p in knob_priors(world, "oven") if p.knob_id == "oven_knob_3")
    priors = knob_priors(world, "oven")
    angles = {p.knob_id: p.state_angles[0] for p in priors}
    angles["oven_knob_3"] = pr.state_angles[4]
    T = pr.T_world_face()
    got = []
    for phi in (0, 90, 180, 270):
        a, f = math.radians(40), math.radians(phi)
        d = np.array([math.sin(a) * math.cos(f), math.sin(a) * math.sin(f), math.cos(a)])
        T_wc = look_at(T[:3, 3] + 0.8 * (T[:3, :3] @ d), T[:3, 3])
        img = scenes.scene("oven", angles).render(K, T_wc).color
        got.append({x.knob_id: x for x in reader.read(img, K, T_wc, [pr])}["oven_knob_3"].state)
    truth = pr.state_names[4]
    assert all(s in (truth, "unknown") for s in got), got
    assert sum(s == truth for s in got) >= 3, got


def test_the_detector_threshold_is_calibrated_on_validation_views(world, reader, scenes):
    """The stored reader carries the gates chosen on validation views; calibrating again on
    those readings gives them back, and an explicit threshold overrides the calibrated one."""
    from dataclasses import replace
    from hearth.perception.knob_data import render_views
    from hearth.perception.knob_training import calibrate, validation_readings
    from hearth.perception.knobs import KnobReader
    cfg = TrainingConfig().tiny()
    assert reader.config.threshold is None and hasattr(reader.detect_gate, "threshold_")
    views = render_views(world, 60, 777, replace(cfg.data, missing_rate=0.3), reader.config, scenes=scenes)
    readings = validation_readings(reader, views)
    assert len(readings) == 60 and sum(not r["present"] for r in readings) > 0
    again = calibrate(reader, readings, cfg)
    # the gate separates this set's regions with and without the knob at least as well as 0 does
    def errors(t):
        return sum((r["score"] > t) != (r["present"] and r["near"]) for r in readings
                   if r["found"] or not r["present"])
    assert errors(again.detect_threshold) <= errors(0.0)
    assert again.state_gate.validation_["negatives_passed"] == 0
    high = KnobReader(reader.templates, reader.detect_gate, reader.state_gate,
                      replace(reader.config, threshold=50.0))
    v = next(v for v in views if v.present)
    assert not high.read(v.image, v.K, v.T_world_camera, [v.believed])[0].found


def test_validation_views_read_alike_on_several_processes(world, reader, scenes):
    """Training reads its validation views on several processes: the readings (and so the
    gates) are those of one process, in the views' order."""
    from hearth.perception.knob_data import render_views
    from hearth.perception.knob_training import _read_views
    views = render_views(world, 40, 7, TrainingConfig().data, reader.config, scenes=scenes)
    one = _read_views(reader, views, jobs=1)
    two = _read_views(reader, views, jobs=2)
    assert one == two
    assert len(one[0]) == len(one[1]) == 40
    assert any(r["found"] for r in one[0]) and any(r["found"] for r in one[1])


def test_half_turns_get_a_gate_of_their_own_so_the_state_gate_need_not_cover_them(reader):
    """Validation readings where the confident wrong ones are half turns (their half-turn
    test negative) and the others wrong by little margin: the calibrated half-turn gate
    keeps the half turns out, so the state gate is set by the others and lets most right
    readings through; no wrong reading passes both gates."""
    from hearth.perception.knob_training import calibrate
    rng = np.random.default_rng(0)

    def reading(right, margin, half_turn, level=0):
        return dict(present=True, found=True, near=True, score=1.0, margin=margin, right=right,
                    off=False, half_turn=half_turn, level=level, hard=bool(level))
    rows = ([reading(True, m, h) for m, h in zip(rng.uniform(0.01, 0.2, 200), rng.uniform(0.3, 1.5, 200))]
            + [reading(False, m, h) for m, h in ((0.09, -0.6), (0.07, -0.3), (0.06, -1.1))]
            + [reading(False, m, None) for m in (0.01, 0.008)]
            + [reading(True, 0.1, 0.8, level=1) for _ in range(50)])
    cal = calibrate(reader, rows, TrainingConfig())
    assert cal.half_turn_gates[0] >= 0.0
    assert cal.margin_threshold_for(0) < 0.02          # not the half turns' 0.09 * 1.25
    passes = [r["margin"] > cal.margin_threshold_for(r["level"])
              and (r["half_turn"] is None or r["half_turn"] > cal.half_turn_gate_for(r["level"]))
              for r in rows]
    assert not any(p for p, r in zip(passes, rows) if not r["right"])
    assert sum(p for p, r in zip(passes, rows) if r["right"] and r["level"] == 0) > 150


def test_dot_readings_get_a_rival_gate_so_their_dot_gate_need_not_cover_its_mistakes(reader):
    """Validation readings of a round body's marker (``dot``) where the confident wrong ones
    are a dot read from a speck beside it (their comparison with the nearest other state,
    ``rival``, negative): the calibrated rival gate keeps them out, so the dot gate is set
    by the others and lets most right readings through; no wrong reading passes both, and
    the knobs without a marker reading keep gates of their own."""
    from hearth.perception.knob_training import calibrate
    rng = np.random.default_rng(1)

    def reading(right, margin, rival, dot=True):
        return dict(present=True, found=True, near=True, score=1.0, margin=margin, right=right,
                    off=False, half_turn=None, rival=rival, dot=dot, level=0, hard=False)
    rows = ([reading(True, m, v) for m, v in zip(rng.uniform(1.0, 8.0, 200), rng.uniform(0.1, 0.9, 200))]
            + [reading(False, m, v) for m, v in ((5.5, -0.4), (4.1, -0.1), (3.0, -0.3))]
            + [reading(False, m, v) for m, v in ((1.2, 0.4), (0.9, 0.2))]
            + [reading(True, 0.1, None, dot=False) for _ in range(50)])
    cal = calibrate(reader, rows, TrainingConfig())
    assert cal.half_turn_gate_for(0, dot=True) >= 0.0
    gate = cal.margin_threshold_for(0, dot=True)
    assert gate < 3.0                                   # not 2 x 5.5
    passes = [r["margin"] > gate and r["rival"] > cal.half_turn_gate_for(0, dot=True)
              for r in rows if r["dot"]]
    dots = [r for r in rows if r["dot"]]
    assert not any(p for p, r in zip(passes, dots) if not r["right"])
    assert sum(p for p, r in zip(passes, dots) if r["right"]) > 150
    assert cal.half_turn_gate_for(0) == -math.inf       # the other readings: no such gate


def test_readings_the_snap_check_refuses_do_not_set_the_gates_of_easier_views(reader):
    """Wrong validation readings whose angle lies between two states (the snap check refuses
    them whatever the gates) do not raise the state gate of the near and hard views, so the
    right readings there pass; at the very hard level they still count; and no wrong
    reading the snap check lets through passes the gates."""
    from hearth.perception.knob_training import calibrate
    rng = np.random.default_rng(2)
    max_snap = reader.config.max_snap

    def reading(right, margin, snap, level):
        return dict(present=True, found=True, near=True, score=1.0, margin=margin, right=right,
                    off=False, half_turn=None, level=level, hard=bool(level), snap=snap)
    rows = []
    for level in (0, 1, 2):
        rows += [reading(True, m, sn, level) for m, sn in zip(rng.uniform(0.01, 0.2, 60), rng.uniform(0, 0.6, 60))]
        rows += [reading(False, 0.15, 0.85, level), reading(False, 0.012, 0.3, level)]
    cal = calibrate(reader, rows, TrainingConfig())
    assert cal.margin_threshold_for(0) < 0.02 and cal.margin_threshold_for(1) < 0.02
    assert cal.margin_threshold_for(2) > 0.15                 # the very hard level: it counts
    for r in rows:
        passes = r["margin"] > cal.margin_threshold_for(r["level"]) and r["snap"] <= max_snap
        assert r["right"] or not passes
    # as before (the field at 0): the refused readings set every level's gate
    old = calibrate(reader, rows, TrainingConfig(snap_free_levels=0))
    assert old.margin_threshold_for(0) > 0.15


@pytest.mark.parametrize("nearest", [True, False])
def test_a_level_with_few_readings_is_calibrated_with_its_nearest_level(reader, nearest):
    """Few validation readings of the near, clear views (level 0), many of level 1 (right
    but for two wrong by little margin) and a very hard level 2 whose small knobs are read
    wrong with confident margins and half turns (a hob seen from above): level 0 is
    calibrated with level 1, not with level 2's wrong readings, so its right readings and
    level 1's pass; level 2's gates keep its wrong readings out. Pooled with every harder
    level (``pool_nearest_levels`` False, as before) level 2's wrong readings set every gate."""
    from dataclasses import replace
    from hearth.perception.knob_training import calibrate
    rng = np.random.default_rng(1)

    def reading(right, margin, half_turn, level):
        return dict(present=True, found=True, near=True, score=1.0, margin=margin, right=right,
                    off=False, half_turn=half_turn, level=level, hard=bool(level))
    rows = ([reading(True, m, h, 0) for m, h in zip(rng.uniform(0.02, 0.2, 15), rng.uniform(0.3, 1.0, 15))]
            + [reading(True, m, h, 1) for m, h in zip(rng.uniform(0.02, 0.2, 100), rng.uniform(0.3, 1.0, 100))]
            + [reading(False, m, 0.1, 1) for m in (0.004, 0.003)]
            + [reading(True, m, h, 2) for m, h in zip(rng.uniform(0.02, 0.2, 100), rng.uniform(0.3, 1.0, 100))]
            + [reading(False, m, h, 2) for m, h in ((0.3, 0.95), (0.25, 0.9), (0.2, 0.85))])
    cal = calibrate(reader, rows, replace(TrainingConfig(), pool_nearest_levels=nearest))
    passes = [r["margin"] > cal.margin_threshold_for(r["level"])
              and (r["half_turn"] is None or r["half_turn"] > cal.half_turn_gate_for(r["level"]))
              for r in rows]
    assert not any(p for p, r in zip(passes, rows) if not r["right"])
    easy = sum(p for p, r in zip(passes, rows) if r["right"] and r["level"] < 2)
    if nearest:
        assert easy >= 110                          # of 115
    else:
        assert easy <= 20


def test_the_state_next_to_a_reading_is_the_nearest_other_state_on_its_side():
    import math
    from hearth.perception.knob_scoring import _next_state

    class Prior:
        symmetry = 1
        state_names = ("off", "1", "2", "3")
        state_angles = (0.0, math.radians(-20), math.radians(-40), math.radians(170))
    name, a = _next_state(Prior, math.radians(-12), "1")
    assert name == "off" and abs(a) < 1e-12
    name, a = _next_state(Prior, math.radians(-175), "3")       # across the wrap
    assert name == "2"
    Prior.symmetry = 2                                            # a bar: modulo half a turn
    name, a = _next_state(Prior, math.radians(-8), "3")          # 170 deg is -10 deg
    assert name == "off" and abs(a) < 1e-12


def test_allowed_angles_answer_as_allowed_angle_does_one_by_one():
    """The vector form the reader uses: the same answers for any travel and symmetry, at the
    travel's widened ends too."""
    import math
    from types import SimpleNamespace
    from hearth.perception.knobs import allowed_angle, allowed_angles
    rng = np.random.default_rng(3)
    seen = set()
    for sym in (1, 2, 4):
        for _ in range(50):
            lo = rng.uniform(-4, 4)
            hi = lo + rng.uniform(0, 6)
            prior = SimpleNamespace(travel=(lo, hi), symmetry=sym)
            ends = np.array([lo, hi]) + np.array([-1, 1]) * math.radians(15)
            a = np.concatenate([rng.uniform(-20, 20, 200), ends, ends + 1e-9, ends - 1e-9])
            got = allowed_angles(prior, a)
            assert got.tolist() == [allowed_angle(prior, x) for x in a]
            seen |= set(got.tolist())
    assert seen == {True, False}
    assert allowed_angles(SimpleNamespace(travel=None, symmetry=1), [0.0, 3.0]).all()


def test_the_half_turn_candidate_is_the_allowed_angle_nearest_the_half_turn():
    """A knob that turns one way only may stop short of its best coarse angle's half turn:
    the candidate checked is then the allowed angle nearest to it, within 45 degrees (home 4:
    states 0-223 degrees, the best coarse angle 61 with the knob at 222; the exact half turn,
    241, is not allowed), and none where no allowed angle comes that near."""
    import math
    from hearth.perception.knob_gates import _with_half_turn
    alphas = np.radians(np.arange(-180, 180, 5.0))
    travel = (alphas >= math.radians(-1)) & (alphas <= math.radians(224))   # 0..223 deg, one way
    allowed = travel | (alphas <= math.radians(-137))          # -180..-137 = 180..223 deg
    best = int(np.argmin(np.abs(alphas - math.radians(60))))
    got = _with_half_turn(alphas, [best], allowed)
    assert len(got) == 2 and round(math.degrees(alphas[got[1]])) == -140    # 220 deg, not 240
    assert _with_half_turn(alphas, [best, got[1]], allowed) == [best, got[1]]
    narrow = (alphas >= math.radians(-1)) & (alphas <= math.radians(60))
    assert _with_half_turn(alphas, [best], narrow) == [best]   # nothing within 45 degrees


def test_a_reading_the_depth_shows_flat_or_far_off_is_no_knob_whatever_its_fit():
    from hearth.perception.knobs import KnobConfig, not_there
    cfg = KnobConfig()
    assert not_there(dict(score=1.9, stands=0.93, offset=0.4), cfg) is None
    assert not_there(dict(score=1.9), cfg) is None                  # colour alone: no relief to see
    assert "relief" in not_there(dict(score=1.9, stands=0.12, offset=0.4), cfg)
    assert "search radii" in not_there(dict(score=1.9, stands=0.9, offset=2.7), cfg)
