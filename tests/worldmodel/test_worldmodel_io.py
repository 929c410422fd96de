"""Loading, validating and saving world files."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hearth.worldmodel import (
    Apartment, LargeObject, Model, ParkingPosition, Pose, Room, SmallObject, Visual, WorldError,
    load_world, parse_world, save_world, to_xml, validate_file,
)
from hearth.worldmodel.demo_home import build


def hearth(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "hearth", *args], capture_output=True,
                          text=True, cwd=cwd)


def test_demo_home_file_matches_its_generator(demo_world_path):
    assert demo_world_path.read_bytes() == to_xml(build()), \
        "data/demo_home/world.xml is stale: run python -m hearth.worldmodel.demo_home"


def test_load_save_load_gives_an_equal_model(demo_world, tmp_path):
    out = tmp_path / "copy.xml"
    save_world(demo_world, out)
    again = load_world(out)
    assert again == demo_world
    assert again.apartment.rooms[0].objects[0] == demo_world.apartment.rooms[0].objects[0]


def test_history_survives_a_round_trip(demo_world, tmp_path):
    demo_world.move_object("blue_cup", "side_table", Pose(0.1, 0.0, 0.72), source="test")
    demo_world.set_joint_state("cupboard_door_left", 0.5, source="test")
    save_world(demo_world, tmp_path / "w.xml")
    again = load_world(tmp_path / "w.xml")
    assert [h.field for h in again.history("blue_cup")] == ["parent", "pose"]
    assert again.parent("blue_cup").id == "side_table"
    assert again.get("cupboard_door_left").joint.state == 0.5
    assert again == demo_world


def test_save_is_atomic_when_the_write_fails(demo_world, tmp_path, monkeypatch):
    target = tmp_path / "w.xml"
    save_world(demo_world, target)
    before = target.read_bytes()
    demo_world.move_object("blue_cup", "side_table", Pose(0.1, 0.0, 0.72))

    def boom(src, dst):
        raise OSError("disk full")
    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        save_world(demo_world, target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["w.xml"], "temporary file left behind"


finite = st.floats(min_value=-50, max_value=50, allow_nan=False, allow_infinity=False)
angle = st.floats(min_value=-3.1, max_value=3.1, allow_nan=False)
ident = st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True)
word = st.from_regex(r"[a-z]{1,8}", fullmatch=True)
poses = st.builds(Pose, finite, finite, finite, angle, angle, angle)
pos_len = st.floats(min_value=0.001, max_value=5, allow_nan=False)
colors = st.tuples(*[st.floats(0, 1, allow_nan=False)] * 3)
visuals = st.one_of(
    st.builds(lambda p, s, c: Visual("box", p, size=s, color=c), poses,
              st.tuples(pos_len, pos_len, pos_len), colors),
    st.builds(lambda p, r, l, c: Visual("cylinder", p, radius=r, length=l, color=c), poses,
              pos_len, pos_len, colors))


@st.composite
def apartments(draw):
    ids = iter(draw(st.lists(ident, min_size=40, max_size=40, unique=True)))
    rooms = []
    for _ in range(draw(st.integers(1, 3))):
        objects = []
        for _ in range(draw(st.integers(0, 3))):
            oid = next(ids)
            parking = [ParkingPosition(f"{oid}_p{i}", Pose(draw(finite), draw(finite), 0, 0, 0,
                                                           draw(angle)))
                       for i in range(draw(st.integers(1, 3)))]
            smalls = [SmallObject(next(ids), draw(word), draw(poses),
                                  relation=draw(st.sampled_from(["on", "in", "under"])),
                                  color=draw(word), description=draw(word),
                                  model=Model(draw(st.lists(visuals, max_size=2))))
                      for _ in range(draw(st.integers(0, 3)))]
            objects.append(LargeObject(oid, draw(word), draw(poses), name=draw(word),
                                       model=Model(draw(st.lists(visuals, max_size=3))),
                                       parking=parking, default_parking=parking[0].id,
                                       static=draw(st.booleans()), children=smalls))
        rooms.append(Room(next(ids), draw(word), pose=draw(poses), objects=objects))
    return Apartment("home", draw(word), rooms=rooms)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(apartments())
def test_any_generated_map_round_trips_exactly(apartment):
    world = parse_world(to_xml(apartment))
    assert world.apartment == apartment
    assert parse_world(to_xml(world.apartment)).apartment == apartment


def _write(tmp_path: Path, text: str, name="bad.xml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


DEMO_TEXT = (Path(__file__).resolve().parents[2] / "data/demo_home/world.xml").read_text()

BAD_FILES = {
    "external_entity": ('<?xml version="1.0"?>\n<!DOCTYPE apartment [\n'
                        '<!ENTITY xxe SYSTEM "file:///etc/passwd">]>\n'
                        '<apartment id="a" version="1"><room id="r" name="&xxe;"/></apartment>\n', 2),
    "billion_laughs": ('<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
                       ' <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">\n'
                       ' <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">\n'
                       ']>\n<apartment id="a" version="1"><room id="r" name="&lol3;"/></apartment>\n', 2),
    "duplicate_id": (DEMO_TEXT.replace('id="bowl"', 'id="red_cup"'), None),
    "joint_out_of_limits": (DEMO_TEXT.replace(
        'lower="0" upper="1.7453292519943295" state="0"',
        'lower="0" upper="1.7453292519943295" state="2.5"', 1), None),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_world_files_give_one_located_line_and_exit_2(case, tmp_path):
    text, line = BAD_FILES[case]
    path = _write(tmp_path, text)
    r = hearth("validate", str(path))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) >= 1 and "Traceback" not in r.stderr
    assert all(l.startswith(f"{path}:") for l in lines), r.stderr
    loc_line = int(lines[0].split(":")[1])
    if line is not None:
        assert loc_line == line
    else:
        assert loc_line > 1
    if case == "joint_out_of_limits":
        assert "outside its limits" in r.stderr
    if case == "duplicate_id":
        assert "red_cup" in r.stderr


def test_validate_demo_home_prints_nothing_and_exits_0(demo_world_path):
    r = hearth("validate", str(demo_world_path))
    assert (r.returncode, r.stdout, r.stderr) == (0, "", "")


def test_semantic_problems_each_name_their_line(tmp_path):
    text = DEMO_TEXT.replace('<parking default="cupboard_front">', '<parking default="nowhere">')
    text = text.replace('<state name="5"', '<state name="4"', 1)
    problems = validate_file(_write(tmp_path, text))
    msgs = [p.message for p in problems]
    assert any("default parking position 'nowhere'" in m for m in msgs)
    assert any("duplicate state names" in m for m in msgs)
    assert all(p.line and p.line > 1 for p in problems)


def test_knob_with_one_state_is_rejected(tmp_path):
    text = ('<?xml version="1.0"?>\n<apartment id="a" version="1">\n<room id="r" name="r">\n'
            '<LargeArticulatedObject id="o" type="oven"><parking default="p">'
            '<position id="p" x="1" y="0"/></parking>\n'
            '<knob id="k" state="off"><state name="off" angle="0"/></knob>\n'
            '</LargeArticulatedObject></room></apartment>\n')
    problems = validate_file(_write(tmp_path, text))
    assert [(p.line, "at least two discrete states" in p.message) for p in problems] == [(5, True)]


def test_unknown_version_and_syntax_errors_are_located(tmp_path):
    bad_version = DEMO_TEXT.replace('version="1"', 'version="7"', 1)
    with pytest.raises(WorldError, match="unsupported world format version"):
        load_world(_write(tmp_path, bad_version))
    broken = DEMO_TEXT.replace("</room>", "", 1)
    errs = validate_file(_write(tmp_path, broken, "broken.xml"))
    assert len(errs) == 1 and errs[0].line > 1 and "syntax" in errs[0].message


def test_missing_file_is_one_line(tmp_path):
    r = hearth("map", "show", str(tmp_path / "nope.xml"))
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no such file" in r.stderr
