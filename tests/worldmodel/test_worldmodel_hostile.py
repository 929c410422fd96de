"""World files from elsewhere: numbers, limits, paths, and saving only what loads back."""
from __future__ import annotations

import fcntl
import math
import os
import re
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree

from hearth.worldmodel import (
    Apartment, LargeObject, Model, ParkingPosition, Pose, Room, SmallObject, Visual, WorldError,
    load_world, save_world,
)
from hearth.worldmodel.io import MAX_DEPTH, SCHEMA_PATH, clean_stale_temporaries, parse_world
from hearth.worldmodel.nodes import (Handle, HistoryEntry, Joint, Knob, KnobState, LargeArticulatedObject,
                              Part, SearchStat, Surface, Switch)
from hearth.worldmodel.validate import MAX_COORD, MAX_ROOMS, MAX_TEXT_CHARS

DEMO = (Path(__file__).resolve().parents[2] / "data/demo_home/world.xml").read_text()


def validate(path):
    return subprocess.run([sys.executable, "-m", "hearth", "validate", str(path)],
                          capture_output=True, text=True)


def validate_here(path, capsys):
    """`hearth validate PATH` in this process: (exit status, stderr)."""
    from hearth.cli.main import main
    status = main(["validate", str(path)])
    return status, capsys.readouterr().err


def first(pattern, repl, text=DEMO):
    new, n = re.subn(pattern, repl, text, count=1)
    assert n == 1
    return new


def with_mesh(path):
    return first(r"(<model>)", rf'\1<mesh file="{path}" color="0.5 0.5 0.5"/>')


#: A small valid mesh (one triangle).
PLY = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
       b"0 0 0\n0.1 0 0\n0 0.1 0\n3 0 1 2\n")

HOSTILE = {
    "nan_pose": (first(r'<pose x="3" y="2.2"/>', '<pose x="NaN" y="2.2"/>'),
                 "'NaN' is not a finite number"),
    "inf_parking": (first(r'(<position id="[^"]*" x=")[^"]*"', r'\1INF"'),
                    "'INF' is not a finite number"),
    "nan_joint_limit": (first(r'upper="[^"]*"', 'upper="NaN"'), "'NaN' is not a finite number"),
    "nan_knob_angle": (first(r'(<knob [^>]*)angle="[^"]*"', r'\1angle="NaN"'),
                       "'NaN' is not a finite number"),
    "coordinate_1e308": (first(r'<pose x="3" y="2.2"/>', '<pose x="1e308" y="2.2"/>'),
                         "greater than the maximum value allowed ('10000')"),
    "size_overflowing_to_inf": (first(r'size="1.2 0.8 0.03"', 'size="1.2 1e999 0.03"'),
                                "'size'"),
    "knob_radius_zero": (first(r'(<knob [^>]*)radius="[^"]*"', r'\1radius="0"'),
                         "must be greater than '0'"),
    "handle_length_negative": (first(r'(<handle [^>]*)length="[^"]*"', r'\1length="-0.2"'),
                               "must be greater than '0'"),
    "colour_above_one": (first(r'color="0.55 0.38 0.22"', 'color="2 0.38 0.22"'), "'color'"),
    "mesh_up_and_out": (with_mesh("../../etc/passwd"), "leaves the world file's folder"),
    "mesh_absolute": (with_mesh("/etc/passwd"), "must be a path relative to the world file's"),
    "mesh_device": (with_mesh("/dev/zero"), "must be a path relative"),
    "mesh_directory": (with_mesh("sub"), "is not a regular file"),
    "mesh_fifo": (with_mesh("fifo.ply"), "is not a regular file"),
    "mesh_symlink_out": (with_mesh("escape.ply"), "leaves the world file's folder (through"),
    "pointcloud_proc": (first(r'(<room id="kitchen")', r'\1 pointcloud="../../../proc/self/environ"'),
                        "point cloud '../../../proc/self/environ' leaves"),
    "pointcloud_missing": (first(r'(<room id="kitchen")', r'\1 pointcloud="kitchen.pcd"'),
                           "is not in the world file's folder"),
    "attribute_10MB": (first(r'name="kitchen table"', 'name="' + "x" * 10_000_000 + '"'),
                       f"attribute name is 10000000 characters long (at most {MAX_TEXT_CHARS})"),
    "rooms_20000": (DEMO.replace("</apartment>", "".join(f'<room id="r{i}" name="r"/>'
                                                         for i in range(20000)) + "</apartment>"),
                    f"more than {MAX_ROOMS} rooms"),
    "parts_100_deep": (first(r"(</LargeArticulatedObject>)", "".join(
        f'<part id="p{i}" type="door"><joint type="fixed"/>' for i in range(100))
        + "</part>" * 100 + r"\1"), f"elements nest more than {MAX_DEPTH} levels deep"),
}


