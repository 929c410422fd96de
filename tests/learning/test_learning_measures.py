"""What the learned model's figures rest on (hearth/perception/object_learning.py): views of a
round object are registered to each other although it has no yaw to find, and the size is
measured from the faces, not from the sensor noise around them; and model sets
(hearth/worldmodel/learned.py) give a map learned models in place of drawn ones."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.perception.object_learning import LearnConfig, ObjectView, measure_size, register_views


def cylinder_view(rng, camera_xy, shift=(0.0, 0.0), radius=0.03, height=0.2, noise=0.001):
    """The half of a cylinder standing at the origin that a camera at ``camera_xy`` sees, its
    points put in the world through a believed pose off by ``shift`` (m)."""
    cam = np.array([*camera_xy, 0.4])
    a = rng.uniform(-math.pi, math.pi, 6000)
    z = rng.uniform(0.0, height, 6000)
    p = np.stack([radius * np.cos(a), radius * np.sin(a), z], axis=1)
    n = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    p = p[np.einsum("ij,ij->i", n, cam - p) > 0]
    p = p + rng.normal(0, noise, p.shape) + [shift[0], shift[1], 0.0]
    T = np.eye(4)
    T[:3, 3] = cam + [shift[0], shift[1], 0.0]
    return ObjectView(p, np.full((len(p), 3), 0.5), np.zeros((0, 3)), np.zeros((0, 3)), T, 0.0)


def test_views_of_a_round_object_are_registered_although_it_has_no_yaw():
    rng = np.random.default_rng(0)
    shifts = [(0.0, 0.0), (0.015, -0.01), (-0.012, 0.018), (0.02, 0.01)]
    views = [cylinder_view(rng, (math.cos(b), math.sin(b)), s)
             for b, s in zip(np.radians([0, 50, 100, 150]), shifts)]
    corrections = register_views(views, LearnConfig())
    for C, s in zip(corrections, shifts):
        moved = C[:2, :2] @ np.asarray(s) + C[:2, 3]     # where the shifted origin ends
        assert np.hypot(*moved) < 0.003, (s, moved)      # back on the first view's (0, 0)
        assert abs(math.degrees(math.atan2(C[1, 0], C[0, 0]))) < 1.0


def box_surface(rng, size, noise):
    """Points on the faces of a box standing at the origin (all but its base), noisy along
    each face's normal, with a few flying points well off it."""
    sx, sy, sz = size
    pts = []
    for axis, (a, b) in ((0, (sy, sz)), (1, (sx, sz))):
        for sign in (-1, 1):
            u, v = rng.uniform(-0.5, 0.5, 3000) * a, rng.uniform(0, 1, 3000) * b
            face = np.zeros((3000, 3))
            face[:, axis] = sign * size[axis] / 2 + rng.normal(0, noise, 3000)
            face[:, 1 - axis], face[:, 2] = u, v
            pts.append(face)
    top = np.stack([rng.uniform(-sx / 2, sx / 2, 3000), rng.uniform(-sy / 2, sy / 2, 3000),
                    sz + rng.normal(0, noise, 3000)], axis=1)
    flying = rng.uniform(-1, 1, (30, 3)) * [sx / 2 + 0.02, sy / 2 + 0.02, 0] + [0, 0, sz / 2]
    return np.vstack(pts + [top, flying])


def test_the_size_is_measured_at_the_faces_not_at_the_noise_around_them():
    rng = np.random.default_rng(1)
    size = (0.092, 0.052, 0.14)
    P = box_surface(rng, size, noise=0.002)
    got = np.array(measure_size(P))
    assert np.abs(got - size).max() < 0.002, got
    # the extents of the points (even trimmed) are 2-3 mm out on every side
    lo, hi = np.percentile(P, 0.5, axis=0), np.percentile(P, 99.5, axis=0)
    assert (hi - lo)[0] - size[0] > 0.004


