"""The semantic draft (issue 47 stages 2-3) on a small generated home.

The cloud here is a *perfect sensor's*: points sampled from the true meshes (1 cm apart, with
their faces' normals and colours), so the tests take seconds; the benchmark
(`hearth bench mapping_draft`) drafts from rendered, fused views."""
from __future__ import annotations


import numpy as np
import open3d as o3d
import pytest

from hearth.benchmarks import mapping_draft as md
from hearth.mapping.classify import LargeObjectClassifier, label, object_features, room_context
from hearth.mapping.truth import label_of, truth_objects
from hearth.perception.semantic_map import Fixture, ObjectDraft, articulate, draft_geometry
from hearth.worldmodel.draft import draft_world, rename
from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.homegen import HomeConfig, generate_home
from hearth.worldmodel.io import checked_xml, parse_world, to_xml
from hearth.worldmodel.world import World

SEED = 1


def perfect_cloud(world, spacing: float = 0.01):
    """Points on every true surface, ``spacing`` apart, with normals and colours."""
    from hearth.worldmodel.geometry import scene_meshes
    o3d.utility.random.seed(0)              # the same points every run
    P, N, C = [], [], []
    for lm in scene_meshes(world):
        m = lm.mesh
        m.compute_triangle_normals()
        n = max(20, int(m.get_surface_area() / spacing ** 2))
        pc = m.sample_points_uniformly(n, use_triangle_normal=True)
        P.append(np.asarray(pc.points))
        N.append(np.asarray(pc.normals))
        C.append(np.tile(lm.color, (n, 1)))
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.vstack(P)))
    pcd.normals = o3d.utility.Vector3dVector(np.vstack(N))
    pcd.colors = o3d.utility.Vector3dVector(np.vstack(C))
    return pcd.voxel_down_sample(spacing)


@pytest.fixture(scope="module")
def home(tmp_path_factory):
    world = generate_home(SEED, HomeConfig(rooms=(1, 1)),
                          mesh_dir=tmp_path_factory.mktemp("meshes"))
    pcd = perfect_cloud(world)
    P, N, C = np.asarray(pcd.points), np.asarray(pcd.normals), np.asarray(pcd.colors)
    return world, pcd, P, N, C, draft_geometry(P, N)


def test_the_draft_finds_the_room_as_its_rectangle(home):
    world, _, _, _, _, d = home
    assert len(d.rooms) == len(world.rooms)
    drafted = World(draft_world(d, parking=False).apartment)
    truth = truth_objects(world)
    assert truth
    ious = [max(md._iou(t, q) for q in md._room_polygons(drafted))
            for t in md._room_polygons(world)]
    assert min(ious) > 0.95


def test_the_draft_finds_every_large_object_with_its_box(home):
    world, _, _, _, _, d = home
    centres = np.array([(o.x, o.y) for o in d.objects])
    for t in truth_objects(world):
        err = np.min(np.linalg.norm(centres - t.centre, axis=1))
        assert err < 0.05, f"{t.id}: nearest drafted box {100 * err:.1f} cm away"


def test_the_draft_world_validates_with_types_parts_and_parking(home):
    """A classifier fitted on this home's own drafted objects (the plumbing, not its
    generalisation: that is the benchmark's) gives each object its true type in a world that
    validates, with doors or drawers where handles were seen and parking positions (an
    object with none is listed, with its type, as left out)."""
    world, _, P, N, C, d = home
    truth = truth_objects(world)
    X = [object_features(P, N, C, o, room_context(d.objects, o, d.rooms)) for o in d.objects]
    y = [label_of(o, truth) for o in d.objects]
    label(d, P, N, C, LargeObjectClassifier(n_estimators=50).fit(X, y))
    result = draft_world(d)
    data = checked_xml(result.apartment)            # raises if load_world would refuse it
    drafted = parse_world(data)
    # every object is in the file with its type, or listed with its type as left out
    left = [u.split("(", 1)[1].split(",", 1)[0] for u in result.unlabelled
            if "no parking position" in u]
    types = sorted([o.type for o in drafted.large_objects()] + left)
    assert types == sorted(t.type for t in truth), result.unlabelled
    assert len(left) <= 1
    for o in drafted.large_objects():
        assert o.parking and o.default_parking
    doors = [p for o in drafted.large_objects() for p in getattr(o, "parts", [])]
    true_parts = sum(len(t.handles) for t in truth)
    assert len(doors) >= 0.8 * true_parts
    s = md.score_draft(drafted, world)
    assert s["handles_found"] >= 0.5 * s["handles_true"]     # the rest: the benchmark's figure
    assert float(np.median(s["handle_mm"])) < 15.0


def _handle(u, v, vertical=True):
    return Fixture("handle", 0, np.zeros(3), u, v, 0.2, 0.02, 0.04, vertical)