def _stats(*stats):
    return DEMO.replace("</apartment>", "<searchStats>" + "".join(
        f'<stat object="{o}" place="{p}" searched="{n}" found="{k}"/>' for o, p, n, k in stats)
        + "</searchStats></apartment>")


OBJ = b"v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n"

#: Issue 44: files inside the world's folder that escaped it or hung drawing, headers that
#: allocated gigabytes, and what the schema cannot say. (name -> world text, message; the
#: meshes are planted by ``world_dir``.)
HOSTILE_44 = {
    "obj_mtllib_etc_passwd": (with_mesh("passwd.obj"), "mesh file 'passwd.obj' names the "
                              "material library '../../../../../../etc/passwd', which leaves"),
    "obj_mtllib_fifo": (with_mesh("fifo_mtl.obj"), "names the material library 'pipe.mtl', "
                        "which is not a regular file"),
    "obj_texture_escape": (with_mesh("texture.obj"), "the texture '/etc/shadow', which is not a "
                           "path relative"),
    "obj_nan_vertex": (with_mesh("nan.obj"), "has 1 vertices that are not finite"),
    "ply_2e9_vertices": (with_mesh("huge.ply"), "declares 2000000000 vertex elements"),
    "ply_nan_vertex": (with_mesh("nan.ply"), "has 2 vertices that are not finite"),
    "gltf_mesh": (with_mesh("m.gltf"), "is not a mesh format Hearth reads"),
    "pointcloud_inf": (first(r'(<room id="kitchen")', r'\1 pointcloud="inf.ply"'),
                       "point cloud 'inf.ply' has 1 vertices that are not finite"),
    "attributes_100000": (first(r'(<room id="kitchen")', r'\1 ' + " ".join(
        f'a{i}="1"' for i in range(100_000))), "an element with more than 256 attributes"),
    "duplicate_surface_id": (first(r'(<surface id="top" sizeX="1.2")', r'<surface id="top" '
                                   r'sizeX="1" sizeY="1"><pose z="0.5"/></surface>\1'),
                             "kitchen_table: duplicate surface id 'top'"),
    "stat_found_above_searched": (_stats(("red_cup", "kitchen_table", 2, 5)),
                                  "found 5 times in 2 searches"),
    "stat_unknown_place": (_stats(("red_cup", "no_such_table", 2, 1)),
                           "no node 'no_such_table' in the map"),
    "stat_twice": (_stats(("red_cup", "kitchen_table", 2, 1), ("red_cup", "kitchen_table", 3, 1)),
                   "given twice"),
    # libxml2 quotes the text after an unfinished CDATA section, newlines and all
    "cdata_unfinished": (first(r'(<room id="kitchen")', r'<![CDATA[\n\n  </box>\n  \1'),
                         "XML syntax error: CData section not finished"),
}
HOSTILE.update(HOSTILE_44)


