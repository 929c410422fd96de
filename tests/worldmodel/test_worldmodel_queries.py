"""Queries, updates with history, geometry and URDF import on the demo home."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from hearth.perception.camera import Intrinsics, look_at
from hearth.worldmodel import Pose, SmallObject, WorldError, load_world
from hearth.worldmodel.errors import UnknownNode
from hearth.worldmodel.geometry import node_mesh
from hearth.worldmodel.urdf import import_urdf


def test_find_blue_cup_by_words_not_the_red_one(demo_world):
    matches = demo_world.find("the blue cup")
    assert matches[0].node.id == "blue_cup"
    assert "red_cup" not in [m.node.id for m in matches]
    assert {m.node.id for m in demo_world.find("cups")} == {"blue_cup", "red_cup"}
    assert demo_world.find("purple elephant") == []


def test_parent_chain_room_and_parking_default_first(demo_world):
    assert [n.id for n in demo_world.chain("blue_cup")] == ["blue_cup", "kitchen_table", "kitchen"]
    assert demo_world.room_of("pill_box").id == "bathroom"
    parking = demo_world.parking_positions("blue_cup")
    assert parking[0][0].id == demo_world.get("kitchen_table").default_parking
    # The south parking position stands 1 m south of the table centre, facing north.
    pose = parking[0][1]
    assert (round(pose.x, 6), round(pose.y, 6), round(pose.yaw, 6)) == (3.0, 1.2, round(math.pi / 2, 6))


def test_cli_map_find_json_names_table_kitchen_and_parking():
    r = subprocess.run([sys.executable, "-m", "hearth", "map", "find",
                        "data/demo_home/world.xml", "blue", "cup", "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["parent"]["id"] == "kitchen_table"
    assert out["room"]["name"] == "kitchen"
    assert [p["id"] for p in out["parking_positions"]] == [
        "kitchen_table_south", "kitchen_table_north", "kitchen_table_west"]


def test_opening_a_door_moves_its_handle_about_the_hinge(demo_world):
    closed = demo_world.T_world("cupboard_handle_left")[:3, 3]
    hinge = demo_world.T_world("cupboard_door_left")[:3, 3]
    demo_world.set_joint_state("cupboard_door_left", math.radians(30))
    opened = demo_world.T_world("cupboard_handle_left")[:3, 3]
    # Same distance from the hinge, same height, swept by 30 degrees about the vertical.
    assert np.linalg.norm((closed - hinge)[:2]) == pytest.approx(np.linalg.norm((opened - hinge)[:2]))
    assert opened[2] == pytest.approx(closed[2])
    a, b = (closed - hinge)[:2], (opened - hinge)[:2]
    ang = math.degrees(math.acos(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)))
    assert ang == pytest.approx(30, abs=1e-6)


def test_drawer_moves_along_its_slide(demo_world):
    before = demo_world.T_world("drawer_1_handle")[:3, 3]
    demo_world.set_joint_state("drawer_1", 0.25)
    after = demo_world.T_world("drawer_1_handle")[:3, 3]
    assert np.linalg.norm(after - before) == pytest.approx(0.25)


def test_knob_angle_turns_its_frame(demo_world):
    k = demo_world.get("oven_knob_2")
    demo_world.set_knob_state("oven_knob_2", k.states[2].name)
    assert demo_world.get("oven_knob_2").angle == k.states[2].angle
    z_axis = demo_world.T_world("oven_knob_2")[:3, 2]
    # The oven faces -y (into the room): the knob's axis points the same way.
    assert z_axis == pytest.approx([0, -1, 0], abs=1e-9)


def test_frustum_sees_the_table_things_not_the_bathroom(demo_world):
    T = look_at([3.0, 1.2, 1.3], [3.0, 2.2, 0.75])
    seen = set(demo_world.in_frustum(T, Intrinsics.kinect()))
    assert {"kitchen_table", "blue_cup", "red_cup", "bowl", "sugar"} <= seen
    assert "pill_box" not in seen and "bathroom_cabinet" not in seen


def test_landmarks_are_the_static_large_objects(demo_world):
    ids = {o.id for o in demo_world.landmarks()}
    assert "chair" not in ids and {"kitchen_table", "oven", "cupboard"} <= ids


def test_updates_record_history_and_notify(demo_world):
    heard = []
    unsubscribe = demo_world.subscribe(heard.append)
    demo_world.move_object("blue_cup", "side_table", Pose(0.1, 0, 0.72), source="DetectObject")
    demo_world.set_knob_state("oven_knob_1", "2", source="ReadKnobs")
    unsubscribe()
    demo_world.set_joint_state("fridge_door", 0.3)
    assert [(c.node, c.field) for c in heard] == [
        ("blue_cup", "parent"), ("blue_cup", "pose"), ("oven_knob_1", "knob.state"),
        ("oven_knob_1", "knob.angle")]
    hist = demo_world.history("blue_cup")
    assert (hist[0].old, hist[0].new, hist[0].source) == ("kitchen_table", "side_table", "DetectObject")
    assert demo_world.describe_location("blue_cup") == "on the side table"
    assert [h.node for h in demo_world.history()][-1] == "fridge_door"


def test_bad_updates_are_refused_naming_the_node(demo_world):
    with pytest.raises(WorldError, match="outside limits") as e:
        demo_world.set_joint_state("cupboard_door_left", 3.0)
    assert str(e.value).startswith("node cupboard_door_left:")
    with pytest.raises(WorldError, match="unknown knob state"):
        demo_world.set_knob_state("oven_knob_1", "max")
    with pytest.raises(UnknownNode):
        demo_world.get("unicorn")
    assert demo_world.history() == []


def test_add_and_find_a_new_small_object(demo_world):
    demo_world.add_small_object(SmallObject("green_cup", "cup", Pose(0, 0, 0.72), color="green"),
                                "side_table", source="test")
    assert demo_world.find("green cup")[0].node.id == "green_cup"
    assert demo_world.room_of("green_cup").id == "kitchen"


def test_mesh_of_an_object_follows_its_articulation(demo_world):
    closed = node_mesh(demo_world, "cupboard").get_axis_aligned_bounding_box()
    demo_world.set_joint_state("cupboard_door_left", math.radians(90))
    opened = node_mesh(demo_world, "cupboard").get_axis_aligned_bounding_box()
    # The cupboard faces -x; an open door sticks out further into the room.
    assert opened.get_min_bound()[0] < closed.get_min_bound()[0] - 0.3


URDF = b"""<?xml version="1.0"?>
<robot name="two_door_cabinet">
  <material name="white"><color rgba="0.9 0.9 0.9 1"/></material>
  <link name="body">
    <visual><origin xyz="0 0 0.4"/><geometry><box size="0.4 0.8 0.8"/></geometry>
      <material name="white"/></visual>
  </link>
  <link name="left_door">
    <visual><origin xyz="0 -0.2 0.35"/><geometry><box size="0.02 0.4 0.7"/></geometry></visual>
  </link>
  <link name="right_door">
    <visual><origin xyz="0 0.2 0.35"/><geometry><box size="0.02 0.4 0.7"/></geometry></visual>
  </link>
  <link name="left_handle">
    <visual><geometry><cylinder radius="0.01" length="0.15"/></geometry></visual>
  </link>
  <joint name="left_hinge" type="revolute">
    <parent link="body"/><child link="left_door"/>
    <origin xyz="0.21 0.4 0.05" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="1.7" effort="1" velocity="1"/>
  </joint>
  <joint name="right_hinge" type="revolute">
    <parent link="body"/><child link="right_door"/>
    <origin xyz="0.21 -0.4 0.05"/><axis xyz="0 0 -1"/>
    <limit lower="0" upper="1.7" effort="1" velocity="1"/>
  </joint>
  <joint name="left_handle_mount" type="fixed">
    <parent link="left_door"/><child link="left_handle"/>
    <origin xyz="0.05 -0.35 0.4"/>
  </joint>
