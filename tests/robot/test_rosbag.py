"""ROS 2 bags: a bag written by an independent writer (mcap-ros2-support, hand-written message
definitions) replays a simulated run to its end; tf is interpolated at the image stamps; bad
bags are one line naming the topic or frame, exit 2; Hearth's own bags read back with rosbags
and the MCAP tools."""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from hearth.cli.main import main
from hearth.robot.errors import RobotError
from hearth.robot.recording import Recording
from hearth.robot.rosbag import BagRecording, TfBuffer, load_topic_map
from hearth.robot.sim import R_BODY_CAMERA
from hearth.perception.camera import Intrinsics

sys.path.insert(0, str(Path(__file__).parent))
from bagwriter import BagFile, planar, transform  # noqa: E402

MISSION = "missions/turn_off_oven.yaml"


def end_of(runs: Path) -> dict:
    """The end line of the only execution log in ``runs``."""
    (log,) = sorted(runs.glob("*.jsonl"))
    return json.loads(log.read_text().splitlines()[-1])


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A simulated turn_off_oven run (scenario seed 5) recorded in Hearth's format."""
    d = tmp_path_factory.mktemp("sim")
    assert main(["scenario", "make", "--seed", "5", "--out", str(d / "sc")]) == 0
    assert main(["record", MISSION, "--scenario", str(d / "sc"), "--out", str(d / "rec"),
                 "--runs-dir", str(d / "runs"), "--quiet"]) == 0
    return d, end_of(d / "runs")


def write_independent_bag(rec: Recording, path: Path) -> None:
    """The recording's frames and poses as a robot's bag would have them: depth 32FC1 metres
    (NaN: no reading) on the aligned-depth topic, colour bgr8, tf map -> odom -> base_link ->
    camera_link -> camera_color_optical_frame with the moving links sampled 50 ms before and
    after each image (moving through the image's pose) and the optical frame static."""
    bag = BagFile(path)
    t0 = 1_000_000_000_000                                   # 1000 s: not at time zero
    T_link_optical = np.eye(4)
    T_link_optical[:3, :3] = R_BODY_CAMERA
    bag.tf(t0, [transform(t0, "map", "odom", np.eye(4)),
                transform(t0, "camera_link", "camera_color_optical_frame", T_link_optical)],
           static=True)
    last = None
    for c in rec.captures:
        ns = t0 + int(round(c.timestamp * 1e9))
        # captures of the same simulated instant (a localisation fix between them) 0.2 s apart
        ns = ns if last is None or ns > last + 200_000_000 else last + 200_000_000
        last = ns
        f = rec.frame(c.index)
        T_wb = c.base_pose.matrix()
        T_b_link = np.linalg.inv(T_wb) @ c.T_world_camera @ np.linalg.inv(T_link_optical)
        for dt, s in ((-50_000_000, -1), (50_000_000, 1)):
            # the base moves 1 cm and turns 0.2 degrees per 50 ms through the image's pose
            step = planar(0.01 * s, 0.0, math.radians(0.2) * s)
            bag.tf(ns + dt, [transform(ns + dt, "odom", "base_link", T_wb @ step),
                             transform(ns + dt, "base_link", "camera_link",
                                       np.linalg.inv(step) @ T_b_link)])
        depth = f.depth.astype(np.float32)
        depth[depth == 0] = np.nan
        bag.image("/camera/aligned_depth_to_color/image_raw", ns, "camera_color_optical_frame",
                  depth, "32FC1")
        bag.image("/camera/color/image_raw", ns, "camera_color_optical_frame",
                  f.color[..., ::-1], "bgr8")
        bag.camera_info("/camera/color/camera_info", ns, "camera_color_optical_frame",
                        rec.intrinsics)
    bag.close()


