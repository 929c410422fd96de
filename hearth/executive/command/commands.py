"""An utterance -> a mission with parameters, or a clarifying answer.

"bring me the blue cup" matches the template ``bring me (the|my|a) {object:thing}`` of
fetch_object; the slot's words are looked up in the map (``world.find``) among the nodes of
the slot's class. Exactly one best match: its id becomes the parameter. Several equally good
matches ("bring me the cup" with a red and a blue cup) or none ("the green cup"): no mission
starts; the answer lists the candidates in words, and the dialogue layer asks the user.

Answers carry a HOBBIT-style text identifier (``text_id`` plus ``args``) as well as the
English sentence, so a dialogue layer can say them in its own language and social role.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hearth.executive.command.vocabulary import SLOT_CLASSES, Template, normalise, strip_courtesy
from hearth.executive.errors import MissionError
from hearth.executive.missionfile_types import parse_param_text

_STOP = {"the", "a", "an", "my", "me", "of", "please", "some", "your", "our", "this", "that"}


@dataclass
class Interpretation:
    """``outcome``: ``run`` (mission and params are set), ``clarify`` (an object was
    ambiguous or unknown: ``candidates``), ``not_understood`` (no template matched)."""
    outcome: str
    say: str
    text_id: str
    args: dict[str, Any] = field(default_factory=dict)
    mission: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    template: str | None = None
    slot: str | None = None
    words: str | None = None
    candidates: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items()}


def _describe(world: Any, node: Any) -> dict[str, Any]:
    label = world.label(node.id)
    try:
        where = world.describe_location(node.id)
    except Exception:  # noqa: BLE001 - a node without a room still has a name
        where = ""
    return {"id": node.id, "label": label, "where": where, "kind": node.kind}


def _phrase(c: dict[str, Any]) -> str:
    return f"the {c['label']}" + (f" {c['where']}" if c["where"] else "")


def _or_list(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


@dataclass
class _Resolution:
    value: Any = None
    problem: Interpretation | None = None


def resolve_slot(world: Any, words: str, cls: str, param: str) -> _Resolution:
    """The map node ``words`` names among ``cls`` nodes, or a clarifying answer."""
    words = " ".join(w for w in words.split() if w not in _STOP) or words
    kinds = SLOT_CLASSES[cls] or None
    matches = world.find(words, kinds=kinds) if world is not None else []
    if matches:
        from hearth.worldmodel.world import best_matches
        top = [m.node for m in best_matches(matches)]
        if len(top) == 1:
            return _Resolution(value=top[0].id)
        cands = [_describe(world, n) for n in top]
        return _Resolution(problem=Interpretation(
            outcome="clarify", text_id="T_CLARIFY_WHICH",
            say=f"Which {words} do you mean: {_or_list([_phrase(c) for c in cands])}?",
            args={"words": words, "candidates": [c["label"] for c in cands]},
            slot=param, words=words, candidates=cands))
    # Nothing has every word: offer what shares a word ("green cup" -> the cups we know).
    seen: dict[str, Any] = {}
    for tok in words.split():
        if tok in _STOP or world is None:
            continue
        for m in world.find(tok, kinds=kinds):
            seen.setdefault(m.node.id, m.node)
    cands = [_describe(world, n) for n in seen.values()][:8]
    if cands:
        say = f"I do not know a {words}. Do you mean {_or_list([_phrase(c) for c in cands])}?"
    else:
        say = f"I do not know a {words}."
    return _Resolution(problem=Interpretation(
        outcome="clarify", text_id="T_UNKNOWN_OBJECT", say=say,
        args={"words": words, "candidates": [c["label"] for c in cands]},
        slot=param, words=words, candidates=cands))


def _specificity(t: Template) -> int:
    """Literal characters in a template: the more, the more specific it is."""
    return len(t.source) - 40 * len(t.slots)


def interpret(text: str, templates: list[Template], world: Any,
              missions: dict[str, Any] | None = None) -> Interpretation:
    """Map ``text`` to a mission and parameters (see the module docstring).

    ``missions`` (name -> Mission) types the slots that are plain values."""
    said = strip_courtesy(normalise(text))
    matched: list[tuple[Template, dict[str, str]]] = []
    for t in sorted(templates, key=_specificity, reverse=True):
        slots = t.match(said)
        if slots is not None:
            matched.append((t, slots))
    first_problem: Interpretation | None = None
    for t, slots in matched:
        params = dict(t.params)
        problem = None
        for slot in t.slots:
            words = slots[slot.param]
            if slot.cls is not None:
                r = resolve_slot(world, words, slot.cls, slot.param)
                if r.problem is not None:
                    problem = r.problem
                    break
                params[slot.param] = r.value
            else:
                spec = missions[t.mission].parameters[slot.param] if missions else None
                try:
                    params[slot.param] = (parse_param_text(slot.param, spec.type, words)
                                          if spec is not None else words)
                    if spec is not None:
                        spec.check(params[slot.param])
                except MissionError as err:
                    problem = Interpretation(outcome="clarify", text_id="T_BAD_VALUE",
                                             say=f"I did not get the {slot.param}: {err.message}.",
                                             args={"param": slot.param, "words": words},
                                             slot=slot.param, words=words)
                    break
        if problem is None:
            return Interpretation(outcome="run", text_id="T_OK", say="OK.",
                                  mission=t.mission, params=params, template=t.text)
        if first_problem is None:
            problem.mission, problem.template = t.mission, t.text
            first_problem = problem
    if first_problem is not None:
        return first_problem
    examples = []
    seen_missions = set()
    for t in templates:
        if t.mission not in seen_missions:
            seen_missions.add(t.mission)
            examples.append(t.example(world))
    return Interpretation(outcome="not_understood", text_id="T_NOT_UNDERSTOOD",
                          say="Sorry, I did not understand."
                              + (f" You can say: {'; '.join(examples)}." if examples else ""),
                          args={"text": text, "examples": examples})
