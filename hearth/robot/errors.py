"""The robot adapters' exception family."""
from __future__ import annotations


class RobotError(Exception):
    """A robot adapter could not do what it was asked (bad recording, no frame near a pose,
    an action that failed). ``file``/``line`` locate file problems; ``str(err)`` is one line."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 node: str | None = None):
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.node = node

    def __str__(self) -> str:
        if self.file is not None:
            loc = f"{self.file}:{self.line}" if self.line is not None else self.file
            return f"{loc}: {self.message}"
        if self.node is not None:
            return f"node {self.node}: {self.message}"
        return self.message