def test_a_bag_from_an_independent_writer_replays_the_simulated_run_to_its_end(simulated, tmp_path, capsys):
    d, sim_end = simulated
    rec = Recording(d / "rec")
    bag = tmp_path / "robot.mcap"
    write_independent_bag(rec, bag)
    # Frames matched to poses through tf at the image stamps (interpolated between samples).
    br = BagRecording(bag)
    assert len(br) == len(rec) and br.intrinsics == rec.intrinsics
    for a, b in zip(rec.captures, br.captures):         # 1 cm off if it were not interpolated
        assert np.allclose(a.T_world_camera, b.T_world_camera, atol=1e-4)
        assert a.base_pose.planar_distance(b.base_pose) < 1e-6
    f, g = rec.frame(1), br.frame(1)
    assert np.array_equal(f.color, g.color) and np.allclose(f.depth, g.depth)
    br.close()
    capsys.readouterr()
    status = main(["run", MISSION, "--recording", str(bag), "--world", str(d / "sc" / "belief.xml"),
                   "--runs-dir", str(tmp_path / "runs")])
    out = capsys.readouterr().out
    assert status == 0, out
    end = end_of(tmp_path / "runs")
    assert (end["outcome"], end["reason"]) == (sim_end["outcome"], sim_end["reason"])
    # The camera poses come back through tf to 1e-4 m: measured figures agree to 1 %.
    assert _close(end["outputs"], sim_end["outputs"]), _differ(end["outputs"], sim_end["outputs"])
    assert "I turned off 1 knob of the oven; it is off now." in out


def test_tf_is_interpolated_and_never_extrapolated():
    tf = TfBuffer(tolerance_ns=0)
    tf.add("map", "base", 0, (0, 0, 0), (0, 0, 0, 1), static=False)
    tf.add("map", "base", 10, (1, 2, 0), (0, 0, math.sin(0.5), math.cos(0.5)), static=False)
    tf.add("base", "cam", 0, (0.1, 0, 1.0), (0, 0, 0, 1), static=True)
    T = tf.lookup("map", "cam", 5)
    assert np.allclose(T[:3, 3], (0.5 + 0.1 * math.cos(0.5), 1.0 + 0.1 * math.sin(0.5), 1.0))
    assert math.atan2(T[1, 0], T[0, 0]) == pytest.approx(0.5)          # half of the 1 rad turn
    assert np.allclose(tf.lookup("cam", "map", 5), np.linalg.inv(T))
    with pytest.raises(LookupError):
        tf.lookup("map", "cam", 11)


def _small_bag(path: Path, *, depth_encoding="16UC1", color_topic="/camera/color/image_raw",
               base_parent="odom", depth_frame="cam", d=(0.0,) * 5, tf_nan=False,
               depth_m=1.5, base_x=None):
    """A tiny two-frame bag, with one thing wrong as asked."""
    K = Intrinsics.kinect(8, 6)
    bag = BagFile(path)
    bag.tf(0, [transform(0, "map", "odom", np.eye(4))], static=True)
    for k, ns in enumerate((1_000_000_000, 2_000_000_000)):
        T = planar(1.0 + k, 2.0, 0.0)
        if tf_nan:
            T[0, 3] = math.nan
        if base_x is not None:
            T[0, 3] = base_x
        bag.tf(ns, [transform(ns, base_parent, "base_link", T),
                    transform(ns, "base_link", "cam", np.eye(4))])
        depth = (np.full((6, 8), 1500, np.uint16) if depth_encoding != "32FC1"
                 else np.full((6, 8), depth_m, np.float32))
        if depth_encoding == "8UC1":
            depth = np.full((6, 8), 15, np.uint8)
        bag.image("/camera/depth/image_raw", ns, depth_frame, depth, depth_encoding)
        bag.image(color_topic, ns, "cam", np.zeros((6, 8, 3), np.uint8), "rgb8")
        bag.camera_info("/camera/color/camera_info", ns, "cam", K, d=d)
    bag.close()


def test_a_small_bag_with_16uc1_depth_reads_in_metres(tmp_path):
    _small_bag(tmp_path / "ok.mcap")
    br = BagRecording(tmp_path / "ok.mcap")
    assert len(br) == 2 and br.captures[1].base_pose.x == pytest.approx(2.0)
    assert np.allclose(br.frame(0).depth, 1.5)


