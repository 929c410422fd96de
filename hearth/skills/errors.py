"""The skills package's exception family."""
from __future__ import annotations

from hearth.util.errors import HearthError


class SkillError(HearthError):
    """A skill was configured wrongly (bad input value, unknown map node); ``node`` names
    the map node when there is one."""
