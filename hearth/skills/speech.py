"""Speaking to the user."""
from __future__ import annotations

import py_trees

from hearth.skills.base import Port, Skill


class Say(Skill):
    """Say ``text`` through the robot (``{name}`` fields are filled from ``values``)."""

    NAME = "Say"
    DESCRIPTION = "say a text to the user"
    INPUTS = (Port("text", "string"),
              Port("values", "dict", required=False, default=None,
                   description="fields for {name} placeholders in text"))
    OUTPUTS = (Port("said", "string", required=False),)

    def update(self) -> py_trees.common.Status:
        text = str(self.input("text"))
        values = self.input("values") or {}
        try:
            text = text.format(**values)
        except (KeyError, IndexError, ValueError):
            pass
        self.robot.say(text)
        self.set_output("said", text)
        self.feedback_message = f"said: {text}"
        return py_trees.common.Status.SUCCESS
