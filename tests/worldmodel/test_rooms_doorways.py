"""Rooms as polygons joined by doorways, and paths on the occupancy grid built from them
(docs/world-format.md "Rooms and doorways", docs/navigation.md)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.worldmodel import WorldError, load_world, parse_world, to_xml
from hearth.worldmodel.frames import T_world_room, room_contains, transform_xy
from hearth.worldmodel.geometry import room_visuals
from hearth.worldmodel.navigation import NoPath, _footprints, nav_grid
from hearth.worldmodel.outline import doorway_rect, outline_contains
from polygon_check import inside_and_distance

# Two rooms: an L-shaped hall (its (4, 0)-(6, 2) corner cut out) and a kitchen beside it,
# 0.3 m apart, joined by a doorway written in the hall; a store room with no doorway.
FLAT = b"""<?xml version='1.0' encoding='UTF-8'?>
<apartment id="flat" version="1" name="L flat">
  <room id="hall" name="hall">
    <outline>
      <corner x="0" y="0"/><corner x="4" y="0"/><corner x="4" y="2"/>
      <corner x="6" y="2"/><corner x="6" y="4"/><corner x="0" y="4"/>
    </outline>
    <doorway id="hall_kitchen" to="kitchen" width="0.9" depth="0.4">
      <pose x="6.15" y="3"/>
    </doorway>
    <LargeObject id="table" type="table" name="hall table">
      <pose x="2" y="2"/>
      <model><box size="1.6 0.8 0.75" color="0.5 0.4 0.3"><pose z="0.375"/></box></model>
      <parking default="south"><position id="south" x="0" y="-1" yaw="1.5708"/>
        <position id="north" x="0" y="1" yaw="-1.5708"/></parking>
      <surface id="top" sizeX="1.6" sizeY="0.8"><pose z="0.75"/></surface>
    </LargeObject>
  </room>
  <room id="kitchen" name="kitchen" bounds="0 0 3 3">
    <pose x="6.3" y="1.5"/>
    <LargeObject id="counter" type="table" name="counter">
      <pose x="2.7" y="1.5"/>
      <model><box size="0.6 2 0.9" color="0.8 0.8 0.8"><pose z="0.45"/></box></model>
      <parking default="front"><position id="front" x="-0.8" y="0" yaw="0"/></parking>
    </LargeObject>
  </room>
  <room id="store" name="store room" bounds="0 0 2 2">
    <pose x="0" y="4.3"/>
    <LargeObject id="shelf" type="shelf" name="store shelf">
      <pose x="1" y="1.7"/>
      <model><box size="1.5 0.4 1.8" color="0.6 0.6 0.6"><pose z="0.9"/></box></model>
      <parking default="front"><position id="front" x="0" y="-0.8" yaw="1.5708"/></parking>
    </LargeObject>
  </room>