@pytest.fixture
def world_dir(tmp_path):
    """A folder with what hostile paths point at: a directory, a FIFO, a link out, a mesh,
    and meshes whose contents are hostile."""
    (tmp_path / "sub").mkdir()
    os.mkfifo(tmp_path / "fifo.ply")
    (tmp_path / "escape.ply").symlink_to("/etc/passwd")
    (tmp_path / "passwd.obj").write_bytes(b"mtllib ../../../../../../etc/passwd\n" + OBJ)
    os.mkfifo(tmp_path / "pipe.mtl")
    (tmp_path / "fifo_mtl.obj").write_bytes(b"mtllib pipe.mtl\n" + OBJ)
    (tmp_path / "tex.mtl").write_bytes(b"newmtl a\nmap_Kd -s 1 1 1 /etc/shadow\n")
    (tmp_path / "texture.obj").write_bytes(b"mtllib tex.mtl\n" + OBJ)
    (tmp_path / "nan.obj").write_bytes(b"v nan 0 0\n" + OBJ)
    (tmp_path / "huge.ply").write_bytes(PLY.replace(b"element vertex 3",
                                                    b"element vertex 2000000000"))
    (tmp_path / "nan.ply").write_bytes(PLY.replace(b"0 0 0\n0.1 0 0", b"nan 0 0\ninf 0 0"))
    (tmp_path / "inf.ply").write_bytes(PLY.replace(b"0 0 0\n", b"0 -inf 0\n"))
    (tmp_path / "m.gltf").write_bytes(b'{"buffers": [{"uri": "/etc/passwd"}]}')
    return tmp_path


def test_meshes_with_materials_and_textures_inside_the_folder_are_accepted(world_dir):
    (world_dir / "ok.mtl").write_bytes(b"newmtl a\nKd 1 0 0\nmap_Kd sub/../tex.png\n")
    (world_dir / "tex.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (world_dir / "ok.obj").write_bytes(b"mtllib ok.mtl\n" + OBJ)
    path = world_dir / "world.xml"
    path.write_text(with_mesh("ok.obj"))
    assert load_world(path).get("kitchen_table").model.visuals[0].file == "ok.obj"


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_world_is_refused_with_one_located_line_and_exit_2(case, world_dir, capsys):
    text, message = HOSTILE[case]
    path = world_dir / "world.xml"
    path.write_text(text)
    status, err = validate_here(path, capsys)
    assert status == 2 and "Traceback" not in err
    lines = err.strip().splitlines()
    assert lines and all(re.match(rf"{re.escape(str(path))}:[1-9]\d*: ", l) for l in lines), lines
    assert message in err


def test_the_cli_refuses_a_nan_pose_in_one_line(world_dir):
    path = world_dir / "world.xml"
    path.write_text(HOSTILE["nan_pose"][0])
    r = validate(path)
    assert (r.returncode, r.stderr) == (2, f"{path}:12: Element 'pose', attribute 'x': 'NaN' is "
                                           "not a finite number\n")


def test_mesh_inside_the_world_folder_is_accepted(tmp_path):
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "leg.ply").write_bytes(PLY)
    path = tmp_path / "world.xml"
    path.write_text(with_mesh("meshes/leg.ply"))
    assert load_world(path).get("kitchen_table").model.visuals[0].file == "meshes/leg.ply"


def test_a_world_parsed_from_bytes_cannot_name_files():
    with pytest.raises(WorldError, match="cannot be checked: the world was not loaded from a "
                                         "folder"):
        parse_world(with_mesh("meshes/leg.ply").encode())


@pytest.mark.parametrize("target", ["/dev/zero", "dir", "fifo"])
def test_a_world_path_that_is_no_regular_file_is_refused_before_reading(target, tmp_path):
    if target == "dir":
        path = tmp_path
    elif target == "fifo":
        path = tmp_path / "w.xml"
        os.mkfifo(path)
    else:
        path = Path(target)
    with pytest.raises(WorldError, match="not a regular file"):
        load_world(path)