def test_a_model_set_gives_a_map_learned_models_in_place_of_drawn_ones(tmp_path):
    from tests.conftest import DEMO_WORLD
    from hearth.worldmodel import load_world
    from hearth.worldmodel.errors import WorldError
    from hearth.worldmodel.geometry import small_object_meshes
    from hearth.worldmodel.learned import apply_model_set, write_model_set
    world = load_world(DEMO_WORLD)
    oid = sorted(o.id for o in world.small_objects())[0]
    V = np.array([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    T = np.eye(4)
    T[:3, 3] = (0.01, 0.0, 0.0)
    write_model_set(tmp_path / "set", {oid: [(V, F, (0.9, 0.1, 0.1), T)]},
                    {"other": "fewer than two views see it"})
    before = world.T_world(oid).copy()
    assert apply_model_set(world, tmp_path / "set") == [oid]
    (mesh,) = small_object_meshes(world, world.get(oid), T_world_object=np.eye(4))
    assert np.allclose(np.asarray(mesh.mesh.vertices).min(axis=0), [0.01, 0, 0], atol=1e-6)
    assert mesh.color == pytest.approx((0.9, 0.1, 0.1))
    assert np.allclose(world.T_world(oid), before)                # the object stays where it was
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "models.json").write_text("{not json")
    with pytest.raises(WorldError, match=r"bad/models.json: not a model set"):
        apply_model_set(world, tmp_path / "bad")
    with pytest.raises(WorldError, match="no model set here"):
        apply_model_set(world, tmp_path)


def test_a_case_with_drawn_models_keeps_its_key_and_one_with_learned_models_differs():
    import hashlib
    import json
    from dataclasses import asdict, replace

    from hearth.executive.scenarios import Case
    from hearth.executive.suite_worker import case_key
    c = Case("fetch_object", 3, world="home:1", target="blue_cup")
    old = {k: v for k, v in asdict(c).items() if k != "models"}
    assert case_key(c) == hashlib.sha256(json.dumps(old, sort_keys=True, default=str)
                                         .encode()).hexdigest()[:16]
    assert case_key(replace(c, models="/tmp/set")) != case_key(c)


def test_the_missions_bench_runs_fetch_cases_again_with_learned_models_and_compares(tmp_path,
                                                                                    monkeypatch):
    """--learned-models: each fetch case with the learned search order once more with the
    world's model set; the success with them over the success with the drawn ones."""
    from dataclasses import asdict
    import hearth.benchmarks.learning as learning
    from hearth.benchmarks.missions import learned_cases, learned_figures
    from hearth.executive.scenarios import Case
    from hearth.worldmodel.learned import write_model_set
    write_model_set(tmp_path, {}, {"jar": "fewer than two views see it"})
    monkeypatch.setattr(learning, "model_set_for", lambda spec, seed=0, progress=None: tmp_path)
    cases = [Case("fetch_object", s, learned=o, world="home:7", target=t)
             for s, t in ((0, "cup"), (1, "jar")) for o in (True, False)]
    cases.append(Case("turn_off_oven", 0, world="home:7", target="oven"))
    sets: dict = {}
    again = learned_cases(cases, 0, sets)
    assert [(c.target, c.learned, c.models) for c in again] == [("cup", True, str(tmp_path)),
                                                                ("jar", True, str(tmp_path))]

    def result(c, ok):
        return dict(asdict(c), outcome="succeeded" if ok else "failed", correct=ok,
                    reason="" if ok else "no jar at the 2 places searched", sim_time_s=1.0,
                    wall_time_s=1.0, positions_visited=1, target_type=c.target)
    results = [result(c, True) for c in cases if c.mission == "fetch_object"]
    results += [result(again[0], True), result(again[1], False)]
    got = learned_figures(results, sets)
    assert got["fetch_object"]["success_rate"] == 0.5
    assert got["fetch_object"]["drawn_success_rate"] == 1.0
    assert got["fetch_object"]["success_ratio"] == 0.5
    assert got["model_sets"]["home:7"]["not_learned"] == {"jar": "fewer than two views see it"}
