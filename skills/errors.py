"""The skills package's exception family."""
from __future__ import annotations


class SkillError(Exception):
    """A skill was configured wrongly (bad input value, unknown map node)."""
