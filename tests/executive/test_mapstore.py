"""The belief map kept on disk: every change saved atomically, a second process starts from
what the first learned, history bounded, the shipped demo file never written."""
from __future__ import annotations

import pytest

from hearth.executive.mapstore import MapKeeper, map_path
from hearth import demo_world_path
from hearth.worldmodel import load_world


@pytest.fixture
def state(tmp_path, monkeypatch):
    monkeypatch.setenv("HEARTH_STATE_DIR", str(tmp_path / "state"))
    return tmp_path / "state"


def test_the_demo_home_is_kept_as_a_copy_and_its_shipped_file_is_never_written(state):
    before = demo_world_path().read_bytes()
    path = map_path(demo_world_path())
    assert path == state / "demo_home" / "world.xml" and path.exists()
    world = load_world(path)
    cup = world.small_objects()[0].id
    with MapKeeper(world, path):
        world.record_search(cup, world.parent(cup).id, found=True, source="test")
    assert demo_world_path().read_bytes() == before
    assert load_world(path).search_stats(cup)[world.parent(cup).id].found == 1


def test_a_second_process_starts_from_what_the_first_learned(tmp_path, state):
    path = map_path(demo_world_path(), map_out=tmp_path / "mine.xml")
    first = load_world(path)
    obj = first.small_objects()[0]
    other = next(o for o in first.large_objects() if o.surfaces and o.id != first.parent(obj.id).id)
    with MapKeeper(first, path) as keeper:
        first.move_object(obj.id, other.id, obj.pose, source="test")
        first.record_search(obj.id, other.id, found=True, source="test")
    assert keeper.saves >= 1 and keeper.error is None
    second = load_world(map_path(demo_world_path(), map_out=tmp_path / "mine.xml"))
    assert second.parent(obj.id).id == other.id
    assert second.search_stats(obj.id)[other.id].found == 1
    assert "parent" in [h.field for h in second.history(obj.id)]


def test_history_is_bounded_when_saved(tmp_path, state):
    path = map_path(demo_world_path(), map_out=tmp_path / "m.xml")
    world = load_world(path)
    knob = world.knobs()[0]
    names = [s.name for s in knob.states]
    with MapKeeper(world, path, max_history=50):
        for i in range(120):
            world.set_knob_state(knob.id, names[i % len(names)], source="test")
    assert len(load_world(path).history()) <= 50
