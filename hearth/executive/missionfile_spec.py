"""The compiled mission (what ``hearth.executive.missionfile.load_mission`` returns): a
``Mission`` of ``NodeSpec`` nodes with its parameters (``ParamSpec``), every reference
resolved; ``hearth.executive.tree`` builds a py_trees tree from it."""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from typing import Any

from hearth.executive.errors import MissionError
from hearth.executive.missionfile_refs import BBKey, Ref
from hearth.executive.missionfile_types import (
    _alternatives, check_value, _control_character, _is_number, plain, _short,
)


# ---------------------------------------------------------------------------------------
# The compiled mission
# ---------------------------------------------------------------------------------------
@dataclass
class ParamSpec:
    name: str
    type: str
    default: Any = None
    required: bool = True
    runtime: bool = False
    enum: list | None = None
    items: str | None = None
    description: str = ""
    line: int = 0
    minimum: float | None = None
    maximum: float | None = None
    kinds: list[str] | None = None       # map node kinds the value must name (at submit)
    having: list[str] | None = None      # kinds the named node must hold (an appliance's Knob)
    sentinels: list[str] | None = None   # values let through: the mission reads them itself
    pick_only: bool = False              # "": the only node of ``kinds`` in the map

    def check(self, value: Any) -> None:
        """Raise MissionError(param=name) unless ``value`` fits this parameter (type, items,
        enum, bounds; the map is checked by :meth:`check_in_map`)."""
        if not check_value(self.type, value):
            raise MissionError(f"expected {self.type}, got {_short(value)}", param=self.name)
        bad = _control_character(value)
        if bad is not None:
            raise MissionError(f"{_short(value)} holds the control character U+{ord(bad):04X}",
                               param=self.name)
        if self.items and isinstance(value, (list, tuple)):
            for item in value:
                if not check_value(self.items, item):
                    raise MissionError(f"expected a list of {self.items}, got item {_short(item)}",
                                       param=self.name)
        if self.enum is not None and value not in self.enum:
            raise MissionError(f"expected one of {_short(self.enum)}, got {_short(value)}",
                               param=self.name)
        if _is_number(value):
            if self.minimum is not None and value < self.minimum:
                raise MissionError(f"expected at least {self.minimum:g}, got {_short(value)}",
                                   param=self.name)
            if self.maximum is not None and value > self.maximum:
                raise MissionError(f"expected at most {self.maximum:g}, got {_short(value)}",
                                   param=self.name)

    def check_in_map(self, value: Any, world: Any) -> Any:
        """``value`` checked against the belief map ``world`` (a worldmodel World): the
        value to run with (``pick_only``: "" becomes the only matching node's id). Raises
        MissionError(param=name) in one line a person can act on: "no node 'nowhere' in the
        map", "mug_3 is a SmallObject, not a LargeArticulatedObject", "fridge holds no
        Knob", "nothing in the map matches 'zebra'". Values that are not strings are left to
        :meth:`check`."""
        if not self.kinds or world is None or not isinstance(value, str):
            return value
        if self.sentinels is not None and value in self.sentinels:
            return value
        if value == "" and self.pick_only:
            return self._only(world)
        if "node_id" in _alternatives(self.type):
            return self._node(value, world)
        # Words ("blue cup") or an id naming a node of these kinds.
        if value in world and world.get(value).kind in self.kinds:
            return value
        if not any(self._fits(m.node, world) for m in world.find(value, kinds=self.kinds)):
            raise MissionError(f"no {_or_kinds(self.kinds)} in the map matches {_short(value)}"
                               f"{self._examples(world)}", param=self.name)
        return value

    def _fits(self, node: Any, world: Any) -> bool:
        if node.kind not in self.kinds:
            return False
        if self.having:
            held = _held_kinds(node)
            return all(k in held for k in self.having)
        return True

    def _node(self, value: str, world: Any) -> str:
        if value not in world:
            raise MissionError(f"no node {_short(value)} in the map{self._examples(world)}",
                               param=self.name)
        node = world.get(value)
        if node.kind not in self.kinds:
            raise MissionError(f"{value} is a {node.kind}, not a {_or_kinds(self.kinds)}"
                               f"{self._examples(world)}", param=self.name)
        if not self._fits(node, world):
            missing = [k for k in self.having or () if k not in _held_kinds(node)]
            raise MissionError(f"{value} holds no {_or_kinds(missing)}{self._examples(world)}",
                               param=self.name)
        return value

    def _candidates(self, world: Any) -> list:
        return sorted((n for k in self.kinds for n in world.nodes(k) if self._fits(n, world)),
                      key=lambda n: n.id)

    def _examples(self, world: Any, most: int = 6) -> str:
        ids = [n.id for n in self._candidates(world)]
        if not ids:
            return ""
        shown = ", ".join(ids[:most]) + (f" and {len(ids) - most} more" if len(ids) > most else "")
        return f"; try one of: {shown}"

    def _only(self, world: Any) -> str:
        found = self._candidates(world)
        what = _or_kinds(self.kinds) + (f" with a {_or_kinds(self.having)}" if self.having else "")
        if not found:
            raise MissionError(f"the map has no {what}", param=self.name)
        if len(found) > 1:
            which = " or ".join(f"the {world.label(n.id)} ({n.id})" for n in found[:8])
            raise MissionError(f"which {what} do you mean: {which}? Name it: "
                               f"{self.name}={found[0].id}", param=self.name)
        return found[0].id