def test_schema_bounds_are_the_semantic_checks_bounds():
    xsd = etree.parse(str(SCHEMA_PATH))
    ns = {"xs": "http://www.w3.org/2001/XMLSchema"}

    def facet(type_name, which):
        return float(xsd.find(f".//xs:simpleType[@name='{type_name}']//xs:{which}", ns).get("value"))
    assert facet("coord", "minInclusive") == -MAX_COORD
    assert facet("coord", "maxInclusive") == MAX_COORD
    assert facet("positive", "maxInclusive") == MAX_COORD
    assert facet("positive", "minExclusive") == 0
    for string_type in ("text", "id", "idref"):
        assert facet(string_type, "maxLength") == MAX_TEXT_CHARS


# -- saving ------------------------------------------------------------------------------------

def test_save_refuses_a_nan_pose_and_leaves_the_file_as_it_was(demo_world, tmp_path):
    target = tmp_path / "w.xml"
    save_world(demo_world, target)
    before = target.read_bytes()
    demo_world.get("kitchen_table").pose = Pose(math.nan, 0, 0)
    with pytest.raises(WorldError) as err:
        save_world(demo_world, target)
    assert str(err.value) == "node kitchen_table: not saved: pose x nan is not a finite number"
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.xml"]


@pytest.mark.parametrize("update, message", [
    (lambda w: w.set_pose("kitchen_table", Pose(math.nan, 0, 0)), "pose x: nan is not a finite"),
    (lambda w: w.set_pose("kitchen_table", Pose(0, 0, 0, 0, 0, math.inf)), "pose yaw: inf is not"),
    (lambda w: w.set_pose("kitchen_table", Pose(1e308, 0, 0)), "beyond +-10000"),
    (lambda w: w.move_object("blue_cup", "kitchen_table", Pose(0, math.nan, 0.8)), "pose y: nan"),
    (lambda w: w.set_knob_state("oven_knob_1", "off", angle=math.nan), "knob angle: nan"),
])
def test_an_update_with_a_non_finite_number_is_refused_and_changes_nothing(demo_world, update,
                                                                             message):
    before = (demo_world.get("kitchen_table").pose, len(demo_world.apartment.history))
    with pytest.raises(WorldError, match=re.escape(message)):
        update(demo_world)
    assert (demo_world.get("kitchen_table").pose, len(demo_world.apartment.history)) == before
    assert demo_world.get("oven_knob_1").angle == 0.0


@pytest.mark.parametrize("change, message", [
    (lambda w: setattr(w.get("oven_knob_1"), "radius", 0.0), "radius 0.0 is not positive"),
    (lambda w: setattr(w.get("oven_knob_1"), "angle", math.inf), "angle inf is not a finite"),
    (lambda w: setattr(w.get("kitchen_table"), "name", "tab\x00le"), "which XML cannot store"),
    (lambda w: setattr(w.get("kitchen"), "pointcloud", "/etc/passwd"), "must be a path relative"),
    (lambda w: setattr(w.get("kitchen"), "id", "1 kitchen"), "would not load back"),
])
def test_save_refuses_what_load_would_refuse(demo_world, tmp_path, change, message):
    change(demo_world)
    with pytest.raises(WorldError, match=re.escape(message)):
        save_world(demo_world, tmp_path / "w.xml")
    assert not (tmp_path / "w.xml").exists()


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o600])
def test_save_keeps_the_files_mode(demo_world, tmp_path, mode):
    target = tmp_path / "w.xml"
    save_world(demo_world, target)
    os.chmod(target, mode)
    save_world(demo_world, target)
    assert stat.S_IMODE(target.stat().st_mode) == mode


def test_a_new_file_gets_the_umasks_mode(demo_world, tmp_path):
    old = os.umask(0o027)
    try:
        save_world(demo_world, tmp_path / "w.xml")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "w.xml").stat().st_mode) == 0o640