</robot>
"""


def test_urdf_two_door_cabinet_imports_as_articulated_object(demo_world, tmp_path):
    obj = import_urdf(URDF, "urdf_cabinet", pose=Pose(1.0, 3.0, 0, 0, 0, 0))
    assert [p.id for p in obj.parts] == ["left_door", "right_door"]
    left = obj.parts[0]
    assert (left.joint.type, left.joint.axis, left.joint.upper) == ("revolute", (0.0, 0.0, 1.0), 1.7)
    assert left.joint.origin.x == pytest.approx(0.21)
    assert [h.id for h in left.handles] == ["left_handle"]
    assert left.handles[0].length == pytest.approx(0.15)
    assert obj.model.visuals[0].color == (0.9, 0.9, 0.9)
    # It joins a map, saves and loads like any other object, and opens.
    demo_world.apartment.rooms[0].objects.append(obj)
    from hearth.worldmodel import save_world
    save_world(demo_world, tmp_path / "w.xml")
    w = load_world(tmp_path / "w.xml")
    before = w.T_world("left_handle")[:3, 3]
    w.set_joint_state("left_door", 1.0)
    assert np.linalg.norm(w.T_world("left_handle")[:3, 3] - before) > 0.2


def test_urdf_with_entities_is_refused():
    bad = b'<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n<robot name="&x;"/>'
    with pytest.raises(WorldError, match="not allowed"):
        import_urdf(bad, "x")


def test_every_demo_parking_position_is_free_floor_inside_its_room(demo_world):
    for obj in demo_world.large_objects():
        x0, y0, x1, y1 = demo_world.room_of(obj.id).bounds
        for p, pose in demo_world.parking_positions(obj.id):
            assert x0 + 0.3 <= pose.x <= x1 - 0.3 and y0 + 0.3 <= pose.y <= y1 - 0.3, p.id
            for other in demo_world.large_objects():
                lo, hi = demo_world.bounds_world(other.id)
                inside = lo[0] - 0.25 < pose.x < hi[0] + 0.25 and lo[1] - 0.25 < pose.y < hi[1] + 0.25
                assert not inside, f"{p.id} stands in {other.id}"


def test_support_at_names_the_furniture_under_a_seen_object(demo_world):
    # A cup seen on the side table (top at 0.72 m), one in the cupboard, and one in mid-air.
    assert demo_world.support_at((1.5, 1.3, 0.72))[0].id == "side_table"
    assert demo_world.support_at((5.72, 1.6, 0.46))[0].id == "cupboard"
    assert demo_world.support_at((3.0, 3.2, 1.5)) is None


def test_aim_point_is_the_top_of_a_table_or_the_middle_of_the_knobs(demo_world):
    # The top of the table's bounds with what stands on it (the sugar jar is 12 cm tall).
    top = demo_world.aim_point("kitchen_table", "top")
    assert top == pytest.approx([3.0, 2.2, 0.87], abs=1e-6)
    knobs = demo_world.aim_point("oven", "knobs")
    assert knobs[2] == pytest.approx(0.81, abs=1e-6)


def test_cli_map_find_asks_which_one_when_words_name_several():
    r = subprocess.run([sys.executable, "-m", "hearth", "map", "find",
                        "data/demo_home/world.xml", "cup"], capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stdout.startswith("which cup do you mean: the blue cup (blue_cup) on the kitchen table or ")


def test_knobs_on_top_are_looked_at_from_nearer_on_the_parking_side_clear_of_the_hob():
    """A hob's knobs face up: the view stands on the side of its parking positions, nearer than
    the distance asked (a steeper look down), and its base clear of the hob itself."""
    import math
    import tempfile
    import numpy as np
    from hearth.worldmodel.homegen import generate_home
    from hearth.worldmodel.viewing import BASE_CLEARANCE, knob_view_pose
    mesh_dir = tempfile.mkdtemp()
    for seed in range(16, 40):          # the first generated home with knobs on top of a hob
        w = generate_home(seed, mesh_dir=mesh_dir)
        hob = next((o.id for o in w.large_objects()
                    if any(w.T_world(k.id)[2, 2] > 0.9 for k in w.knobs(o.id))), None)
        if hob is not None:
            break
    assert hob is not None
    centre = np.mean([w.T_world(k.id)[:3, 3] for k in w.knobs(hob)], axis=0)
    pose = knob_view_pose(w, hob, distance=1.0)
    assert pose is not None
    d = math.hypot(pose.x - centre[0], pose.y - centre[1])
    assert d < 1.0
    lo, hi = w.bounds_world(hob)
    assert math.hypot(max(lo[0] - pose.x, 0, pose.x - hi[0]), max(lo[1] - pose.y, 0, pose.y - hi[1])) >= BASE_CLEARANCE
    # facing the knobs, from the side its parking positions are on
    assert abs(math.remainder(pose.yaw - math.atan2(centre[1] - pose.y, centre[0] - pose.x), 2 * math.pi)) < 1e-6
    _, park = w.parking_positions(hob)[0]
    assert (pose.x - centre[0]) * (park.x - centre[0]) + (pose.y - centre[1]) * (park.y - centre[1]) > 0


def test_knob_view_pose_is_refused_outside_the_rooms_or_against_furniture(demo_world):
    from hearth.worldmodel.viewing import knob_view_pose
    near = knob_view_pose(demo_world, "oven", distance=1.0)
    assert near is not None
    assert knob_view_pose(demo_world, "oven", distance=30.0) is None      # outside every room
    # another large object's footprint where the robot would stand: refused
    other = next(o for o in demo_world.large_objects()
                 if demo_world.large_object_of("oven").id != o.id)
    lo, hi = demo_world.bounds_world(other.id)
    centre = (lo + hi) / 2
    demo_world.set_pose(other.id, Pose.planar(near.x - centre[0] + other.pose.x,
                                              near.y - centre[1] + other.pose.y, other.pose.yaw))
    assert knob_view_pose(demo_world, "oven", distance=1.0) is None
    # a node without knobs has no such pose
    assert knob_view_pose(demo_world, other.id) is None
