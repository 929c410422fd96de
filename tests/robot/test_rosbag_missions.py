"""`hearth record --format mcap` then `hearth run --recording BAG` reproduces the simulated
run's outcome for each of the three named missions; the bag reads back with rosbags and with
the MCAP tools (mcap + mcap-ros2-support), standard types and Hearth's extras."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from hearth.cli.main import main
from hearth.executive.scenarios import Case, make_case_scenario
from hearth.robot.scenario import save_scenario

CASES = [Case("fetch_object", seed=0, warmup=0, target="blue_cup"), Case("turn_off_oven", seed=0),
         Case("refine_localisation", seed=1)]


def _end(runs: Path) -> dict:
    (log,) = sorted(runs.glob("*.jsonl"))
    return json.loads(log.read_text().splitlines()[-1])


def _record_and_replay(case: Case, d: Path) -> tuple[dict, dict]:
    sc, params, _target = make_case_scenario(case)
    save_scenario(sc, d / "sc")
    p = [x for k, v in params.items() for x in ("--param", f"{k}={str(v).lower() if isinstance(v, bool) else v}")]
    mission = f"missions/{case.mission}.yaml"
    assert main(["record", mission, "--scenario", str(d / "sc"), "--seed", str(case.seed),
                 "--format", "mcap", "--out", str(d / "bag"), "--runs-dir", str(d / "sim"),
                 "--quiet", *p]) == 0
    status = main(["run", mission, "--recording", str(d / "bag"), "--world",
                   str(d / "sc" / "belief.xml"), "--runs-dir", str(d / "replay"), "--quiet", *p])
    simulated, replayed = _end(d / "sim"), _end(d / "replay")
    assert status == (0 if replayed["outcome"] == "succeeded" else 1)
    return simulated, replayed


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.mission)
def test_a_mission_recorded_as_a_ros2_bag_replays_to_the_simulated_outcome(case, tmp_path):
    simulated, replayed = _record_and_replay(case, tmp_path)
    assert simulated["outcome"] == "succeeded", simulated["reason"]
    assert (replayed["outcome"], replayed["reason"]) == (simulated["outcome"], simulated["reason"])
    # Every output the same, measurements within what the recording's millimetre depth
    # changes (the simulated camera had it unrounded): an object's pose within 1 cm (a cup's
    # yaw is arbitrary), registration figures (fitness, residual) within 20 %.
    assert _same(replayed["outputs"], simulated["outputs"]), (replayed["outputs"],
                                                              simulated["outputs"])


def _same(a, b) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, str) and isinstance(b, str) and a.startswith("Pose(") and b.startswith("Pose("):
        pa, pb = (np.array(re.findall(r"[xyz]=(-?[\d.e-]+)", v), dtype=float) for v in (a, b))
        return bool(np.abs(pa - pb).max() < 0.01)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return abs(a - b) <= 0.2 * max(abs(a), abs(b)) + 1e-3
    return a == b


def test_hearths_bag_reads_back_with_rosbags_and_the_mcap_tools(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    _record_and_replay(Case("turn_off_oven", seed=0), tmp_path)
    bag = tmp_path / "bag"
    with AnyReader([bag]) as r:                          # the rosbag2 directory
        types = {c.topic: c.msgtype for c in r.connections}
        counts = {c.topic: c.msgcount for c in r.connections}
    assert types["/camera/depth/image_raw"] == "sensor_msgs/msg/Image"
    assert types["/camera/color/camera_info"] == "sensor_msgs/msg/CameraInfo"
    assert types["/tf"] == types["/tf_static"] == "tf2_msgs/msg/TFMessage"
    assert types["/hearth/events"] == "hearth_msgs/msg/MissionEvent"
    assert types["/hearth/truth"] == "hearth_msgs/msg/GroundTruth"
    n = counts["/camera/depth/image_raw"]
    assert n >= 2 and counts["/camera/color/image_raw"] == counts["/hearth/truth"] == n
    (mcap_file,) = bag.glob("*.mcap")
    seen: dict[str, list] = {}
    with open(mcap_file, "rb") as f:                     # the MCAP tools, on the file inside
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            seen.setdefault(channel.topic, []).append((schema.name, decoded))
    depth = seen["/camera/depth/image_raw"][0][1]
    color = seen["/camera/color/image_raw"][0][1]
    assert (depth.encoding, color.encoding) == ("16UC1", "rgb8")
    assert depth.header.frame_id == color.header.frame_id == "camera_color_optical_frame"
    frames = {(t.header.frame_id, t.child_frame_id) for _, m in seen["/tf"] for t in m.transforms}
    assert frames == {("odom", "base_link"), ("base_link", "camera_color_optical_frame")}
    actions = [m for _, m in seen["/hearth/actions"]]
    assert any(a.action == "turn_knob" and a.status == "succeeded" for a in actions)
    kinds = {m.kind for _, m in seen["/hearth/events"]}
    assert {"run", "status", "feedback"} <= kinds
    ends = [json.loads(m.data_json) for _, m in seen["/hearth/events"] if m.kind == "run"]
    assert ends[-1]["state"] == "succeeded"
