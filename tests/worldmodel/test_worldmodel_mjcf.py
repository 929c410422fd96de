"""MJCF import (hearth/worldmodel/mjcf.py, `hearth home import-model`): a model's hinges become knobs
with their shape, range and an off state, or doors; slides drawers; handle geoms handles; the
world written validates; a broken file is one clear error naming it. The worlds converted from
public packages (tests/assets/) load and validate."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

from hearth.worldmodel.errors import WorldError  # noqa: E402
from hearth.worldmodel.io import load_world  # noqa: E402
from hearth.worldmodel.mjcf import import_model  # noqa: E402

ASSETS = Path(__file__).resolve().parents[1] / "assets"

OVEN = """<mujoco model="little_oven">
  <compiler angle="radian"/>
  <asset>
    <texture name="t" type="2d" builtin="checker" width="8" height="8"/>
    <texture name="t" type="2d" builtin="flat" width="8" height="8"/>
    <material name="steel" rgba="0.7 0.7 0.72 1" texture="t"/>
  </asset>
  <worldbody>
    <body name="oven" pos="0 0 0.45">
      <geom type="box" size="0.3 0.3 0.45" material="steel" group="1"/>
      <geom type="box" size="0.3 0.3 0.45" group="0" rgba="1 0 0 0.3"/>
      <body name="knob_left" pos="0.3 0.15 0.35">
        <joint name="kl" type="hinge" axis="1 0 0" range="0 3"/>
        <geom type="cylinder" size="0.02 0.01" pos="0.01 0 0" euler="0 1.5708 0" rgba="0.8 0.8 0.8 1" group="1"/>
        <geom type="box" size="0.002 0.003 0.012" pos="0.021 0 0.008" rgba="0.05 0.05 0.05 1" group="1"/>
      </body>
      <body name="knob_bar" pos="0.3 -0.15 0.35">
        <joint name="kb" type="hinge" axis="1 0 0" range="-1.5 0"/>
        <geom type="box" size="0.008 0.004 0.018" pos="0.008 0 0" rgba="0.1 0.1 0.1 1" group="1"/>
      </body>
      <body name="door" pos="0.3 -0.28 -0.1">
        <joint name="door_hinge" type="hinge" axis="0 0 1" range="-1.6 0"/>
        <geom type="box" size="0.01 0.28 0.3" pos="0.01 0.28 0" rgba="0.2 0.2 0.2 1" group="1"/>
        <geom name="door_handle" type="cylinder" size="0.008 0.2" pos="0.05 0.3 0.2" euler="1.5708 0 0" rgba="0.8 0.8 0.8 1" group="1"/>
      </body>
      <body name="tray" pos="0 0 -0.4">
        <joint name="tray_slide" type="slide" axis="1 0 0" range="0 0.4"/>
        <geom type="box" size="0.28 0.28 0.02" rgba="0.3 0.3 0.3 1" group="1"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def oven_world(tmp_path_factory):
    d = tmp_path_factory.mktemp("mjcf")
    (d / "little_oven.xml").write_text(OVEN)
    return load_world(import_model(d / "little_oven.xml", d / "out"))


def test_a_small_hinge_is_a_knob_with_its_range_an_off_state_and_a_marker(oven_world):
    knob = oven_world.get("little_oven_knob_left")
    assert knob.off == "off" and knob.state == "off" and knob.angle == 0.0
    angles = [s.angle for s in knob.states]
    assert len(angles) == 4 and angles[0] == 0.0 and math.isclose(angles[-1], 3.0)
    assert knob.turns == "counterclockwise"
    assert knob.radius == pytest.approx(0.02, abs=1e-3)
    assert knob.depth == pytest.approx(0.02 + 0.004, abs=2e-3)    # cylinder + marker on it
    assert [v.shape for v in knob.marker.visuals] == ["box"]
    assert [v.shape for v in knob.grip.visuals] == ["cylinder"]
    # its +z (the turning axis, out of the panel) is the appliance's front (+x)
    obj = oven_world.large_object_of(knob.id)
    z_world = oven_world.T_world(knob.id)[:3, 2]
    assert float(z_world @ oven_world.T_world(obj.id)[:3, 0]) == pytest.approx(1.0, abs=1e-6)


def test_a_bar_knob_without_a_marker_is_symmetric_and_turns_the_way_its_range_goes(oven_world):
    knob = oven_world.get("little_oven_knob_bar")
    assert knob.marker is None and knob.symmetry == 2
    assert knob.turns == "clockwise" and math.isclose(knob.states[-1].angle, -1.5)
    assert oven_world.get("little_oven_knob_left").symmetry == 1      # its marker breaks it


def test_large_hinges_are_doors_slides_drawers_and_handle_geoms_handles(oven_world):
    obj = oven_world.get("little_oven")
    kinds = {p.id: (p.type, p.joint.type, p.joint.lower, p.joint.upper) for p in obj.parts}
    assert kinds["little_oven_door"] == ("door", "revolute", -1.6, 0.0)
    assert kinds["little_oven_tray"][:2] == ("drawer", "prismatic")
    door = next(p for p in obj.parts if p.type == "door")
    [handle] = door.handles
    assert handle.length == pytest.approx(0.4, abs=0.01) and handle.radius == pytest.approx(0.008, abs=1e-3)
    # collision geoms (group 0, see-through) are left out: the body's one visual box stays
    assert [v.shape for v in obj.model.visuals] == ["box"]


def test_the_appliance_stands_in_a_kitchen_with_parking_in_front(oven_world):
    obj = oven_world.get("little_oven")
    T = oven_world.T_world(obj.id)
    for _pp, pose in oven_world.parking_positions(obj.id):
        to_robot = np.array([pose.x, pose.y]) - T[:2, 3]
        assert float(to_robot @ T[:2, 0]) > 0.8          # in front of its front
        assert oven_world.room_of(obj.id).id == "kitchen"


def test_a_model_mujoco_refuses_is_one_error_naming_the_file(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><geom type='box'/></worldbody>")
    with pytest.raises(WorldError) as err:
        import_model(bad, tmp_path / "out")
    assert str(bad) in str(err.value)


def test_the_cli_writes_a_world_and_says_which_knobs(tmp_path, capsys):
    from hearth.cli.main import main
    (tmp_path / "little_oven.xml").write_text(OVEN)
    assert main(["home", "import-model", str(tmp_path / "little_oven.xml"),
                 "--out", str(tmp_path / "w")]) == 0
    out = capsys.readouterr().out
    assert "2 knobs" in out and "knob little_oven_knob_left: off is 'off'" in out
    assert main(["home", "import-model", str(tmp_path / "little_oven.xml"), "--body", "nope",
                 "--out", str(tmp_path / "w2")]) == 2
    assert "no body 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("folder", ["libero_flat_stove", "metaworld_dial"])
def test_converted_public_assets_load_with_their_licence(folder):
    world = load_world(ASSETS / folder / "world.xml")
    [knob] = world.knobs()
    assert knob.off == "off" and len(knob.states) == 4
    assert "MIT License" in (ASSETS / folder / "LICENSE").read_text()