</apartment>
"""


def flat():
    return parse_world(FLAT, "flat.xml")


def test_an_old_rectangle_room_world_loads_and_saves_byte_identical(demo_world_path):
    data = demo_world_path.read_bytes()
    world = load_world(demo_world_path)
    assert all(r.outline is None and not r.doorways for r in world.rooms)
    assert to_xml(world.apartment) == data
    assert b"<outline" not in data and b"bounds=" in to_xml(world.apartment)


def test_polygon_rooms_and_doorways_load_save_and_load_equal():
    world = flat()
    hall = world.get("hall")
    assert hall.outline == [(0, 0), (4, 0), (4, 2), (6, 2), (6, 4), (0, 4)]
    assert hall.bounds == (0, 0, 6, 4)                 # its bounding box, for extents
    assert [d.id for d in hall.doorways] == ["hall_kitchen"]
    assert world.get("hall_kitchen").to == "kitchen"
    data = to_xml(world.apartment)
    assert b"<outline>" in data and b'<doorway id="hall_kitchen"' in data
    assert b'<room id="hall" name="hall" bounds' not in data   # the outline only
    again = parse_world(data, "again.xml")
    assert again == world and to_xml(again.apartment) == data


def test_the_corner_an_l_shaped_room_lacks_is_not_in_it():
    world = flat()
    hall = world.get("hall")
    assert room_contains(hall, 1.0, 1.0) and room_contains(hall, 5.0, 3.0)
    assert not room_contains(hall, 5.0, 1.0)           # in its bounds, not on its floor
    assert world.room_of("table").id == "hall"


@pytest.mark.parametrize("change, message", [
    (b'<corner x="6" y="2"/><corner x="6" y="4"/>', "crosses"),
    (b'to="kitchen"', "not another room"),
    (b'<pose x="6.15" y="3"/>', "from the walls"),
    (b'<room id="hall" name="hall">', "not both"),
])
def test_a_bad_outline_or_doorway_is_one_line_naming_the_file_and_line(change, message):
    bad = {
        b'<corner x="6" y="2"/><corner x="6" y="4"/>': b'<corner x="6" y="4"/><corner x="6" y="2"/>',
        b'to="kitchen"': b'to="nowhere"',
        b'<pose x="6.15" y="3"/>': b'<pose x="3" y="3"/>',
        b'<room id="hall" name="hall">': b'<room id="hall" name="hall" bounds="0 0 6 4">',
    }[change]
    with pytest.raises(WorldError) as err:
        parse_world(FLAT.replace(change, bad), "flat.xml")
    text = str(err.value)
    if message == "crosses":
        message = "cross"
    assert message in text and "flat.xml:" in text and "\n" not in text.strip()


def _wall_footprints(world):
    """World (4, 2) footprints of every wall box the simulator draws that stands on the
    floor (not the lintels above doorways)."""
    out = []
    for room in world.rooms:
        T = T_world_room(room)
        for v in room_visuals(room, world):
            if v.name != "wall" or v.pose.z - v.size[2] / 2 > 0.5:
                continue
            sx, sy = v.size[0] / 2, v.size[1] / 2
            c, s = math.cos(v.pose.yaw), math.sin(v.pose.yaw)
            corners = [(v.pose.x + c * a - s * b, v.pose.y + s * a + c * b)
                       for a, b in ((-sx, -sy), (sx, -sy), (sx, sy), (-sx, sy))]
            out.append(transform_xy(T, corners))
    return out


def test_walls_are_open_where_a_doorway_crosses_them():
    world = flat()
    door = world.get("hall_kitchen")
    hall = world.get("hall")
    centre = transform_xy(T_world_room(hall), [(door.pose.x, door.pose.y)])[0]
    walls = _wall_footprints(world)
    for dy in (-0.3, 0.0, 0.3):      # across the opening, 0.9 m wide
        for dx in (-0.2, -0.1, 0.0, 0.1, 0.2):
            p = (centre[0] + dx, centre[1] + dy)
            assert not any(outline_contains([tuple(q) for q in w], *p) for w in walls), p
    # beside the opening the wall stands
    assert any(outline_contains([tuple(q) for q in w], centre[0] - 0.1, centre[1] + 0.8)
               for w in walls)


def test_the_path_goes_round_the_table_and_through_the_doorway():
    world = flat()
    grid = nav_grid(world)
    start = world.parking_pose("table", "south")
    goal = world.parking_pose("counter", "front")
    path = grid.path((start.x, start.y), (goal.x, goal.y))
    assert path.length > path.straight + 0.3              # round the table, not across it
    assert path.grid_length >= path.length - 1e-6
    door = transform_xy(T_world_room(world.get("hall")),
                        [np.mean(doorway_rect(world.get("hall_kitchen")), axis=0)])[0]
    assert min(np.linalg.norm(path.points - door, axis=1)) < 0.5 or any(
        _segment_near(a, b, door, 0.5) for a, b in zip(path.points[:-1], path.points[1:]))


def _segment_near(a, b, p, r):
    d = b - a
    t = np.clip(np.dot(p - a, d) / max(np.dot(d, d), 1e-12), 0, 1)
    return np.linalg.norm(a + t * d - p) < r


def test_a_room_without_a_doorway_and_a_goal_in_furniture_have_no_path():
    world = flat()
    grid = nav_grid(world)
    start = world.parking_pose("table", "south")
    store = world.parking_pose("shelf", "front")
    with pytest.raises(NoPath, match="no way from"):
        grid.path((start.x, start.y), (store.x, store.y))
    table = world.world_pose("table")
    with pytest.raises(NoPath, match="inside table"):
        grid.path((start.x, start.y), (table.x, table.y))


def test_the_simulated_robot_is_refused_an_unreachable_parking_position_and_stays():
    from hearth.robot.adapter import wait
    from hearth.robot.clock import SimClock
    from hearth.robot.simulated import SimulatedRobot
    world = flat()
    clock = SimClock()
    robot = SimulatedRobot(world.copy(), clock, start_pose=world.parking_pose("table", "south"))
    before = robot.true_pose()
    act = robot.navigate_to(world.parking_pose("shelf", "front"))
    assert wait(act, clock) == "failed"
    assert act.reason.startswith("no path to (") and "no way from" in act.reason
    assert robot.true_pose() == before
    act = robot.navigate_to(world.parking_pose("counter", "front"))
    assert wait(act, clock) == "succeeded"
    assert robot.true_pose().planar_distance(world.parking_pose("counter", "front")) < 1e-6


def test_the_search_orders_by_path_length_and_leaves_out_unreachable_places():
    from hearth.worldmodel.nodes import SmallObject
    from hearth.worldmodel.pose import Pose
    from hearth.worldmodel.search import search_order
    world = flat()
    world.add_small_object(SmallObject("cup", "cup", Pose(0, 0, 0.75)), "table", source="test")
    robot = world.parking_pose("table", "north")
    plan = search_order(world, "cup", robot)
    places = [p.place for p in plan]
    assert "shelf" not in places                           # no doorway reaches the store
    table = next(p for p in plan if p.place == "table")
    assert table.parking == "north" and table.path_m < 0.1
    grid = nav_grid(world)
    south = world.parking_pose("table", "south")
    assert grid.path((robot.x, robot.y), (south.x, south.y)).grid_length > 2.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_path_in_a_generated_home_crosses_a_wall_or_furniture(seed):
    from hearth.worldmodel.homegen import generate_home
    world = generate_home(seed)
    grid = nav_grid(world)
    assert grid.walls_known
    obstacles = _wall_footprints(world) + [hull for _oid, hull in _footprints(world)]
    poses = [pose for o in world.large_objects() for _p, pose in world.parking_positions(o.id)]
    rng = np.random.default_rng(seed)
    r = grid.config.robot_radius
    samples = []
    for _ in range(10):
        i, j = rng.choice(len(poses), 2, replace=False)
        a, b = poses[i], poses[j]
        pts = grid.path((a.x, a.y), (b.x, b.y)).points   # every parking position is reachable
        for p, q in zip(pts[:-1], pts[1:]):
            n = max(2, int(np.linalg.norm(q - p) / 0.02) + 1)
            samples.append(p + np.linspace(0, 1, n)[:, None] * (q - p))
    samples = np.vstack(samples)
    assert len(samples) > 200
    for poly in obstacles:
        # the robot's disc stays off every wall box and every piece's footprint (a few cm
        # of grid rounding allowed)
        inside, dist = inside_and_distance(samples, np.asarray(poly, float))
        assert not inside.any(), (seed, samples[inside][:3])
        assert dist.min() > r - 0.06, (seed, samples[np.argmin(dist)], dist.min())


def test_generated_homes_have_l_shaped_rooms_corridors_and_doorways():
    from hearth.worldmodel.homegen import generate_home
    shapes = set()
    for seed in range(5):
        world = generate_home(seed)
        rooms = world.rooms
        # every room is joined to the others: a tree of doorways
        assert sum(len(r.doorways) for r in rooms) == len(rooms) - 1
        for r in rooms:
            if r.outline is not None:
                shapes.add("L")
                assert len(r.outline) == 6
            if r.id.startswith("corridor"):
                shapes.add("corridor")
                assert not r.objects
            for d in r.doorways:
                assert d.to in {x.id for x in rooms}
    assert shapes == {"L", "corridor"}
