"""Small objects in drawers and sliding doors on one track (issue 43): a file that says so
loads and saves unchanged; one that gets it wrong is refused in one line naming the map node
(file:line from `hearth validate`, the node for a map in memory), exit status 2."""
from __future__ import annotations

import re

import pytest

from hearth.worldmodel import WorldError, load_world, save_world

WORLD = """<?xml version='1.0' encoding='UTF-8'?>
<apartment id="flat" version="1" name="flat">
  <room id="kitchen" name="kitchen" bounds="0 0 4 4">
    <LargeArticulatedObject id="counter" type="drawers" name="kitchen counter" affordances="container openable">
      <pose x="1.2" y="0.3"/>
      <model><box size="0.5 0.6 0.8" color="0.9 0.9 0.9" name="body"><pose z="0.4"/></box></model>
      <parking default="front"><position id="front" x="0.9" y="0" yaw="3.1416"/></parking>
      <part id="top_drawer" type="drawer" name="top drawer">
        <joint type="prismatic" axis="1 0 0" lower="0" upper="0.35" state="0"><origin x="0.26" z="0.62"/></joint>
        <model><box size="0.02 0.56 0.16" color="0.9 0.9 0.9" name="face"><pose z="0.08"/></box></model>
        <surface id="top_drawer_floor" sizeX="0.38" sizeY="0.5" relation="in"><pose x="-0.2" z="0.036"/></surface>
        <handle id="top_drawer_handle" radius="0.008" length="0.2" standoff="0.03"><pose x="0.04" z="0.11" roll="-1.5708"/></handle>
      </part>
      <SmallObject id="red_pill_box" type="pill box" color="red" relation="in" part="top_drawer">
        <pose x="-0.22" y="0.05" z="0.036"/>
        <model><box size="0.08 0.05 0.03" color="0.8 0.1 0.1"><pose z="0.015"/></box></model>
      </SmallObject>
    </LargeArticulatedObject>
    <LargeArticulatedObject id="wardrobe" type="wardrobe" name="hall wardrobe" affordances="container openable">
      <pose x="3" y="2"/>
      <model><box size="0.6 1.0 2.0" color="0.9 0.9 0.88" name="body"><pose z="1.0"/></box></model>
      <parking default="front"><position id="front" x="1.0" y="0" yaw="3.1416"/></parking>
      <part id="door_left" type="door" name="left sliding door" track="front">
        <joint type="prismatic" axis="0 -1 0" lower="0" upper="0.48" state="0"><origin x="0.33" y="0.25" z="0.06"/></joint>
        <model><box size="0.02 0.54 1.9" color="0.9 0.9 0.88" name="face"><pose z="0.95"/></box></model>
        <handle id="door_left_pull" kind="recessed" radius="0.015" length="0.14" standoff="0.01"><pose x="0.01" y="0.22" z="1.0"/></handle>
      </part>
      <part id="door_right" type="door" name="right sliding door" track="front">
        <joint type="prismatic" axis="0 1 0" lower="0" upper="0.48" state="0"><origin x="0.31" y="-0.25" z="0.06"/></joint>
        <model><box size="0.02 0.54 1.9" color="0.9 0.9 0.88" name="face"><pose z="0.95"/></box></model>
        <handle id="door_right_pull" kind="recessed" radius="0.015" length="0.14" standoff="0.01"><pose x="0.01" y="-0.22" z="1.0"/></handle>
      </part>
    </LargeArticulatedObject>
  </room>
</apartment>
"""


def _replace(text: str, old: str, new: str, nth: int = 0) -> str:
    """``text`` with the ``nth`` occurrence of ``old`` (0: the first) replaced."""
    i = -1
    for _ in range(nth + 1):
        i = text.index(old, i + 1)
    return text[:i] + new + text[i + len(old):]


#: spoiled file -> (line of the node named, the message)
BAD = {
    "object_in_an_unknown_part": (
        _replace(WORLD, 'part="top_drawer"', 'part="bottom_drawer"'), 14,
        "red_pill_box: part 'bottom_drawer' is not a part of its parent 'counter'"),
    "a_track_with_one_door": (
        _replace(WORLD, ' track="front">', '>'), 28,
        "wardrobe: part 'door_right' is the only door on track 'front' (doors on one track "
        "exclude each other: give the track two doors or drop it)"),
    "overlapping_sliding_doors": (
        _replace(WORLD, 'origin x="0.31" y="-0.25"', 'origin x="0.31" y="0.2"'), 28,
        "wardrobe: sliding doors 'door_left' and 'door_right' on track 'front' overlap by "
        "0.49 m of 0.54 m when closed (each must cover a span of its own)"),
    "a_hinged_door_on_a_track": (
        _replace(WORLD, 'type="prismatic" axis="0 1 0"', 'type="revolute" axis="0 0 1"'), 28,
        "part 'door_right': a part on a track (track 'front') slides: its joint must be prismatic"),
    "doors_on_one_track_sliding_across": (
        _replace(WORLD, 'axis="0 1 0"', 'axis="1 0 0"'), 28,
        "wardrobe: sliding doors 'door_left' and 'door_right' on track 'front' slide along "
        "different lines"),
}


def test_a_drawer_object_and_sliding_doors_load_and_save_unchanged(tmp_path):
    path = tmp_path / "world.xml"
    path.write_text(WORLD)
    world = load_world(path)
    assert world.get("red_pill_box").part == "top_drawer"
    assert [p.track for p in world.get("wardrobe").parts] == ["front", "front"]
    assert [h.handle_kind for p in world.get("wardrobe").parts for h in p.handles] == ["recessed"] * 2
    save_world(world, tmp_path / "again.xml")
    again = (tmp_path / "again.xml").read_text()
    assert 'part="top_drawer"' in again and again.count('track="front"') == 2
    assert load_world(tmp_path / "again.xml").get("red_pill_box").part == "top_drawer"


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_parts_and_tracks_are_refused_in_one_line_naming_the_node(case, tmp_path, capsys):
    from hearth.cli.main import main
    text, line, message = BAD[case]
    path = tmp_path / "world.xml"
    path.write_text(text)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.strip().splitlines() == [f"{path}:{line}: {message}"]


def test_a_map_in_memory_with_a_lone_door_on_a_track_is_not_saved(tmp_path):
    path = tmp_path / "world.xml"
    path.write_text(WORLD)
    world = load_world(path)
    world.get("door_left").track = "other"
    with pytest.raises(WorldError, match=re.escape(
            "wardrobe: part 'door_right' is the only door on track 'front'")):
        save_world(world, path)
    assert path.read_text() == WORLD          # nothing lost
