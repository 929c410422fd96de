"""Recordings: round trip, one clear line per broken file, replay within tolerances."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hearth import robot
from hearth.robot.adapter import wait
from hearth.robot.clock import SimClock
from hearth.robot.errors import RobotError
from hearth.robot.recording import Recording, RecordingRobot, ReplayRobot
from hearth.robot.simulated import SimulatedRobot
from hearth.worldmodel.pose import Pose


def _record(world, directory):
    clock = SimClock()
    sim = SimulatedRobot(world.copy(), clock, localisation_error=Pose.planar(0.05, 0.0, 0.02),
                         stuck_knobs=["oven_knob_3"], seed=2)
    rec = RecordingRobot(sim, directory, info=dict(world="demo"))
    oven = world.parking_positions("oven")[0][1]
    assert wait(rec.navigate_to(oven), clock) == "succeeded"
    rec.look_at(world.T_world("oven_knob_2")[:3, 3])
    rec.capture()
    rec.set_head(0.0, math.radians(10))
    rec.capture()
    assert wait(rec.turn_knob("oven_knob_1", -1.0), clock) == "succeeded"
    assert wait(rec.turn_knob("oven_knob_3", -1.0), clock) == "failed"
    table = world.parking_positions("kitchen_table")[0][1]
    assert wait(rec.navigate_to(table), clock) == "succeeded"
    rec.look_at(world.T_world("kitchen_table")[:3, 3] + [0, 0, 0.75])
    frame = rec.capture()
    rec.say("done")
    return sim, frame


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    from hearth.worldmodel.io import load_world
    from pathlib import Path
    world = load_world(Path(__file__).resolve().parents[2] / "data/demo_home/world.xml")
    d = tmp_path_factory.mktemp("rec")
    sim, last = _record(world, d)
    return d, world, sim, last


def test_recording_round_trips_frames_poses_and_truth(recording):
    d, world, sim, last = recording
    rec = Recording(d)
    assert len(rec) == 3 and rec.intrinsics == sim.intrinsics
    f = rec.frame(2)
    assert np.array_equal(f.color, last.color)
    assert np.abs(f.depth - last.depth).max() <= 0.0005 + 1e-6          # millimetres
    assert np.array_equal(f.depth == 0, last.depth == 0)
    assert np.allclose(f.T_world_camera, last.T_world_camera)
    assert np.allclose(f.T_world_camera_true, last.T_world_camera_true)
    assert f.base_pose.planar_distance(last.base_pose) < 1e-9
    assert rec.captures[0].parking == "oven_front"
    assert rec.captures[0].goal.planar_distance(world.parking_positions("oven")[0][1]) < 1e-9
    stuck = [a for a in rec.actions if a["action"] == "turn_knob"]
    assert [a["status"] for a in stuck] == ["succeeded", "failed"]
    assert stuck[1]["reason"] == "oven_knob_3 is stuck"


def test_missing_frame_corrupt_manifest_and_unknown_version_are_one_line_each(recording, tmp_path):
    import shutil
    d = tmp_path / "copy"
    shutil.copytree(recording[0], d)
    (d / "frames" / "0000" / "000001_depth.png").unlink()
    with pytest.raises(RobotError) as err:
        Recording(d)                     # checked when opened, not when the frame is asked for
    assert str(err.value) == f"{d / 'frames' / '0000' / '000001_depth.png'}: frame 1 is missing"
    manifest = d / "manifest.json"
    good = manifest.read_text()
    manifest.write_text(good.replace('"info": {', '"info": {,', 1))
    with pytest.raises(RobotError) as err:
        Recording(d)
    msg = str(err.value)
    assert msg.startswith(f"{manifest}:") and "corrupt manifest" in msg and "\n" not in msg
    data = json.loads(good)
    data["version"] = 7
    manifest.write_text(json.dumps(data))
    with pytest.raises(RobotError) as err:
        Recording(d)
    assert str(err.value) == (f"{manifest}: unknown recording version 7 (this Hearth reads "
                              "versions 1, 2)")
    with pytest.raises(RobotError, match="manifest.json is missing"):
        Recording(tmp_path)


def test_replay_serves_the_nearest_frame_within_tolerances_and_names_both_poses(recording):
    d, world, sim, last = recording
    clock = SimClock()
    r = ReplayRobot(d, clock=clock, position_tolerance=0.10, yaw_tolerance=math.radians(10))
    oven = world.parking_positions("oven")[0][1]
    near = Pose.planar(oven.x + 0.07, oven.y, oven.yaw + math.radians(5))
    assert wait(r.navigate_to(near), clock) == "succeeded"
    r.look_at(world.T_world("oven_knob_2")[:3, 3])        # the head as it was recorded
    first = r.capture()
    r.set_head(0.0, math.radians(10))
    second = r.capture()
    rec = Recording(d)
    assert np.array_equal(first.color, rec.frame(0).color)      # in recorded order
    assert np.array_equal(second.color, rec.frame(1).color)
    assert first.base_pose == near
    assert wait(r.navigate_to(Pose.planar(oven.x + 0.2, oven.y, oven.yaw)), clock) == "succeeded"
    with pytest.raises(RobotError) as err:
        r.capture()
    msg = str(err.value)
    assert "no recorded frame within 0.10 m and 10 deg of base pose" in msg
    assert f"({oven.x + 0.2:.2f}, {oven.y:.2f}" in msg and "at oven_front" in msg
    assert "0.20 m and 0 deg away" in msg and "\n" not in msg
    r2 = ReplayRobot(d, clock=clock, position_tolerance=0.25)
    wait(r2.navigate_to(Pose.planar(oven.x + 0.2, oven.y, oven.yaw)), clock)
    assert r2.capture().parking == "oven_front"


def test_replayed_arm_actions_are_logged_and_recorded_failures_repeat(recording):
    d = recording[0]
    clock = SimClock()
    r = robot.create_adapter(recording=str(d), clock=clock)
    assert isinstance(r, ReplayRobot)
    a, b = r.turn_knob("oven_knob_1", -1.0), None
    assert wait(a, clock) == "succeeded"
    b = r.turn_knob("oven_knob_3", -1.0)
    assert wait(b, clock) == "failed" and b.reason == "oven_knob_3 is stuck"
    assert wait(r.open_articulated("oven_door", "oven_handle", 1.0), clock) == "succeeded"
    assert [e["action"] for e in r.log] == ["turn_knob", "turn_knob", "open_articulated"]
