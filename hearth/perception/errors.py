"""The perception package's exception family."""
from __future__ import annotations

from hearth.util.errors import HearthError


class PerceptionError(HearthError):
    """A perception step could not produce an answer (too little overlap, no data, stale model).

    ``node`` names the map node concerned when there is one; ``str(err)`` is one line
    (formatted by ``hearth.util.errors.HearthError``).
    """
