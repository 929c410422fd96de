"""Foxglove: a WebSocket client speaking Foxglove's protocol, connected to `hearth run
--foxglove`, receives the channels and messages docs/ros2-foxglove.md lists; the same run
written with --foxglove-mcap reads back with the MCAP tools."""
from __future__ import annotations

import json
import struct
import subprocess
import sys
from collections import Counter

import pytest

from hearth.executive.foxglove import TOPICS

MISSION = "missions/turn_off_oven.yaml"
SCHEMAS = {"/hearth/log": "foxglove.Log", "/hearth/tree": "hearth.TreeStatus",
           "/robot/pose": "foxglove.PoseInFrame", "/tf": "foxglove.FrameTransforms",
           "/camera/color": "foxglove.RawImage", "/camera/depth": "foxglove.RawImage",
           "/camera/calibration": "foxglove.CameraCalibration",
           "/map/objects": "foxglove.SceneUpdate"}


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    from hearth.cli.main import main
    d = tmp_path_factory.mktemp("fg")
    assert main(["scenario", "make", "--seed", "5", "--out", str(d / "sc")]) == 0
    return d / "sc"


def test_a_foxglove_client_receives_every_documented_channel_live(scenario, tmp_path):
    from websockets.sync.client import connect

    cmd = [sys.executable, "-m", "hearth", "run", MISSION, "--scenario", str(scenario),
           "--world", str(scenario / "belief.xml"), "--runs-dir", str(tmp_path), "--quiet",
           "--foxglove", "0", "--foxglove-wait", "60"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        assert line.startswith("hearth: Foxglove live at ws://127.0.0.1:"), line
        port = int(line.split("127.0.0.1:")[1].split()[0])
        channels, topic_of, counts, trees, logs = {}, {}, Counter(), [], []
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"],
                     max_size=None, open_timeout=30) as ws:
            while True:
                m = ws.recv(timeout=60)
                if isinstance(m, str):
                    op = json.loads(m)
                    if op["op"] == "advertise":
                        channels.update({c["id"]: c for c in op["channels"]})
                        subs = [{"id": i, "channelId": cid} for i, cid in enumerate(channels, 1)]
                        topic_of = {s["id"]: channels[s["channelId"]]["topic"] for s in subs}
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    continue
                opcode, sub, _log_time = struct.unpack("<BIQ", m[:13])   # message data
                assert opcode == 1
                topic = topic_of[sub]
                counts[topic] += 1
                if topic == "/hearth/tree":
                    trees.append(json.loads(m[13:]))
                    if trees[-1]["state"] in ("succeeded", "failed"):
                        break
                elif topic == "/hearth/log":
                    logs.append(m[13:])
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
    advertised = {c["topic"]: c["schemaName"] for c in channels.values()}
    assert advertised == SCHEMAS and set(TOPICS) == set(SCHEMAS)
    assert all(counts[t] > 0 for t in SCHEMAS), counts
    assert counts["/camera/color"] == counts["/camera/depth"] == 4       # the run's captures
    end = trees[-1]
    assert end["mission"] == "turn_off_oven" and end["state"] == "succeeded"
    nodes = {n["path"]: n for n in end["nodes"]}
    assert nodes["/turn_off_oven"]["status"] == "SUCCESS"
    assert any("it is off now" in n["feedback"] for n in nodes.values())
    assert any(b"I turned off 1 knob of the oven" in payload for payload in logs)


def test_the_run_as_foxglove_mcap_reads_back_with_the_mcap_tools(scenario, tmp_path):
    from mcap.reader import make_reader

    from hearth.cli.main import main
    out = tmp_path / "run.mcap"
    assert main(["run", MISSION, "--scenario", str(scenario), "--world",
                 str(scenario / "belief.xml"), "--runs-dir", str(tmp_path), "--quiet",
                 "--foxglove-mcap", str(out)]) == 0
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        counts = {summary.channels[k].topic: v
                  for k, v in summary.statistics.channel_message_counts.items()}
        trees = [json.loads(m.data) for _, ch, m in reader.iter_messages(topics=["/hearth/tree"])]
    assert schemas == SCHEMAS
    assert all(counts.get(t, 0) > 0 for t in SCHEMAS), counts
    assert trees[-1]["state"] == "succeeded"
    # a scene entity per object of the map, sent whole at the start
    assert counts["/map/objects"] >= 1


def test_a_client_offering_only_foxglove_websocket_v1_gets_the_documented_answer(capsys):
    """foxglove-sdk serves foxglove.sdk.v1 only: an older client (Foxglove Studio,
    Lichtblick) is refused, and the user reads why in one line; the server's own
    "Dropping client" line goes to the log, not to the mission's output."""
    import asyncio
    import time

    websockets = pytest.importorskip("websockets")
    from hearth.executive.foxglove import OLD_SUBPROTOCOL, REFUSED_HANDSHAKE, FoxgloveSink

    sink = FoxgloveSink(port=0)
    lines = []
    sink.server_line = lambda level, name, text: lines.append(text)

    async def connect() -> str:
        try:
            async with websockets.connect(f"ws://127.0.0.1:{sink.port}",
                                          subprotocols=[OLD_SUBPROTOCOL], open_timeout=5):
                return "connected"
        except websockets.InvalidStatus as err:
            return f"refused {err.response.status_code}"
    try:
        assert asyncio.run(connect()) == "refused 400"
        t0 = time.monotonic()
        while not any("handshake failed" in t for t in lines) and time.monotonic() - t0 < 5:
            time.sleep(0.05)
    finally:
        sink.close()
    err = capsys.readouterr().err
    assert any("Dropping client" in t and "handshake failed" in t for t in lines)
    assert err.strip() == REFUSED_HANDSHAKE
    assert "Dropping client" not in err
