"""A skill's feedback values through the command API: the event stream, a run's recent
events and its tree carry them as JSON values beside the sentence; a Pose it writes arrives
as its dict, not as Python text."""
from __future__ import annotations

import json

import httpx
import pytest
from py_trees import common

from hearth.executive.command.api import create_app
from hearth.executive.command.server import ServerThread, make_service
from hearth.executive.testing import Substitution, test_skills
from hearth.robot.clock import WallClock
from hearth.skills.base import Port, Skill
from hearth.worldmodel.pose import Pose

SENTENCE = "fridge registered 2.5 cm from the map (fitness 0.93)"


class Register(Skill):
    NAME = "Register"
    OUTPUTS = (Port("pose", "pose", required=False),)

    def update(self):
        self.set_output("pose", Pose(1.5, 2.0, 0.75, 0.0, 0.0, 0.5))
        self.report(SENTENCE, moved_cm=2.5, fitness=0.9312, parts=["door", "drawer"])
        return common.Status.SUCCESS


@pytest.fixture
def api(demo_world, tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "register.yaml").write_text(
        "hearth: 1\nname: register_test\ndescription: Register and report.\n"
        "tree: {skill: Register, name: register, outputs: {pose: fridge_pose}}\n")
    service = make_service(demo_world, None, [str(tmp_path / "m")],
                           skills={**test_skills(), "Register": Register},
                           make_skill=Substitution([], None), clock=WallClock(), tick_hz=50,
                           runs_dir=None)
    assert service.catalogue_problems == []
    thread = ServerThread(create_app(service)).start()
    client = httpx.Client(base_url=thread.url, timeout=30.0)
    yield client
    client.close()
    thread.stop()
    service.executive.shutdown()
    service.close()


def _stream(client, run_id):
    with client.stream("GET", "/api/events", params={"run": run_id, "since": 0,
                                                     "close_on_end": True}) as r:
        kind = None
        for line in r.iter_lines():
            if line.startswith("event: "):
                kind = line[7:]
            elif line.startswith("data: "):
                yield kind, json.loads(line[6:])


def test_the_stream_the_recent_events_and_the_tree_carry_feedback_values_as_values(api):
    run_id = api.post("/api/runs", json={"mission": "register_test"}).json()["run"]["id"]
    want = {"moved_cm": 2.5, "fitness": 0.9312, "parts": ["door", "drawer"]}
    streamed = [d for k, d in _stream(api, run_id) if k == "feedback"]
    assert [(d["message"], d["values"]) for d in streamed] == [(SENTENCE, want)]
    recent = api.get(f"/api/runs/{run_id}/events").json()["events"]
    assert [e["data"]["values"] for e in recent if e["event"] == "feedback"] == [want]
    node = api.get(f"/api/runs/{run_id}/tree").json()["root"]
    assert (node["feedback"], node["values"]) == (SENTENCE, want)
    # the blackboard write of a Pose: its dict (the monitor page reads no Python text)
    writes = [e["data"] for e in recent if e["event"] == "write"]
    pose = {"x": 1.5, "y": 2.0, "z": 0.75, "roll": 0.0, "pitch": 0.0, "yaw": 0.5}
    assert [(w["key"], w["value"]) for w in writes] == [("fridge_pose", pose)]
    assert api.get(f"/api/runs/{run_id}").json()["result"]["outputs"] == {"fridge_pose": pose}

