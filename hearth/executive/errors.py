"""The executive's exception family: mission files, parameters, running."""
from __future__ import annotations

from hearth.util.errors import HearthError, problem_lines


class MissionError(HearthError):
    """A problem with a mission file, its parameters or a run.

    ``file``/``line`` locate a problem in a mission file, ``param`` names a bad parameter;
    ``str(err)`` is the one line the CLI prints (``path:line: ...``, ``parameter P: ...``).
    """

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 param: str | None = None):
        super().__init__(message, file=file, line=line)
        self.param = param

    def where(self) -> str | None:
        if self.file is None and self.param is not None:
            return f"parameter {self.param}"
        return super().where()


class MissionValidationError(MissionError):
    """Several problems found while loading one mission; each is a MissionError."""

    def __init__(self, problems: list[MissionError]):
        first = problems[0]
        super().__init__(first.message, file=first.file, line=first.line, param=first.param)
        self.problems = problems

    def __str__(self) -> str:
        return problem_lines(self.problems)
