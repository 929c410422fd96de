"""The one base of Hearth's exception families: an error that says where the problem is.

Each package has its own family (``hearth.worldmodel.errors.WorldError``,
``hearth.executive.errors.MissionError``, ``hearth.perception.errors.PerceptionError``,
``hearth.robot.errors.RobotError``, ``hearth.skills.errors.SkillError``); they all subclass
``HearthError``, which formats the one line the CLI prints (and exits 2 on):

- ``path:line: message`` for a problem in a file (line 0 when the line is not known;
  a family that sets ``file_line_optional`` prints ``path: message`` instead),
- ``node ID: message`` for a map node,
- ``message`` alone otherwise.

Importing this module is cheap (no third-party imports): the CLI catches ``HearthError``
before it has loaded any package.
"""
from __future__ import annotations

from typing import Optional


class HearthError(Exception):
    """A problem a user can act on; ``str(err)`` is one line saying where and what.

    ``file``/``line`` locate a problem in a file, ``node`` names a map node.
    """

    #: True: a file problem without a line prints ``path: message``, not ``path:0: message``.
    file_line_optional = False

    def __init__(self, message: str, *, file: Optional[str] = None, line: Optional[int] = None,
                 node: Optional[str] = None):
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.node = node

    def where(self) -> Optional[str]:
        """Where the problem is (``path:line``, ``node ID``), or None when nowhere in particular."""
        if self.file is not None:
            if self.line is None:
                return f"{self.file}" if self.file_line_optional else f"{self.file}:0"
            return f"{self.file}:{self.line}"
        if self.node is not None:
            return f"node {self.node}"
        return None

    def __str__(self) -> str:
        where = self.where()
        return self.message if where is None else f"{where}: {self.message}"


#: At most this many problems of one file are printed, one line each; a line after them says how
#: many more there are (a world of 300 copied rooms has 2,100 problems, all of one kind).
MOST_PROBLEMS_PRINTED = 50


def problem_lines(problems) -> str:
    """The problems of one file, one line each, at most ``MOST_PROBLEMS_PRINTED`` of them and a
    last line counting the rest (the full list stays on the exception's ``problems``)."""
    lines = [str(p) for p in problems[:MOST_PROBLEMS_PRINTED]]
    rest = len(problems) - len(lines)
    if rest > 0:
        lines.append(f"... and {rest} more problems ({len(problems)} in all)")
    return "\n".join(lines)
