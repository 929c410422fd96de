"""Helpers for the mission tests: the skill registry, with stand-in declarations for skills
other engineers are still writing (same NAME; the ports the missions assume)."""
from __future__ import annotations

from pathlib import Path

import py_trees

from hearth.skills.base import Skill, registry

MISSIONS = Path(__file__).resolve().parents[2] / "missions"

# The ports the missions rely on; a real skill replaces its stand-in as soon as it lands.
ASSUMED: dict = {}


def _not_yet(self):
    self.feedback_message = f"{self.NAME} is not available yet"
    return py_trees.common.Status.FAILURE


def mission_skills() -> dict[str, type[Skill]]:
    found = dict(registry())
    for name, (inputs, outputs) in ASSUMED.items():
        if name not in found:
            found[name] = type(f"Pending{name}", (Skill,),
                               {"NAME": name, "INPUTS": inputs, "OUTPUTS": outputs,
                                "update": _not_yet, "__module__": "tests_missions_pending"})
    return found