def test_save_through_a_symlink_keeps_the_link_and_writes_its_target(demo_world, tmp_path):
    (tmp_path / "maps").mkdir()
    real = tmp_path / "maps" / "home.xml"
    save_world(demo_world, real)
    link = tmp_path / "world.xml"
    link.symlink_to(real)
    demo_world.set_joint_state("cupboard_door_left", 0.5, source="test")
    assert save_world(demo_world, link) == link
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert load_world(real).get("cupboard_door_left").joint.state == 0.5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["maps", "world.xml"]
    assert sorted(p.name for p in (tmp_path / "maps").iterdir()) == ["home.xml"]


def test_stale_temporaries_of_a_killed_save_are_removed_by_the_next(demo_world, tmp_path):
    target = tmp_path / "w.xml"
    save_world(demo_world, target)
    (tmp_path / ".w.xml.k1lled.tmp").write_bytes(b"<?xml half a map")
    (tmp_path / ".w.xml.2nd.tmp").write_bytes(b"")
    (tmp_path / ".other.xml.x.tmp").write_bytes(b"not ours")
    save_world(demo_world, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".other.xml.x.tmp", "w.xml"]


def test_a_temporary_held_by_a_save_in_progress_is_left_alone(demo_world, tmp_path):
    target = tmp_path / "w.xml"
    busy = tmp_path / ".w.xml.busy.tmp"
    busy.write_bytes(b"being written")
    with open(busy, "rb") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        save_world(demo_world, target)
        assert busy.exists()
    assert clean_stale_temporaries(target) == [busy]


# -- load(save(w)) == w over generated maps, edge values included ---------------------------------

edge = st.sampled_from([MAX_COORD, -MAX_COORD, 0.0, -0.0, 5e-324, 1e-300, 9999.999999999998,
                        math.pi, -math.pi, 0.1 + 0.2])
coord = st.one_of(edge, st.floats(-MAX_COORD, MAX_COORD, allow_nan=False))
pos_edge = st.sampled_from([MAX_COORD, 5e-324, 1e-300, 1e-9, 0.001])
positive = st.one_of(pos_edge, st.floats(1e-6, MAX_COORD, allow_nan=False).filter(lambda v: v > 0))
unit = st.one_of(st.sampled_from([0.0, 1.0, 5e-324]), st.floats(0, 1))
#: What a world file cannot hold: save must refuse it.
bad_number = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e5, MAX_COORD * 1.0000001])
ident = st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True)
word = st.from_regex(r"[a-zA-Z\u00e9\u4e2d][a-zA-Z0-9 \u00e9\u4e2d]{0,10}[a-z]", fullmatch=True)
poses = st.builds(Pose, coord, coord, coord, coord, coord, coord)
colours = st.tuples(unit, unit, unit)
visuals = st.one_of(
    st.builds(lambda p, s, c: Visual("box", p, size=s, color=c), poses,
              st.tuples(positive, positive, positive), colours),
    st.builds(lambda p, r, l, c: Visual("cylinder", p, radius=r, length=l, color=c), poses,
              positive, positive, colours),
    st.builds(lambda p, r, c, m: Visual("sphere", p, radius=r, color=c, material=m, name="n"),
              poses, positive, colours, st.sampled_from(["matte", "dark", "shiny", "glass"])))


