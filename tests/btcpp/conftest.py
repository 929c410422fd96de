"""Shared pieces for the BehaviorTree.CPP interchange tests: the shipped missions and a
scripted case that drives them through their branches (failures, then successes)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from hearth.executive.testing import MissionCase, Script
from hearth import missions_dir

MISSIONS = sorted(str(p) for p in Path(missions_dir()).glob("*.yaml")) + \
    [str(Path(missions_dir()) / "subtrees" / "search.yaml")]

PARAMS = {"fetch_object": {"object": "blue cup"}, "search_object": {"object": "blue cup"},
          "refine_localisation": {"at": "kitchen_table"},
          "deliver_reminder": {"text": "time for your pills"},
          "learn_object": {"name": "pill organiser"}}


def branching_case(mission: str) -> MissionCase:
    """First attempts fail, later ones succeed; outputs that steer the loops."""
    scripts = [
        Script("ResolveObject", outputs={"object_id": "blue_cup", "room": "kitchen",
                                         "label": "blue cup"}),
        Script("PlanSearch", outputs={"places": [{"place": "kitchen_table"},
                                                 {"place": "cupboard"}]}),
        Script("ClosedParts", outputs={"parts": ["door_1"], "count": 1}),
        Script("NavigateTo", outcomes=["failure", "success"], duration=0.3),
        Script("DetectObject", outcomes=["failure", "failure", "success"],
               outputs={"pose": {"x": 1.0, "y": 2.0}, "hypotheses": []}),
        Script("KnobsOn", outputs={"knobs": ["knob_1", "knob_2"], "count": 2}),
        Script("ReadKnobs", outcomes=["failure", "success"], outputs={"unknown": []}),
        Script("ExpectKnobsOff", outcomes=["failure", "success"]),
        Script("RefineLocalisation", outcomes=["failure", "failure", "success"],
               outputs={"correction": {"dx": 0.01, "dy": 0.0, "dyaw": 0.0}, "quality": 0.9}),
        Script("Grasp", outcomes=["failure", "success"]),
    ]
    return MissionCase(scripts=scripts, params=PARAMS.get(Path(mission).stem, {}))


def timeline(log_path: str) -> list[tuple]:
    """What a run did, in order: every status change and every write, by tick."""
    out = []
    for line in open(log_path, encoding="utf-8"):
        e = json.loads(line)
        if e["e"] == "status":
            out.append((e["tick"], "status", e["path"], e["status"], e.get("halted", False)))
        elif e["e"] == "write":
            out.append((e["tick"], "write", e["path"], e["port"], json.dumps(e["value"])))
        elif e["e"] == "run":
            out.append((e["tick"], "run", e["state"], e["reason"]))
    return out


@pytest.fixture(params=MISSIONS, ids=lambda p: Path(p).stem)
def shipped_mission(request) -> str:
    return request.param