def test_a_door_is_hinged_on_the_edge_away_from_its_handle():
    one = ObjectDraft(0, 0, 0, 0, 0.5, 0.6, 0.0, 0.9, np.arange(1), type="cupboard",
                      fixtures=[_handle(-0.25, 0.6)])
    assert [(p.kind, p.hinge) for p in articulate(one)] == [("door", "+y")]
    two = ObjectDraft(0, 0, 0, 0, 0.5, 1.0, 0.0, 0.9, np.arange(1), type="wardrobe",
                      fixtures=[_handle(-0.05, 1.0), _handle(0.05, 1.0)])
    parts = articulate(two)
    assert [(p.hinge, round(p.y0, 2), round(p.y1, 2)) for p in parts] == \
        [("-y", -0.5, 0.0), ("+y", 0.0, 0.5)]     # each hinged at its outer edge


def test_horizontal_handles_give_a_drawer_unit_its_drawers_and_an_oven_a_bottom_hinge():
    unit = ObjectDraft(0, 0, 0, 0, 0.5, 0.6, 0.0, 0.9, np.arange(1), type="drawers",
                       fixtures=[_handle(0, 0.2, False), _handle(0, 0.5, False),
                                 _handle(0, 0.8, False)])
    parts = articulate(unit)
    assert [p.kind for p in parts] == ["drawer"] * 3
    assert parts[0].z1 == pytest.approx(0.35) and parts[-1].z1 == pytest.approx(0.9)
    oven = ObjectDraft(0, 0, 0, 0, 0.6, 0.6, 0.0, 0.9, np.arange(1), type="oven",
                       fixtures=[_handle(0, 0.7, False)])
    assert [(p.kind, p.hinge) for p in articulate(oven)] == [("door", "bottom")]


def test_rename_updates_the_node_and_every_reference(home):
    world, _, P, N, C, d = home
    for o in d.objects:
        o.type = o.type or "cupboard"
        o.parts = articulate(o)
    data = to_xml(draft_world(d).apartment)
    drafted = parse_world(data)
    old = next(o for o in drafted.large_objects() if o.parts)
    new_data, changed = rename(data, old.id, "pantry")
    renamed = parse_world(new_data)
    node = next(o for o in renamed.large_objects() if o.id == "pantry")
    assert changed > 3
    assert node.default_parking.startswith("pantry_")
    assert all(p.id.startswith("pantry_") for p in node.parts)
    assert not any(o.id == old.id for o in renamed.large_objects())
    with pytest.raises(WorldError, match="already there"):
        rename(new_data, "pantry", renamed.rooms[0].id)
    with pytest.raises(WorldError, match="no node"):
        rename(new_data, old.id, "x")


def test_hearth_map_draft_writes_a_world_its_picture_and_what_it_could_not_label(
        home, tmp_path, monkeypatch, capsys):
    from hearth.cli.main import main
    _, pcd, *_ = home
    (tmp_path / "map" / "fused").mkdir(parents=True)
    o3d.io.write_point_cloud(str(tmp_path / "map" / "fused" / "map.ply"), pcd)
    monkeypatch.setenv("HEARTH_MODEL_DIR", str(tmp_path / "models"))   # no classifier there
    out = tmp_path / "draft"
    assert main(["map", "draft", str(tmp_path / "map"), "--out", str(out)]) == 0
    parse_world((out / "world.xml").read_bytes(), base_dir=out)
    assert (out / "draft.png").stat().st_size > 1000
    assert "no object types" in (out / "unlabelled.txt").read_text()
    capsys.readouterr()
    assert main(["map", "draft", str(tmp_path / "nowhere"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no fused map" in err[0]


def _parked(objects) -> dict:
    """Type -> parking position ids of the drafted world of one 4 m x 4 m room."""
    from hearth.perception.semantic_map import Draft, RoomDraft
    room = RoomDraft(0.0, 0.0, 0.0, 4.0, 4.0, 16.0)
    result = draft_world(Draft([room], objects))
    checked_xml(result.apartment)
    return {o.type: [p.id for p in o.parking] for r in result.apartment.rooms
            for o in r.objects}


def test_a_chair_whose_guessed_front_faces_its_table_is_parked_behind_it():
    import math
    table = ObjectDraft(0, 0.0, 0.0, 0.0, 1.2, 0.8, 0.0, 0.75, np.arange(1), type="table",
                        confidence=0.9)
    # the chair's +x (its guessed front) points at the table, 0.15 m away
    chair = ObjectDraft(0, 0.0, 0.75, -math.pi / 2, 0.45, 0.45, 0.0, 0.9, np.arange(1),
                        type="chair", confidence=0.9)
    parked = _parked([table, chair])
    assert parked["chair"] and not any(p.endswith("_front") for p in parked["chair"])
    assert any(p.endswith("_back") for p in parked["chair"])


def test_a_bookshelf_whose_guessed_front_is_its_narrow_end_is_parked_at_its_long_side():
    import math
    # 0.9 m long against the north wall in its west corner, its +x (turned by pi) at the
    # west wall: no parking in front fits; its object +y is the room's -y, into the room
    shelf = ObjectDraft(0, -1.5, 1.83, math.pi, 0.9, 0.3, 0.0, 1.6, np.arange(1),
                        type="bookshelf", confidence=0.9, wall_distance=0.02)
    parked = _parked([shelf])
    assert parked["bookshelf"] and all(p.startswith("bookshelf_1_side_left")
                                       for p in parked["bookshelf"])