@st.composite
def apartments(draw):
    ids = iter(draw(st.lists(ident, min_size=60, max_size=60, unique=True)))
    rooms = []
    for _ in range(draw(st.integers(1, 2))):
        objects = []
        for _ in range(draw(st.integers(0, 3))):
            oid = next(ids)
            parking = [ParkingPosition(f"{oid}_p{i}", Pose(draw(coord), draw(coord), 0, 0, 0,
                                                           draw(coord)))
                       for i in range(draw(st.integers(1, 2)))]
            smalls = [SmallObject(next(ids), draw(word), draw(poses),
                                  relation=draw(st.sampled_from(["on", "in", "under"])),
                                  color=draw(word), description=draw(word),
                                  model=Model(draw(st.lists(visuals, max_size=2))))
                      for _ in range(draw(st.integers(0, 2)))]
            kw = dict(name=draw(word), model=Model(draw(st.lists(visuals, max_size=2))),
                      parking=parking, default_parking=parking[0].id, static=draw(st.booleans()),
                      children=smalls, affordances=draw(st.lists(ident, max_size=2)),
                      surfaces=[Surface("top", draw(poses), draw(positive), draw(positive))])
            if draw(st.booleans()):
                lo = draw(coord)
                hi = draw(st.floats(lo, MAX_COORD))
                states = [KnobState("off", draw(coord)), KnobState("on", draw(coord))]
                knob = Knob(next(ids), draw(poses), states, "on", angle=draw(coord),
                            radius=draw(positive), depth=draw(positive), color=draw(colours),
                            marker_color=draw(colours), off_state=draw(st.sampled_from(["", "off"])))
                handle = Handle(next(ids), draw(poses), radius=draw(positive),
                                length=draw(positive), standoff=draw(positive), color=draw(colours))
                inner = Part(next(ids), "door", Joint("fixed", draw(poses)))
                part = Part(next(ids), "door",
                            Joint(draw(st.sampled_from(["revolute", "prismatic"])), draw(poses),
                                  (draw(coord), draw(coord), 1.0), lo, hi, hi),
                            name=draw(word), model=Model(draw(st.lists(visuals, max_size=1))),
                            handles=[handle], knobs=[knob], parts=[inner])
                objects.append(LargeArticulatedObject(oid, draw(word), draw(poses), parts=[part],
                                                      **kw))
            else:
                objects.append(LargeObject(oid, draw(word), draw(poses), **kw))
        x0, y0 = draw(coord), draw(coord)
        bounds = (x0, y0, draw(st.floats(x0, MAX_COORD).filter(lambda v: v > x0)),
                  draw(st.floats(y0, MAX_COORD).filter(lambda v: v > y0))) \
            if x0 < MAX_COORD and y0 < MAX_COORD and draw(st.booleans()) else None
        switches = [Switch(next(ids), draw(st.sampled_from(["rotational", "prismatic"])),
                           draw(poses), draw(word), draw(st.booleans()))]
        rooms.append(Room(next(ids), draw(word), pose=draw(poses), bounds=bounds,
                          switches=switches, objects=objects))
    history = [HistoryEntry(draw(st.floats(0, 2e9)), "x", "pose", draw(word), draw(word), "t")]
    searched = draw(st.integers(0, 10**9))     # found <= searched, at a node of the map
    stats = [SearchStat("cup", rooms[0].id, searched, draw(st.integers(0, searched)))]
    lib = {"mug": Model(draw(st.lists(visuals, min_size=1, max_size=2)))}
    return Apartment("home", draw(word), rooms=rooms, library=lib, history=history,
                     search_stats=stats)


def _spoil(apartment, value, where):
    """Put a number a world file cannot hold somewhere in the map."""
    room = apartment.rooms[0]
    if where == "room pose":
        room.pose = Pose(value, 0, 0)
    elif where == "switch":
        room.switches[0].pose = Pose(0, value, 0)
    elif where == "history":
        apartment.history[0].time = value
    else:
        apartment.library["mug"].visuals[0].pose = Pose(0, 0, value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(apartments(), st.none() | st.tuples(bad_number, st.sampled_from(
    ["room pose", "switch", "history", "library"])))
def test_save_then_load_gives_the_same_map_or_save_refuses(tmp_path_factory, apartment, spoil):
    from hearth.worldmodel.world import World
    path = tmp_path_factory.mktemp("rt") / "w.xml"
    if spoil is not None:
        _spoil(apartment, *spoil)
        if spoil[1] == "history" and math.isfinite(spoil[0]):
            return  # any finite time is a time
    world = World(apartment)
    if spoil is None:
        save_world(world, path)
        assert load_world(path).apartment == apartment
    else:
        with pytest.raises(WorldError, match="not saved"):
            save_world(world, path)
        assert not path.exists()
