"""hearth tour -> hearth map build on a one-room generated home (small images for speed)."""
from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from hearth.cli.main import main
from hearth.robot.recording import Recording, RecordingWriter
from hearth.robot.tour import OdometryDrift, TourOptions, plan_tour, record_tour
from hearth.perception.camera import Intrinsics
from hearth.worldmodel.homegen import HomeConfig, generate_home


@pytest.fixture(scope="module")
def home():
    return generate_home(7, HomeConfig(rooms=(1, 1)))


@pytest.fixture(scope="module")
def tour(home, tmp_path_factory):
    out = tmp_path_factory.mktemp("tour") / "rec"
    summary = record_tour(home, out, TourOptions(max_stops_per_room=2),
                          OdometryDrift(distance=0.02, rotation=0.02), seed=3,
                          intrinsics=Intrinsics.kinect(160, 120))
    return out, summary


@pytest.fixture(scope="module")
def built(tour, tmp_path_factory):
    out = tmp_path_factory.mktemp("map") / "build"
    status = main(["map", "build", str(tour[0]), "--out", str(out), "--quiet"])
    return out, status


def test_tour_stops_are_on_free_floor_of_every_room(home):
    from hearth.robot.tour import footprints
    from hearth.worldmodel.homegen_geometry import disc_clear
    plan = plan_tour(home)
    assert {s.room for s in plan.stops} == {r.id for r in home.rooms}
    for s in plan.stops:
        room = home.get(s.room)
        assert all(disc_clear((s.x, s.y), h, 0.3) for h in footprints(home, room))


def test_tour_records_believed_poses_with_truth_beside_them(tour):
    rec = Recording(tour[0])
    assert len(rec) == tour[1].frames > 40
    assert all(c.T_world_camera_true is not None for c in rec.captures)
    drift = [np.linalg.norm(c.T_world_camera[:3, 3] - c.T_world_camera_true[:3, 3])
             for c in rec.captures]
    assert drift[0] < 1e-6 and max(drift) > 0.005       # starts true, then drifts


def test_build_puts_the_floor_at_zero_and_keyframes_near_the_truth(built):
    out, status = built
    assert status == 0
    report = json.loads((out / "build.json").read_text())
    assert report["failed"] == []
    assert abs(report["stages"]["fuse"]["floor_z_m"]) < 0.02
    pg = report["stages"]["posegraph"]
    assert pg["loop_closures_kept"] >= 1
    assert pg["ate_posegraph_m"] < 0.05
    for f in ("odometry/keyframes.json", "posegraph/poses.json", "posegraph/pose_graph.json",
              "fused/map.ply", "fused/mesh.ply", "map.png"):
        assert (out / f).is_file(), f
    assert cv2.imread(str(out / "map.png")).shape[0] > 100


def test_one_stage_reruns_alone_from_the_earlier_outputs(built, tour, tmp_path, capsys):
    out = tmp_path / "copy"
    shutil.copytree(built[0], out)
    (out / "map.png").unlink()
    assert main(["map", "build", str(tour[0]), "--out", str(out), "--stages", "picture"]) == 0
    assert (out / "map.png").is_file()
    report = json.loads((out / "build.json").read_text())
    assert report["stages_run"] == ["picture"] and "posegraph" in report["stages"]


def test_an_empty_recording_is_one_line_and_exit_2(tmp_path, capsys):
    RecordingWriter(tmp_path / "empty", Intrinsics.kinect(160, 120)).close()
    assert main(["map", "build", str(tmp_path / "empty"), "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "empty recording" in err[0] and "empty/manifest.json" in err[0]


def _copy(tour, tmp_path):
    rec = tmp_path / "rec"
    shutil.copytree(tour[0], rec)
    return rec, Recording(rec, check_frames=False)


def test_a_dark_frame_is_named_in_one_line_and_exit_2(tour, tmp_path, capsys):
    rec, r = _copy(tour, tmp_path)
    color = rec / r.captures[5].color
    cv2.imwrite(str(color), np.zeros((120, 160, 3), np.uint8))
    assert main(["map", "build", str(rec), "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "frame 5 is dark" in err[0] and str(color) in err[0]


def test_a_missing_frame_is_named_in_one_line_and_exit_2(tour, tmp_path, capsys):
    rec, r = _copy(tour, tmp_path)
    (rec / r.captures[3].depth).unlink()
    assert main(["map", "build", str(rec), "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "frame 3 is missing" in err[0]


def test_a_bag_with_depth_images_missing_their_colour_is_refused(monkeypatch, tmp_path):
    from hearth.mapping import MappingError
    from hearth.mapping import inputs

    class Bag:                      # what BagRecording reports after pairing images
        path = tmp_path / "tour.mcap"
        captures = [object()] * 10
        skipped = dict(unpaired=2, outside_tf=0)

    import hearth.robot.recording as recording
    monkeypatch.setattr(recording, "open_recording", lambda path, topics=None: Bag())
    with pytest.raises(MappingError, match="2 of 12 frames are missing") as err:
        inputs.open_tour(Bag.path)
    assert str(err.value).startswith(str(Bag.path))


def test_a_tour_recorded_as_a_ros2_bag_builds_with_its_truth(home, tmp_path):
    pytest.importorskip("rosbags")
    from hearth.mapping.build import build
    bag = tmp_path / "tour-bag"   # (a .bag name is a ROS 1 bag to rosbags)
    summary = record_tour(home, bag, TourOptions(max_stops_per_room=1), format="mcap",
                          intrinsics=Intrinsics.kinect(160, 120))
    result = build(bag, tmp_path / "map", only=["odometry"])
    odo = result.stages["odometry"]
    assert result.failed == [] and odo["captures"] == summary.frames
    assert odo["ate_odometry_m"] < 0.05          # the bag's /hearth/truth was read


def test_a_blind_frame_is_skipped_with_a_warning_naming_it(tour, tmp_path, capsys):
    """A view nearer than the depth camera's range (a wall faced at 0.3 m) reads nothing:
    the build goes on without it and says so."""
    rec, r = _copy(tour, tmp_path)
    depth = rec / r.captures[4].depth
    cv2.imwrite(str(depth), np.zeros((120, 160), np.uint16))
    out = tmp_path / "m"
    assert main(["map", "build", str(rec), "--out", str(out), "--quiet",
                 "--stages", "odometry"]) == 0
    report = json.loads((out / "build.json").read_text())
    assert report["stages"]["odometry"]["blind_skipped"] == [4]
    assert any("frame 4 has depth readings in 0.0%" in w and w.endswith("skipped")
               for w in report["warnings"])
    keyframes = json.loads((out / "odometry/keyframes.json").read_text())["keyframes"]
    assert 4 not in keyframes and 3 in keyframes and 5 in keyframes
