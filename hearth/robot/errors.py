"""The robot adapters' exception family."""
from __future__ import annotations

from hearth.util.errors import HearthError


class RobotError(HearthError):
    """A robot adapter could not do what it was asked (bad recording, no frame near a pose,
    an action that failed). ``file``/``line`` locate file problems; ``str(err)`` is one line
    (a recording's file without a line prints as ``path: message``)."""

    file_line_optional = True
