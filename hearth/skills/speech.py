"""Speaking to the user: ``Say`` and ``GiveUp``.

One skill speaks. ``Say`` fills a template and says it through the robot: the map-label fields
(``{object}``, ``{place}``, ``{part}``, ``{count}``, ``{places}``, ``{detail}``, ``{s}``) and
any ``values`` given; ``GiveUp`` says why a mission cannot go on and fails with that sentence,
so the mission's reason is a sentence a person can act on ("no blue cup at the 3 places
searched").

(Until 2026-12-07 there were two speaking skills, ``Say`` (a text with ``values``, spoken
whether or not there was a robot to speak through) and ``Tell`` (the map-label template,
spoken only when a robot was there). ``Tell`` was folded into ``Say``; a mission file that
says ``skill: Tell`` now says ``skill: Say`` with the same inputs.)
"""
from __future__ import annotations

from typing import Any

import py_trees

from hearth.skills.base import Port, Skill, words
from hearth.worldmodel.nodes import Knob

S = py_trees.common.Status


def _label(world, value: Any) -> str:
    """Words for a node id, a search place dict, a door {part, handle} or anything else."""
    if isinstance(value, dict):
        value = value.get("part") or value.get("place") or value.get("id") or value
    if isinstance(value, str) and world is not None and value in world:
        if isinstance(world.get(value), Knob):   # knobs have no name: "oven knob 2"
            return value.replace("_", " ")
        return world.label(value)
    if isinstance(value, dict):
        return "the position at {:.1f}, {:.1f}".format(float(value.get("x", 0.0)),
                                                        float(value.get("y", 0.0)))
    return "" if value is None else words(value)


def _join(words: list[str]) -> str:
    words = [w for w in words if w]
    if len(words) <= 1:
        return "".join(words)
    return ", ".join(words[:-1]) + " and " + words[-1]


class Say(Skill):
    """Say a sentence built from a template through ``robot.say`` (when there is a robot to
    say it; the sentence is the ``said`` output either way).

    Template fields: ``{object}``, ``{place}``, ``{part}`` (labels of node ids, search places
    or doors), ``{count}`` (a number, or a list's length), ``{places}`` (a list's labels
    joined: "the kitchen table, the side table and the cupboard"), ``{detail}`` (text, or a
    list joined with "; "), ``{s}`` ("s" unless count is 1: "{count} knob{s}"), and the keys
    of ``values``. A template that names a field it is not given is said as it is written."""

    NAME = "Say"
    DESCRIPTION = "say a sentence to the user, built from a template and map labels"
    INPUTS = (Port("text", "string"),
              Port("values", "dict", required=False, default=None,
                   description="fields for {name} placeholders in text"),
              Port("object", "any", required=False, default=None),
              Port("place", "any", required=False, default=None),
              Port("part", "any", required=False, default=None),
              Port("count", "any", required=False, default=None),
              Port("places", "list", required=False, default=None),
              Port("detail", "any", required=False, default=None),
              Port("say", "boolean", required=False, default=True))
    OUTPUTS = (Port("said", "string", required=False),)
    RESULT = S.SUCCESS

    def sentence(self) -> str:
        count = self.input("count")
        if isinstance(count, (list, tuple)):
            count = len(count)
        detail = self.input("detail")
        if isinstance(detail, (list, tuple)):
            detail = "; ".join(words(d) for d in detail if d)
        elif detail is not None and not isinstance(detail, str):
            detail = words(detail)
        places = self.input("places") or []
        fields = dict(object=_label(self.world, self.input("object")),
                      place=_label(self.world, self.input("place")),
                      part=_label(self.world, self.input("part")),
                      count=0 if count is None else count,
                      s="" if count == 1 else "s",
                      places=_join(["the " + _label(self.world, p) for p in places]),
                      detail=detail or "")
        fields.update({k: v if isinstance(v, (str, int, float)) else words(v)
                       for k, v in (self.input("values") or {}).items()})
        text = str(self.input("text"))
        try:
            text = text.format(**fields)
        except (KeyError, IndexError, ValueError):
            pass
        # A template whose {detail} came out empty leaves a dangling ": " or "; ".
        return text.strip().rstrip(" :;,")

    def update(self) -> S:
        text = self.sentence()
        if self.input("say") and self.robot is not None and hasattr(self.robot, "say"):
            self.robot.say(text)
        self.set_output("said", text)
        self.feedback_message = text
        return self.RESULT


class GiveUp(Say):
    """Tell the user why the mission cannot go on, then fail with that sentence (the mission's
    reason): "no blue cup at the 3 places searched"."""

    NAME = "GiveUp"
    DESCRIPTION = "say why the mission cannot go on, and fail with it"
    RESULT = S.FAILURE


__all__ = ["Say", "GiveUp"]