@dataclass
class NodeSpec:
    """One node of a compiled mission tree.

    ``path`` is unique in the tree (``/root/child/...``); ``attrs`` holds the kind's
    attributes (``reactive``, ``policy``, ``threshold``, ``times``, ``seconds``, ``expr``,
    ``source``, ``target``, ``until``, ``params``, ``message``, ``initial``, ``states``,
    ``outcomes``); a skill has ``skill`` (its class), ``inputs`` (port -> Ref) and
    ``outputs`` (port -> BBKey).
    """
    kind: str
    name: str
    path: str
    file: str
    line: int
    children: list["NodeSpec"] = field(default_factory=list)
    attrs: dict[str, Any] = field(default_factory=dict)
    skill: type | None = None
    skill_name: str = ""
    inputs: dict[str, Ref] = field(default_factory=dict)
    outputs: dict[str, BBKey] = field(default_factory=dict)

    def walk(self):
        yield self
        for child in self.children:
            yield from child.walk()

    @property
    def label(self) -> str:
        return f"{self.skill_name} {self.name}" if self.kind == "skill" and self.name != self.skill_name \
            else (self.skill_name if self.kind == "skill" else f"{self.kind} {self.name}")


@dataclass
class Mission:
    """A checked mission: parameters, initial blackboard, the compiled tree, declared keys."""
    name: str
    description: str
    file: str
    parameters: dict[str, ParamSpec]
    root: NodeSpec
    blackboard: dict[str, Any]
    key_types: dict[str, str]
    files: list[str]
    #: What a day's supervisor does with this mission after a higher priority event (low
    #: battery, an emergency) interrupted it (docs/day.md): ``{"then": "restart"}``, or
    #: ``{"then": "resume", "progress": KEY, "param": NAME}``: run it again with parameter
    #: NAME set to the value key KEY held when it was interrupted (the places done).
    interrupted: dict[str, str] = field(default_factory=lambda: {"then": "restart"})

    def nodes(self):
        return self.root.walk()

    def runtime_parameters(self) -> list[str]:
        return [p.name for p in self.parameters.values() if p.runtime]

    def resolve_parameters(self, given: dict[str, Any] | None = None,
                           runtime: dict[str, Any] | None = None) -> dict[str, Any]:
        """Parameter values for one run: ``given`` (submit keywords) over executive
        ``runtime`` values (for runtime parameters) over defaults. Checks types, unknown and
        missing parameters (MissionError with ``param``)."""
        given = dict(given or {})
        runtime = runtime or {}
        values: dict[str, Any] = {}
        for name in given:
            if name not in self.parameters:
                known = ", ".join(sorted(self.parameters)) or "none"
                raise MissionError(f"unknown parameter of mission {self.name} (known: {known})",
                                   param=name)
        for name, spec in self.parameters.items():
            if name in given:
                value = given[name]
            elif spec.runtime and name in runtime:
                value = runtime[name]
            elif spec.default is not None:
                value = plain(spec.default)
            elif spec.required:
                raise MissionError(f"required by mission {self.name} but not given", param=name)
            else:
                value = None
            if value is not None:
                spec.check(value)
            values[name] = value
        return values

    def resolve_in_map(self, given: dict[str, Any] | None, world: Any) -> dict[str, Any]:
        """``given`` checked against the belief map for every parameter that declares
        ``kinds`` (given or defaulted; runtime parameters are not: the executive checks
        their type, enum and bounds when they are set), with ``pick_only`` defaults filled
        in: what to submit. Raises
        MissionError(param=) at the first value the map refutes. No map: ``given`` as is."""
        out = dict(given or {})
        if world is None or not callable(getattr(world, "find", None)):
            return out
        with getattr(world, "lock", None) or contextlib.nullcontext():  # skills may be moving things
            for name, spec in self.parameters.items():
                if not spec.kinds:
                    continue
                if name in out:
                    out[name] = spec.check_in_map(out[name], world)
                elif spec.default is not None and not spec.runtime:
                    value = spec.check_in_map(plain(spec.default), world)
                    if value != spec.default:
                        out[name] = value
        return out


def _held_kinds(node: Any) -> set[str]:
    """The kinds of the map nodes ``node`` holds, at any depth. (World.descendants answers
    the same by walking the whole map, some 25 ms a node in a map of 10,000 objects; a
    submit asks it of every appliance.)"""
    out: set[str] = set()
    stack = [node]
    while stack:
        n = stack.pop()
        for attr in ("objects", "switches", "children", "handles", "knobs", "parts"):
            for child in getattr(n, attr, None) or ():
                out.add(child.kind)
                stack.append(child)
    return out


def _or_kinds(kinds: list[str]) -> str:
    return " or ".join(kinds)
