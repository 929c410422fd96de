"""The simulated robot: actions take simulated time and change the truth; drift; capture."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth import robot
from hearth.robot.adapter import RobotAdapter, wait
from hearth.robot.clock import SimClock
from hearth.robot.simulated import SimulatedRobot
from hearth.worldmodel.pose import Pose


@pytest.fixture
def sim(demo_world):
    clock = SimClock()
    return SimulatedRobot(demo_world.copy(), clock, localisation_error=Pose.planar(0.10, 0.0, 0.05),
                          seed=1), clock, demo_world


def test_it_is_a_robot_adapter(sim):
    assert isinstance(sim[0], RobotAdapter)


def test_believed_pose_is_true_pose_composed_with_the_error_and_correction_fixes_it(sim):
    r, clock, _ = sim
    true, bel = r.true_pose(), r.base_pose()
    expect = Pose.from_matrix(true.matrix() @ Pose.planar(0.10, 0.0, 0.05).matrix())
    assert bel.planar_distance(expect) < 1e-9 and bel.yaw_difference(expect) == pytest.approx(0)
    r.apply_correction(true)
    assert r.base_pose().planar_distance(true) < 1e-9


def test_navigation_takes_path_length_over_speed_and_can_be_cancelled(sim):
    r, clock, world = sim
    goal = world.parking_positions("oven")[0][1]
    start = r.base_pose()
    act = r.navigate_to(goal)
    assert act.status() == "running" and act.progress == 0.0
    drive = r.log[-1]
    # The path goes round the furniture: longer than the straight line, and the time is
    # its length over the speed plus the turning (to the goal's heading and at corners).
    assert drive["path_m"] > drive["straight_m"] + 0.05
    assert drive["straight_m"] == pytest.approx(r.true_pose().planar_distance(
        Pose.from_matrix(goal.matrix() @ np.linalg.inv(r.localisation_error().matrix()))), abs=1e-3)
    expected = act.duration
    assert expected >= drive["path_m"] / r.speed + abs(goal.yaw_difference(start)) / r.turn_speed - 1e-6
    assert expected < drive["path_m"] / r.speed + (abs(goal.yaw_difference(start)) + 2 * math.pi) / r.turn_speed
    clock.advance(expected / 2)
    assert act.status() == "running" and act.progress == pytest.approx(0.5, abs=0.01)
    act.cancel()
    assert act.status() == "cancelled"
    halfway = r.base_pose()
    clock.advance(expected)
    assert r.base_pose() == halfway                        # stopped where it was
    act = r.navigate_to(goal)
    assert wait(act, clock) == "succeeded"
    assert r.base_pose().planar_distance(goal) < 1e-6     # believed pose reaches the goal
    assert r.true_pose().planar_distance(goal) > 0.05     # the truth is off by the drift


def test_turning_a_knob_changes_the_truth_and_a_stuck_knob_fails(demo_world):
    clock = SimClock()
    r = SimulatedRobot(demo_world.copy(), clock, stuck_knobs=["oven_knob_2"],
                       start_pose=demo_world.parking_positions("oven")[0][1])
    act = r.turn_knob("oven_knob_1", demo_world.get("oven_knob_1").state_angle("2"))
    assert wait(act, clock) == "succeeded"
    assert r.truth.get("oven_knob_1").state == "2" and demo_world.get("oven_knob_1").state == "off"
    act = r.turn_knob("oven_knob_2", -1.0)
    assert wait(act, clock) == "failed" and act.reason == "oven_knob_2 is stuck"
    assert r.truth.get("oven_knob_2").state == "off"


def test_door_opens_over_time_a_locked_door_does_not_and_far_handles_are_refused(demo_world):
    clock = SimClock()
    r = SimulatedRobot(demo_world.copy(), clock, locked=["fridge_door"],
                       start_pose=demo_world.parking_positions("oven")[0][1])
    act = r.open_articulated("oven_door", "oven_handle", 1.0)
    assert wait(act, clock) == "succeeded" and r.truth.get("oven_door").joint.state == 1.0
    assert clock.now() == pytest.approx(r.approach_time + 1.0 / r.joint_speed, abs=0.2)
    far = r.open_articulated("cabinet_door", "cabinet_handle", 1.0)
    assert far.status() == "failed" and "out of reach" in far.reason
    r2 = SimulatedRobot(demo_world.copy(), clock, locked=["fridge_door"],
                        start_pose=demo_world.parking_positions("fridge")[0][1])
    act = r2.open_articulated("fridge_door", "fridge_handle", 1.0)
    assert wait(act, clock) == "failed" and act.reason == "fridge_door is locked"
    assert r2.truth.get("fridge_door").joint.state == 0.0


def test_the_arm_reaches_from_where_the_robot_believes_it_stands(sim):
    # With the localisation 10 cm and 3 degrees off, the robot sees the cup where it believes
    # it is from its believed pose: grasped there, the arm reaches the cup; at the truth's own
    # coordinates (a pose from a map the error does not apply to) it closes on nothing.
    r, clock, world = sim
    parent = world.parent("blue_cup").id
    assert wait(r.navigate_to(world.parking_positions("blue_cup")[0][1]), clock) == "succeeded"
    true_cup = r.truth.T_world("blue_cup")
    seen = r.base_pose().matrix() @ np.linalg.inv(r.true_pose().matrix()) @ true_cup
    assert np.linalg.norm(seen[:3, 3] - true_cup[:3, 3]) > r.grasp_tolerance
    miss = r.grasp("blue_cup", Pose.from_matrix(true_cup))
    assert wait(miss, clock) == "failed" and "closed on nothing" in miss.reason
    assert wait(r.grasp("blue_cup", Pose.from_matrix(seen)), clock) == "succeeded"
    # put back where it was seen: in truth, where it stood
    assert wait(r.place(parent, Pose.from_matrix(seen)), clock) == "succeeded"
    assert np.allclose(r.truth.T_world("blue_cup")[:3, 3], true_cup[:3, 3], atol=1e-9)


def test_grasped_object_moves_with_the_robot_and_stop_cancels(sim):
    r, clock, world = sim
    r.apply_correction(r.true_pose())
    assert wait(r.navigate_to(world.parking_positions("blue_cup")[0][1]), clock) == "succeeded"
    cup = world.world_pose("blue_cup")
    miss = r.grasp("blue_cup", Pose(cup.x + 0.2, cup.y, cup.z))
    assert wait(miss, clock) == "failed" and "closed on nothing" in miss.reason
    # the arm goes where it is told: a point beyond its reach is refused as such, wherever
    # the object is
    far = r.grasp("blue_cup", Pose(0.0, 0.0, 0.0))
    assert wait(far, clock) == "failed" and "out of reach" in far.reason
    # an object the home does not hold (a false detection): the gripper closes on nothing
    ghost = r.grasp("no_such_cup", Pose(cup.x, cup.y, cup.z))
    assert wait(ghost, clock) == "failed" and ghost.reason.startswith("the gripper closed on nothing")
    assert wait(r.grasp("blue_cup", world.world_pose("blue_cup")), clock) == "succeeded"
    assert r.held.id == "blue_cup" and "blue_cup" not in r.truth
    act = r.navigate_to(world.parking_positions("side_table")[0][1])
    clock.advance(0.5)
    r.stop()
    assert act.status() == "cancelled"
    frame = r.capture()
    r.set_head(0.0, math.radians(40))
    frame = r.capture()
    assert frame.mask(["blue_cup"]).sum() > 500           # carried in front of the robot
    assert wait(r.hand_over(), clock) == "succeeded" and r.handed_over == ["blue_cup"]
    assert [e["action"] for e in r.log].count("grasp") == 4


def test_capture_has_believed_and_true_camera_poses_and_sees_the_oven(sim):
    r, clock, world = sim
    wait(r.navigate_to(world.parking_positions("oven")[0][1]), clock)
    r.look_at(world.T_world("oven_knob_2")[:3, 3])
    f = r.capture()
    assert f.timestamp == clock.now() and f.parking == "oven_front"
    assert np.linalg.norm(f.T_world_camera[:3, 3] - f.T_world_camera_true[:3, 3]) > 0.05
    assert f.owner_mask(["oven"]).mean() > 0.2
    assert (f.depth[f.owner_mask(["oven"])] > 0).mean() > 0.8


def test_create_adapter_without_scenario_simulates_a_copy_of_the_world(demo_world):
    r = robot.create_adapter(world=demo_world, clock=SimClock())
    assert isinstance(r, SimulatedRobot) and r.truth is not demo_world
    with pytest.raises(robot.RobotError):
        robot.create_adapter()
