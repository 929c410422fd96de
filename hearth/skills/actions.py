"""A base for skills that run one long robot action (navigate, open a door, grasp).

The action starts in ``initialise``, is polled in ``update`` and is cancelled in
``terminate`` when the skill is halted, so a cancelled mission stops the robot.
"""
from __future__ import annotations

from typing import Any, Optional

import py_trees

from hearth.skills.base import Feedback, Skill, error_text, values_of


class RobotActionSkill(Skill):
    """Subclasses implement ``start()`` returning a robot Action (``status()``, ``cancel()``,
    ``progress``, ``reason``, ``result``) and may override ``succeeded(action)``."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.action: Optional[Any] = None
        #: why the action could not start: a sentence, with the values it was raised with
        self.error: Optional[Feedback] = None

    def start(self):  # pragma: no cover - abstract
        raise NotImplementedError

    def describe(self) -> str:
        return self.NAME

    def succeeded(self, action) -> None:
        """Write outputs after the action succeeded."""

    def failed(self, action) -> None:
        """Write outputs after the action failed (``action.reason`` says why)."""

    def initialise(self) -> None:
        self.action = None
        self.error = None
        try:
            self.action = self.start()
        except Exception as err:  # bad input, unknown node: fail this skill with the reason
            self.error = Feedback(error_text(err), values_of(err))

    def update(self) -> py_trees.common.Status:
        if self.error is not None:
            self.feedback_message = self.error
            return py_trees.common.Status.FAILURE
        status = self.action.status()
        if status == "running":
            progress = getattr(self.action, "progress", None)
            self.feedback_message = (f"{self.describe()}: {progress:.0%}" if progress is not None
                                     else f"{self.describe()}")
            return py_trees.common.Status.RUNNING
        if status == "succeeded":
            self.succeeded(self.action)
            self.feedback_message = f"{self.describe()}: done"
            return py_trees.common.Status.SUCCESS
        self.failed(self.action)
        self.feedback_message = (f"{self.describe()}: "
                                 f"{getattr(self.action, 'reason', '') or status}")
        return py_trees.common.Status.FAILURE

    def terminate(self, new_status: py_trees.common.Status) -> None:
        self._halted = None
        if (new_status == py_trees.common.Status.INVALID and self.action is not None
                and self.action.status() == "running"):
            self.action.cancel()
            self._halted = self.action
            self.feedback_message = f"{self.describe()}: cancelled"

    def is_halting(self) -> bool:
        """True while a cancelled action is still stopping (the base braking, the arm
        retracting): the executive reports the cancel only when it has stopped."""
        halted = getattr(self, "_halted", None)
        return halted is not None and halted.status() == "running"
