"""The world model's exception family: every error says where the problem is."""
from __future__ import annotations

from hearth.util.errors import HearthError, problem_lines


class WorldError(HearthError):
    """A problem with a world file or the map.

    ``file`` and ``line`` locate a problem in a file; ``node`` names a map node.
    ``str(err)`` is the one line the CLI prints: ``path:line: message`` or
    ``node ID: message`` (formatted by ``hearth.util.errors.HearthError``).
    """


class WorldValidationError(WorldError):
    """Several problems found while validating one file; each is a WorldError."""

    def __init__(self, problems: list[WorldError]):
        super().__init__(problems[0].message, file=problems[0].file, line=problems[0].line,
                         node=problems[0].node)
        self.problems = problems

    def __str__(self) -> str:
        return problem_lines(self.problems)


class UnknownNode(WorldError):
    """A query named a node id the map does not have."""
