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


# -- any world: one clear line for what cannot be used, scenarios that validate anywhere --------

_NO_SURFACE = """<?xml version='1.0' encoding='UTF-8'?>
<apartment id="flat" version="1">
  <room id="hall" name="hall" bounds="0 0 4 3">
    <LargeObject id="stool" type="stool">
      <pose x="2" y="1.5"/>
      <model><box size="0.4 0.4 0.5" color="0.5 0.4 0.3"><pose z="0.25"/></box>{mesh}</model>
      <parking default="p"><position id="p" x="-0.8" y="0" yaw="0"/></parking>
      <SmallObject id="key" type="key" color="grey">
        <pose z="0.5"/>
        <model><box size="0.05 0.02 0.01" color="0.5 0.5 0.5"/></model>
      </SmallObject>
    </LargeObject>
  </room>
</apartment>
"""


def test_a_world_with_a_small_object_and_no_surface_gets_a_scenario_and_a_note(tmp_path, capsys):
    from hearth.cli.main import main
    world = tmp_path / "w.xml"
    world.write_text(_NO_SURFACE.format(mesh=""))
    assert main(["scenario", "make", "--world", str(world), "--seed", "1",
                 "--out", str(tmp_path / "sc")]) == 0
    out = capsys.readouterr().out
    assert "note: no <surface> in the map: no small object moved, no clutter put down" in out
    sc = load_scenario(tmp_path / "sc")
    assert sc.truth.parent("key").id == "stool"


def test_a_world_the_scenario_tool_cannot_use_is_one_line_naming_the_node(tmp_path, capsys):
    from hearth.cli.main import main
    world = tmp_path / "empty.xml"
    world.write_text("<?xml version='1.0'?>\n<apartment id=\"flat\" version=\"1\">"
                     "<room id=\"hall\" name=\"hall\" bounds=\"0 0 4 3\"/></apartment>\n")
    assert main(["scenario", "make", "--world", str(world), "--out", str(tmp_path / "sc")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("node flat: the map has no parking position to start the robot at (add a "
                   "large object with <parking>; docs/world-format.md)")
    assert not (tmp_path / "sc").exists()


def test_a_scenario_of_a_generated_home_validates_where_its_meshes_are(tmp_path, capsys):
    from hearth.cli.main import main
    from hearth.worldmodel.homegen import make_home
    from hearth.worldmodel.io import validate_file
    home = make_home(2, tmp_path / "home")
    meshes = sorted(p.name for p in (tmp_path / "home" / "meshes").iterdir())
    assert meshes, "seed 2 has no mesh: pick a seed that has"
    out = tmp_path / "elsewhere" / "sc"
    assert main(["scenario", "make", "--world", str(home), "--seed", "4", "--out", str(out)]) == 0
    assert validate_file(out / "truth.xml") == [] and validate_file(out / "belief.xml") == []
    assert sorted(p.name for p in (out / "meshes").iterdir()) == meshes
    sc = load_scenario(out)
    r = robot.create_adapter(world=sc.belief, scenario=str(out), clock=SimClock())
    frame = r.capture()
    assert (frame.depth > 0).mean() > 0.5


def test_a_world_whose_meshes_leave_its_folder_is_refused_and_a_lost_mesh_is_named(tmp_path):
    """Mesh paths stay inside the world's folder (issue 19), so a scenario never has to
    reach outside it; a mesh that disappears before the scenario is saved is one line."""
    from hearth.worldmodel.errors import WorldError
    from hearth.worldmodel.io import load_world, validate_file
    (tmp_path / "shared").mkdir()
    (tmp_path / "flat" / "parts").mkdir(parents=True)
    ply = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n0.1 0 0\n0 0.1 0\n3 0 1 2\n")
    (tmp_path / "shared" / "leg.ply").write_text(ply)
    (tmp_path / "flat" / "parts" / "leg.ply").write_text(ply)
    outside = tmp_path / "flat" / "out.xml"
    outside.write_text(_NO_SURFACE.format(mesh='<mesh file="../shared/leg.ply"/>'))
    with pytest.raises(WorldError, match="leaves the world file's folder"):
        load_world(outside)
    world = tmp_path / "flat" / "w.xml"
    world.write_text(_NO_SURFACE.format(mesh='<mesh file="parts/leg.ply"/>'))
    sc, later = make_scenario(load_world(world), seed=0), make_scenario(load_world(world), seed=0)
    save_scenario(sc, tmp_path / "sc")
    assert validate_file(tmp_path / "sc" / "truth.xml") == []
    assert (tmp_path / "sc" / "parts" / "leg.ply").is_file()
    (tmp_path / "flat" / "parts" / "leg.ply").unlink()
    with pytest.raises(robot.RobotError) as err:
        save_scenario(later, tmp_path / "sc2")
    assert str(err.value) == (f"node stool: mesh file 'parts/leg.ply' not found (looked in "
                              f"{tmp_path / 'flat'})")


def test_what_a_scenario_puts_on_shelves_fits_under_the_shelf_above(tmp_path):
    from hearth.robot.scenario import ScenarioConfig, _headroom, _height, _surfaces
    from hearth.worldmodel.homegen import generate_home
    cfg = ScenarioConfig(moved_objects=(3, 3), clutter=(4, 4), occluders=(2, 2))
    shelves = 0
    for seed in range(6):
        world = generate_home(seed, mesh_dir=tmp_path)
        sc = make_scenario(world, seed, cfg)
        room = _headroom(sc.truth, _surfaces(sc.truth))
        for p in sc.perturbations:
            if p["kind"] not in ("moved", "clutter", "occluder"):
                continue
            oid = p["object"]
            parent = sc.truth.parent(oid)
            z = sc.truth.get(oid).pose.z
            surf = next(s for s in parent.surfaces if abs(s.pose.z - z) < 1e-6)
            assert _height(sc.truth, oid) <= room[(parent.id, surf.id)], (seed, p)
            shelves += room[(parent.id, surf.id)] < 1.0
    assert shelves > 0