@pytest.mark.parametrize("case, words", [
    ("missing_topic", "no color topic: none of /camera/color/image_raw"),
    ("unknown_encoding", "topic /camera/depth/image_raw: depth encoding '8UC1' is not supported"),
    ("no_tf", "no tf between map and base_link"),
    ("unregistered", "is not registered to colour /camera/color/image_raw (frame cam, 8x6) and "
                     "the bag has no depth camera_info"),
    ("distortion", "topic /camera/color/camera_info: distortion model 'plumb_bob' with 3 "
                   "coefficients is not one OpenCV undistorts"),
    ("nan_tf", "the transform odom -> base_link at 1.000 s has numbers that are not finite"),
    ("truncated", "not a readable ROS 2 bag"),
])
def test_a_bad_bag_is_one_line_naming_the_topic_or_frame_and_exit_2(case, words, tmp_path, capsys):
    bag = tmp_path / f"{case}.mcap"
    _small_bag(bag, **{
        "missing_topic": dict(color_topic="/elsewhere/image"),
        "unknown_encoding": dict(depth_encoding="8UC1"),
        "no_tf": dict(base_parent="odom2"),
        "unregistered": dict(depth_frame="depth_cam"),
        "distortion": dict(d=(0.1, 0.0, 0.0)),
        "nan_tf": dict(tf_nan=True),
        "truncated": {}}[case])
    if case == "truncated":
        data = bag.read_bytes()
        bag.write_bytes(data[:len(data) // 2])
    status = main(["run", MISSION, "--recording", str(bag), "--runs-dir", str(tmp_path / "runs")])
    cap = capsys.readouterr()
    assert status == 2
    assert cap.err.count("\n") == 1 and cap.err.startswith(f"{bag}: ")
    assert words in cap.err, cap.err
    assert cap.out == ""                        # refused before the mission started


def test_topics_map_other_names_and_refuse_unknown_keys(tmp_path, capsys):
    bag = tmp_path / "renamed.mcap"
    _small_bag(bag, color_topic="/head/rgb")
    with pytest.raises(RobotError, match="no color topic"):
        BagRecording(bag)
    assert len(BagRecording(bag, topics="color=/head/rgb")) == 2
    (tmp_path / "renamed.topics.yaml").write_text("color: /head/rgb\n")       # the side file
    assert len(BagRecording(bag)) == 2
    side = tmp_path / "bad.yaml"
    side.write_text("colour: /head/rgb\n")
    assert main(["run", MISSION, "--recording", str(bag), "--topics", str(side),
                 "--runs-dir", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{side}: unknown key 'colour' in the topic mapping") and err.count("\n") == 1
    assert load_topic_map("base_frame=base_footprint,sync_tolerance=0.01").base_frame == "base_footprint"


def test_without_the_ros_extra_a_bag_command_says_what_to_install(tmp_path, capsys, monkeypatch):
    bag = tmp_path / "ok.mcap"
    _small_bag(bag)
    for name in [m for m in sys.modules if m == "rosbags" or m.startswith("rosbags.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "rosbags", None)          # import rosbags now fails
    assert main(["run", MISSION, "--recording", str(bag), "--runs-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == ("reading and writing ROS 2 bags needs the ros extra: pip install "
                           "'hearth[ros]' (rosbags, mcap, mcap-ros2-support, foxglove-sdk)")


def _differ(a, b, at="") -> list:
    """The leaves where ``a`` and ``b`` are not ``_close`` (for the failure message)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in a.keys() | b.keys() for d in _differ(a.get(k), b.get(k), f"{at}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differ(x, y, f"{at}[{i}]")]
    return [] if _close(a, b) else [(at, a, b)]


def _close(a, b) -> bool:
    """Equal, numbers to 1 % (or 1e-4 absolute); whole counts (pixels that agree within a
    threshold, which step with the pose) to 5 %."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, int) and isinstance(b, int) and not isinstance(a, bool):
        return abs(a - b) <= 5e-2 * max(abs(a), abs(b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return abs(a - b) <= 1e-2 * max(abs(a), abs(b)) + 1e-4
    return a == b


#: A RealSense D435's colour distortion (plumb_bob), of the size its calibration reports.
D435_COLOR_D = (0.06, -0.09, 0.0006, -0.0004, 0.03)
#: Its depth camera: 15 mm to the left of the colour camera, a wider lens.
T_COLOR_DEPTH = planar(0.0, 0.0, 0.0)
T_COLOR_DEPTH[0, 3] = -0.015


def write_realsense_bag(rec: BagRecording, path: Path) -> None:
    """Hearth's own bag of a run, as a RealSense on a robot records it (written with
    rosbags' own writer): colour a JPEG
    CompressedImage with plumb-bob distortion; depth unregistered, 16UC1 millimetres as the
    depth camera (15 mm beside the colour one, its own intrinsics) sees it, with its own
    camera_info; tf at 30 Hz (the robot stands still for 0.1 s around each capture and moves
    in straight lines between)."""
    import cv2
    from bagwriter import RealSenseBag, distort
    from hearth.perception.camera import register_depth
    from scipy.spatial.transform import Rotation, Slerp

    K = rec.intrinsics
    Kd = Intrinsics(K.fx * 0.85, K.fy * 0.85, K.cx + 3.0, K.cy - 2.0, K.width, K.height)
    bag = RealSenseBag(path)
    t0 = 1_000_000_000_000
    T_link_optical = np.eye(4)
    T_link_optical[:3, :3] = R_BODY_CAMERA
    bag.tf(t0, [transform(t0, "map", "odom", np.eye(4)),
                transform(t0, "camera_link", "camera_color_optical_frame", T_link_optical),
                transform(t0, "camera_color_optical_frame", "camera_depth_optical_frame",
                          T_COLOR_DEPTH)], static=True)
    stamps, poses = [], []
    for c in rec.captures:
        ns = t0 + int(round(c.timestamp * 1e9))
        ns = max(ns, stamps[-1] + 500_000_000) if stamps else ns
        stamps.append(ns)
        T_wb = c.base_pose.matrix()
        poses.append((T_wb, np.linalg.inv(T_wb) @ c.T_world_camera @ np.linalg.inv(T_link_optical)))
        f = rec.frame(c.index)
        depth_cam = register_depth(f.depth, K, Kd, np.linalg.inv(T_COLOR_DEPTH))
        bag.image("/camera/depth/image_rect_raw", ns, "camera_depth_optical_frame",
                  np.rint(depth_cam * 1000).astype(np.uint16), "16UC1")
        bag.jpeg("/camera/color/image_raw/compressed", ns, "camera_color_optical_frame",
                 distort(f.color, K, D435_COLOR_D))
        bag.camera_info("/camera/color/camera_info", ns, "camera_color_optical_frame", K,
                        d=D435_COLOR_D)
        bag.camera_info("/camera/depth/camera_info", ns, "camera_depth_optical_frame", Kd)

    def at(ns: int, k: int) -> int:
        return k if abs(ns - stamps[k]) <= 100_000_000 else -1

    def blend(A, B, s):
        out = np.eye(4)
        out[:3, 3] = (1 - s) * A[:3, 3] + s * B[:3, 3]
        rots = Rotation.from_matrix(np.stack([A[:3, :3], B[:3, :3]]))
        out[:3, :3] = Slerp([0, 1], rots)(s).as_matrix()
        return out

    for ns in range(stamps[0] - 200_000_000, stamps[-1] + 200_000_000, 33_333_333):
        j = int(np.searchsorted(stamps, ns))
        k = next((i for i in (j - 1, j) if 0 <= i < len(stamps) and at(ns, i) >= 0), None)
        if k is not None:
            T_wb, T_bl = poses[k]
        else:                                    # between two captures' standing still
            a, b = max(j - 1, 0), min(j, len(stamps) - 1)
            s = ((ns - stamps[a] - 100_000_000) / max(stamps[b] - stamps[a] - 200_000_000, 1)
                 if a != b else 0.0)
            s = float(np.clip(s, 0.0, 1.0))
            T_wb, T_bl = blend(poses[a][0], poses[b][0], s), blend(poses[a][1], poses[b][1], s)
        bag.tf(ns, [transform(ns, "odom", "base_link", T_wb),
                    transform(ns, "base_link", "camera_link", T_bl)])
    bag.close()
    del cv2


@pytest.fixture(scope="module")
def hearths_bag(simulated, tmp_path_factory):
    """Hearth's own bag of the same scenario (seed 5) and the end of its replay."""
    d, _ = simulated
    out = tmp_path_factory.mktemp("bag")
    assert main(["record", MISSION, "--scenario", str(d / "sc"), "--format", "mcap",
                 "--out", str(out / "bag"), "--runs-dir", str(out / "sim"), "--quiet"]) == 0
    assert main(["run", MISSION, "--recording", str(out / "bag"), "--world",
                 str(d / "sc" / "belief.xml"), "--runs-dir", str(out / "replay"),
                 "--quiet"]) in (0, 1)
    return out / "bag", end_of(out / "replay")


def test_a_realsense_layout_bag_replays_turn_off_oven_as_hearths_own_bag(simulated, hearths_bag,
                                                                         tmp_path, capsys):
    d, _ = simulated
    bag_dir, own_end = hearths_bag
    own = BagRecording(bag_dir)
    bag = tmp_path / "realsense"                    # a rosbag2 directory, MCAP storage
    write_realsense_bag(own, bag)
    rs = BagRecording(bag)
    assert len(rs) == len(own)
    # tf at 30 Hz, read at the image stamps: the poses are the recording's.
    for a, b in zip(own.captures, rs.captures):
        assert np.allclose(a.T_world_camera, b.T_world_camera, atol=1e-6)
    # Registered and undistorted again: nearly every reading comes back, within the few
    # millimetres that resampling twice (into the depth camera's coarser pixels and back)
    # moves a reading on a slanted surface.
    f, g = own.frame(1), rs.frame(1)
    both = (f.depth > 0) & (g.depth > 0)
    assert both.mean() > 0.9 * (f.depth > 0).mean()
    assert np.median(np.abs(f.depth[both] - g.depth[both])) < 0.006
    own.close()
    rs.close()
    capsys.readouterr()
    status = main(["run", MISSION, "--recording", str(bag), "--world",
                   str(d / "sc" / "belief.xml"), "--runs-dir", str(tmp_path / "runs"), "--quiet"])
    end = end_of(tmp_path / "runs")
    assert own_end["outcome"] == "succeeded", own_end["reason"]
    assert (end["outcome"], end["reason"]) == (own_end["outcome"], own_end["reason"])
    assert status == 0


# -- issue 44 ----------------------------------------------------------------------------------

def test_a_bag_that_is_a_fifo_is_refused_without_blocking(tmp_path, capsys):
    bag = tmp_path / "pipe.mcap"
    os.mkfifo(bag)
    status = main(["run", MISSION, "--recording", str(bag), "--runs-dir", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert status == 2 and err == f"{bag}: not a regular file (a bag is an .mcap file or a " \
                                  "rosbag2 directory)\n"


@pytest.mark.parametrize("kind, words", [
    ("fifo", "not a regular file"), ("dev_zero", "not a regular file"),
    ("sparse_3GB", "larger than 64 KiB"), ("nested", "nested too deeply"),
])
def test_a_hostile_topic_mapping_side_file_is_one_line(kind, words, tmp_path):
    bag = tmp_path / "ok.mcap"
    _small_bag(bag)
    side = tmp_path / "ok.topics.yaml"
    if kind == "fifo":
        os.mkfifo(side)
    elif kind == "dev_zero":
        side.symlink_to("/dev/zero")
    elif kind == "sparse_3GB":
        with open(side, "wb") as f:
            f.truncate(3 << 30)
    else:
        side.write_text("a: " + "[" * 30_000 + "]" * 30_000 + "\n")
    with pytest.raises(RobotError) as err:
        BagRecording(bag)
    assert str(err.value).startswith(f"{side}: ") and words in str(err.value)
    assert "\n" not in str(err.value)


def test_a_32fc1_depth_of_3_4e38_metres_is_refused_when_served(tmp_path):
    bag = tmp_path / "far.mcap"
    _small_bag(bag, depth_encoding="32FC1", depth_m=3.4e38)
    br = BagRecording(bag)
    with pytest.raises(RobotError, match=r"the depth image at 1.000 s has a depth of 3.4e\+38 m "
                                         r"\(at most 1000 m; NaN or inf for no reading\)"):
        br.frame(0)


def test_a_base_pose_of_1e300_in_tf_is_refused(tmp_path):
    bag = tmp_path / "far.mcap"
    _small_bag(bag, base_x=1e300)
    with pytest.raises(RobotError, match=r"tf: the pose of cam or base_link at 1.000 s is not "
                                         r"finite or beyond \+-10000 m"):
        BagRecording(bag)
