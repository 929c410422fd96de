"""Scenarios: a seed perturbs the truth reproducibly; files round-trip; create_adapter uses them."""
from __future__ import annotations

import json

import pytest

from hearth import robot
from hearth.robot.clock import SimClock
from hearth.robot.scenario import load_scenario, make_scenario, save_scenario


def _where(world):
    return {o.id: (world.parent(o.id).id, o.pose) for o in world.small_objects()}


def test_a_seed_moves_objects_sets_states_and_leaves_belief_and_input_alone(demo_world):
    before = _where(demo_world)
    sc = make_scenario(demo_world, seed=3)
    assert _where(demo_world) == before and _where(sc.belief) == before
    moved = [p for p in sc.perturbations if p["kind"] == "moved"]
    assert moved
    for m in moved:
        assert sc.truth.parent(m["object"]).id == m["to_parent"] != m["from_parent"]
    assert any(p["kind"] in ("joint", "knob") for p in sc.perturbations)
    assert any(p["kind"] in ("clutter", "occluder") for p in sc.perturbations)
    assert 0 < sc.localisation_error.planar_distance(sc.localisation_error.__class__()) <= 0.12
    assert make_scenario(demo_world, seed=3).perturbations == sc.perturbations
    assert make_scenario(demo_world, seed=4).perturbations != sc.perturbations


def test_scenario_directory_round_trips_and_drives_create_adapter(demo_world, tmp_path):
    sc = make_scenario(demo_world, seed=3)
    save_scenario(sc, tmp_path)
    assert {p.name for p in tmp_path.iterdir()} == {"belief.xml", "truth.xml", "scenario.json"}
    back = load_scenario(tmp_path)
    assert _where(back.truth) == _where(sc.truth) and _where(back.belief) == _where(sc.belief)
    assert back.start_pose.planar_distance(sc.start_pose) < 1e-9
    r = robot.create_adapter(world=demo_world, scenario=str(tmp_path), clock=SimClock())
    assert r.true_pose().planar_distance(sc.start_pose) < 1e-9
    assert r.localisation_error().planar_distance(sc.localisation_error) < 1e-9
    assert _where(r.truth) == _where(sc.truth)


def test_broken_scenarios_are_one_clear_line(demo_world, tmp_path):
    with pytest.raises(robot.RobotError, match="scenario.json is missing"):
        load_scenario(tmp_path)
    save_scenario(make_scenario(demo_world, seed=1), tmp_path)
    meta = json.loads((tmp_path / "scenario.json").read_text())
    (tmp_path / "scenario.json").write_text(json.dumps(dict(meta, version=99)))
    with pytest.raises(robot.RobotError) as err:
        load_scenario(tmp_path)
    assert str(err.value) == f"{tmp_path / 'scenario.json'}: unknown scenario version 99 (this Hearth reads 1)"
    (tmp_path / "scenario.json").write_text("{not json")
    with pytest.raises(robot.RobotError, match="corrupt scenario"):
        load_scenario(tmp_path)
