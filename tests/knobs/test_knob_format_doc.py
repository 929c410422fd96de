"""The knob designs docs/world-format.md shows load as written, and come back the same."""
from __future__ import annotations

import re
from pathlib import Path

from hearth import demo_world_path
from hearth.worldmodel.homegen_geometry import extrude, ply_bytes


def test_the_documented_knob_designs_load_and_round_trip(tmp_path):
    from hearth.worldmodel.io import load_world, to_xml
    doc = (Path(__file__).resolve().parents[2] / "docs" / "world-format.md").read_text()
    section = doc[doc.index("## Knobs"):doc.index("## What loading checks")]
    xml = re.search(r"```xml\n(.*?)```", section, re.S).group(1)
    assert xml.count("<knob ") >= 4
    world = demo_world_path().read_text()
    # the documented knobs on the demo oven, the pointer's mesh beside the world file
    at = world.index("<knob ")
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "knob-pointer.ply").write_bytes(ply_bytes(extrude(
        [(0.0, 0.0228), (-0.012, -0.004), (0.0, -0.014), (0.012, -0.004)], 0.004, 0.02)))
    (tmp_path / "meshes" / "knob-d.ply").write_bytes(ply_bytes(extrude(
        [(-0.01, -0.007), (0.01, -0.007), (0.014, 0.004), (0.0, 0.015), (-0.014, 0.004)], 0.001, 0.02)))
    (tmp_path / "world.xml").write_text(world[:at] + xml + world[at:])
    w = load_world(tmp_path / "world.xml")
    bar, tip, ptr = w.get("k_bar"), w.get("k_tip"), w.get("k_pointer")
    assert not w.get("k_plain").described
    assert bar.symmetry == 2 and bar.turns == "clockwise" and bar.grip.visuals[0].shape == "box"
    assert tip.marker.visuals[0].color == (0.85, 0.1, 0.1)
    assert ptr.base_fixed and ptr.grip.visuals[0].shape == "mesh"
    dial = w.get("k_dial")    # a dial ring: ticks on the fixed base, no marker, off mid-travel
    assert dial.base_fixed and dial.marker is None and len(dial.base.visuals) == 4
    assert dial.off == "standby" and [s.name for s in dial.states].index("standby") == 2
    (tmp_path / "again.xml").write_bytes(to_xml(w.apartment))
    again = load_world(tmp_path / "again.xml")
    for kid in ("k_plain", "k_bar", "k_tip", "k_pointer", "k_dial"):
        a, b = w.get(kid), again.get(kid)
        assert (a.base, a.grip, a.marker, a.symmetry, a.turns, a.base_fixed) == \
               (b.base, b.grip, b.marker, b.symmetry, b.turns, b.base_fixed)
