"""go_to_rest in a home it was not written for: its places come from the map."""
from __future__ import annotations

import math

from hearth.executive.executive import Executive
from hearth.executive.scenarios import MISSIONS, resolve_world
from hearth.robot.clock import SimClock
from hearth.robot.simulated import SimulatedRobot
from hearth.worldmodel.frames import room_at
from hearth.worldmodel.rest import rest_place


def _run(world, **params):
    clock = SimClock()
    robot = SimulatedRobot(world.copy(), clock=clock)
    ex = Executive(world=world, robot=robot, clock=clock, tick_hz=10.0, background=False)
    h = ex.submit(str(MISSIONS / "go_to_rest.yaml"), **params)
    ex.run_until_idle(50_000)
    return h.result, robot


def test_go_to_rest_in_a_generated_home_without_parameters_rests_on_free_floor():
    world = resolve_world("home:3")
    room = world.rooms[-1]
    result, robot = _run(world, user_room=room.name)
    assert result.outcome == "succeeded", result.reason
    here = robot.true_pose()
    assert room_at(world, here.x, here.y) is room           # in the user's room
    for obj in world.large_objects():                       # clear of the furniture
        (lx, ly, _), (hx, hy, _) = world.bounds_world(obj.id)
        assert math.hypot(max(lx - here.x, 0, here.x - hx), max(ly - here.y, 0, here.y - hy)) > 0.3


def test_the_user_away_sends_the_robot_to_its_charger_and_a_declared_place_wins():
    world = resolve_world("home:3")
    result, robot = _run(world, presence="away")
    assert result.outcome == "succeeded", result.reason
    dock = world.dock_pose(world.chargers()[0].id)
    assert robot.true_pose().planar_distance(dock) < 0.05
    sofa = next(o for o in world.large_objects() if world.room_of(o.id).id == world.rooms[0].id
                and o.parking)
    sofa.affordances.append("rest")
    assert rest_place(world, world.rooms[0].id).target == sofa.id
