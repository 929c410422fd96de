"""The perception package's exception family."""
from __future__ import annotations


class PerceptionError(Exception):
    """A perception step could not produce an answer (too little overlap, no data, stale model).

    ``node`` names the map node concerned when there is one; ``str(err)`` is one line.
    """

    def __init__(self, message: str, *, node: str | None = None, file: str | None = None,
                 line: int | None = None):
        super().__init__(message)
        self.message = message
        self.node = node
        self.file = file
        self.line = line

    def __str__(self) -> str:
        if self.file is not None:
            return f"{self.file}:{self.line if self.line is not None else 0}: {self.message}"
        if self.node is not None:
            return f"node {self.node}: {self.message}"
        return self.message
