"""Missions to and from BehaviorTree.CPP v4 XML (what Groot2 and Nav2 read and write).

``export_mission(path)`` writes a checked mission as BT.CPP v4 XML (``BTCPP_format="4"``):
one ``<BehaviorTree>`` for the mission and one per subtree it includes, ``{key}`` blackboard
remapping for inputs and outputs, and a ``<TreeNodesModel>`` with every skill's declared ports
(direction, type, default, description), the Hearth node types that BT.CPP has no equivalent
for (``ForEach``, ``Watch``, ``Guard``, ``Check``, ``StateMachine``/``State``, ``Succeed``,
``Fail``) and one ``<SubTree>`` model per tree carrying its parameters.

``import_tree(path)`` reads BT.CPP v4 XML back into a mission (YAML text) that is then
checked like any other mission. BT.CPP idioms with no Hearth node of their own are rewritten
into Hearth nodes (``LOWERED_PORTS``: Script and ScriptCondition for the script subset
Hearth's conditions carry, SetBlackboard, Precondition, Delay, Sleep, RunOnce, IfThenElse,
Switch2..6; the pre/post-condition attributes; ``_autoremap``). Every problem is a
:class:`~hearth.executive.errors.MissionError` with the XML file and line: a leaf that is no
registered skill, a port the skill does not declare (in the tree or in its Groot2 model), a
BT.CPP or Nav2 node Hearth does not map (each has its reason in ``REFUSED``), a script beyond
the subset, an XML entity or DTD, a syntax error.

``nodes_header()`` is the C++ header (hearth/executive/cpp/hearth_nodes.hpp) with Hearth's node
types for BT.CPP, which ``hearth export --nodes-header`` writes beside a mission.

The mapping is the table in docs/missions.md, "From and to BehaviorTree.CPP". Inside one
``<BehaviorTree>``, ``{name}`` is a port of that tree (a Hearth ``$parameter``) when the
tree's ``<SubTree>`` model declares it, and a blackboard key otherwise. Literals carry their
type through the port they feed: text as is, numbers and booleans as BT.CPP writes them,
lists, mappings and anything ambiguous as ``json:...`` (BT.CPP's JSON prefix).

``live_tree(mission)`` is the tree a running mission shows over the Groot2 protocol
(``hearth.executive.groot2``): the compiled tree with every include expanded, each node with its
``_uid``, as BT.CPP's ``WriteTreeToXML(tree, add_metadata=true)`` writes it.

The XML is read with lxml and never resolves entities, loads a DTD or touches the network
(as hearth/worldmodel/io.py reads world files); a file with a DOCTYPE is refused before parsing.
"""
from __future__ import annotations

import json
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import yaml
from lxml import etree

from hearth.executive.errors import MissionError, MissionValidationError
from hearth.executive.missionfile import KINDS as _KINDS_ALL
from hearth.executive.missionfile import (BBKey, Lit, Mission, NodeSpec, Param, compile_mission,
                                          load_mission, plain, skill_registry)
from hearth.executive.missionfile_format import IDENT
from hearth.executive.missionfile_yaml import LineDict, LineList, load_yaml, load_yaml_text

_KEY = re.compile(r"^\{(" + IDENT + r")\}$")
_PARAM = re.compile(r"^\$(" + IDENT + r")$")
#: Mission parameter keys carried on a SubTree model's ports as JSON attributes.
_CHECKS = ("minimum", "maximum", "kinds", "having", "sentinels", "pick_only")
_IDENT = re.compile(r"^" + IDENT + r"$")
# Operands of a condition, skipping quoted literals: {key} and $param are rewritten.
_EXPR_TOKEN = re.compile(r"'[^']*'|\"[^\"]*\"|\{(" + IDENT + r")\}|\$(" + IDENT + r")")

#: Hearth kind -> BT.CPP node (memory / reactive variants for sequence and selector).
SEQUENCE = {False: "Sequence", True: "ReactiveSequence"}
SELECTOR = {False: "Fallback", True: "ReactiveFallback"}
DECORATOR_TAGS = {"retry": "RetryUntilSuccessful", "timeout": "Timeout", "inverter": "Inverter",
                  "force_success": "ForceSuccess", "force_failure": "ForceFailure"}
#: BT.CPP nodes that import maps, with the ports each takes.
BUILTIN_PORTS: dict[str, tuple[str, ...]] = {
    "Sequence": (), "ReactiveSequence": (), "SequenceWithMemory": (),
    "Fallback": (), "ReactiveFallback": (),
    "Parallel": ("success_count", "failure_count"),
    "Inverter": (), "ForceSuccess": (), "ForceFailure": (),
    "RetryUntilSuccessful": ("num_attempts",), "Repeat": ("num_cycles",),
    "Timeout": ("msec",), "KeepRunningUntilFailure": (),
    "AlwaysSuccess": (), "AlwaysFailure": (),
}
BUILTIN_CONTROLS = {"Sequence", "ReactiveSequence", "SequenceWithMemory", "Fallback",
                    "ReactiveFallback", "Parallel"}

#: Hearth node types with no BT.CPP equivalent: (model element, ports).
#: A port is (direction, name, type, default, description).
CUSTOM: dict[str, tuple[str, tuple[tuple[str, str, str, str | None, str], ...]]] = {
    "ForEach": ("Decorator", (
        ("input_port", "in", "list", None, "the items: a {key}, a tree port or a json: list"),
        ("output_port", "as", "any", None, "the key each item is written to"),
        ("input_port", "until", "string", "failure",
         "failure: every item must succeed; success: stop at the first that succeeds"))),
    "Watch": ("Decorator", (
        ("input_port", "params", "string", None,
         "runtime parameters (;-separated): when one changes the child is halted and restarted"),)),
    "Guard": ("Decorator", (
        ("input_port", "while", "string", None,
         "a Hearth condition checked every tick; the child is halted and the guard fails "
         "when it stops holding"),)),
    "Check": ("Condition", (
        ("input_port", "expr", "string", None,
         "a Hearth condition: {key}, not {key}, or {key} OP value (== != < <= > >= in, not in)"),)),
    "StateMachine": ("Control", (
        ("input_port", "initial", "string", None, "the first state"),
        ("input_port", "outcomes", "string", None,
         "container outcome:status pairs (;-separated), status success or failure"))),
    "State": ("Decorator", (
        ("input_port", "transitions", "string", None,
         "outcome:target pairs (;-separated); a target is a state or a container outcome"),
        ("input_port", "outcome", "string", None,
         "after a success, the outcome is this key's value ({key})"))),
    "Succeed": ("Action", (("input_port", "message", "string", None, "feedback message"),)),
    "Fail": ("Action", (("input_port", "message", "string", None, "feedback message"),)),
}

#: Nodes import refuses, each with the reason (docs/missions.md has the same table).
REFUSED: dict[str, str] = {
    # Nav2 (nav2_behavior_tree)
    "RecoveryNode": "Nav2's RecoveryNode (retry the first child after the second recovers) has "
                    "no exact Hearth equivalent; write retry: {times: N} over a selector",
    "PipelineSequence": "Nav2's PipelineSequence (re-ticks every earlier child while a later "
                        "one runs) is not supported; use a reactive sequence",
    "RoundRobin": "Nav2's RoundRobin is not supported",
    "RateController": "Nav2's RateController (ticks its child at a rate) is not supported: "
                      "Hearth ticks the whole tree at the executive's rate",
    "DistanceController": "Nav2's DistanceController needs the robot's odometry in the tree; "
                          "not supported",
    "SpeedController": "Nav2's SpeedController is not supported",
    "GoalUpdater": "Nav2's GoalUpdater is not supported",
    "SingleTrigger": "Nav2's SingleTrigger is not supported",
    "PathLongerOnApproach": "Nav2's PathLongerOnApproach is not supported",
    # BehaviorTree.CPP built-ins without a Hearth mapping
    "WhileDoElse": "WhileDoElse is not supported; write a guard or a reactive selector",
    "ManualSelector": "ManualSelector is not supported",
    "TryCatch": "TryCatch is not supported; write a selector",
    "ParallelAll": "ParallelAll is not supported; use Parallel",
    "AsyncSequence": "AsyncSequence is not supported; use Sequence",
    "UnsetBlackboard": "UnsetBlackboard is not supported",
    "LoopInt": "Loop nodes are not supported; use ForEach (for_each)",
    "LoopDouble": "Loop nodes are not supported; use ForEach (for_each)",
    "LoopString": "Loop nodes are not supported; use ForEach (for_each)",
    "LoopBool": "Loop nodes are not supported; use ForEach (for_each)",
    "EntryUpdated": "EntryUpdated is not supported",
    "SkipUnlessUpdated": "SkipUnlessUpdated is not supported",
    "WaitValueUpdate": "WaitValueUpdate is not supported",
    "WasEntryUpdated": "WasEntryUpdated is not supported",
    "SubTreePlus": "SubTreePlus is BT.CPP v3; write <SubTree> with port remapping (v4)",
}
#: BT.CPP pre/post-condition attributes (scripts), in the order BT.CPP checks them.
PRE_ATTRS = ("_failureIf", "_successIf", "_skipIf", "_while")
POST_ATTRS = ("_onSuccess", "_onFailure", "_post", "_onHalted")
SCRIPT_ATTRS = PRE_ATTRS + POST_ATTRS
#: BT.CPP nodes import rewrites into Hearth nodes (docs/missions.md, "The mapping"), with
#: their ports.
LOWERED_PORTS: dict[str, tuple[str, ...]] = {
    "Script": ("code",), "ScriptCondition": ("code",), "SetBlackboard": ("value", "output_key"),
    "Precondition": ("if", "else"), "Delay": ("delay_msec",), "Sleep": ("msec",),
    "RunOnce": ("then_skip",), "IfThenElse": (),
    **{f"Switch{n}": ("variable",) + tuple(f"case_{i}" for i in range(1, n + 1))
       for n in range(2, 7)},
}
#: Parents under which BT.CPP's SKIPPED has a Hearth reading: a sequence passes over a
#: skipped child as over a success, a fallback as over a failure.
SKIP_AS = {"Sequence": "success", "ReactiveSequence": "success", "SequenceWithMemory": "success",
           "Fallback": "failure", "ReactiveFallback": "failure"}
#: Attributes that never are ports: Groot2's metadata and Hearth's comment.
META_ATTRS = ("_uid", "_fullpath", "_description")

BT_NAMES = set(BUILTIN_PORTS) | set(REFUSED) | set(LOWERED_PORTS) | {"SubTree", "Action", "Condition", "Control",
                                                "Decorator", "BehaviorTree", "root"}


# ---------------------------------------------------------------------------------------
# Literals through typed ports
# ---------------------------------------------------------------------------------------
def _alts(type_name: str) -> set[str]:
    return {t.strip() for t in str(type_name).split("|")}


def _textual(type_name: str) -> bool:
    return bool(_alts(type_name) & {"string", "node_id", "any"})


def _pointer_like(text: str) -> bool:
    # BT.CPP takes any value that starts with { and ends with } for a blackboard pointer.
    return len(text) >= 3 and text.startswith("{") and text.endswith("}")


def encode_literal(value: Any, type_name: str = "any") -> str:
    """A Hearth literal as the text of a BT.CPP port of Hearth type ``type_name``."""
    if isinstance(value, str):
        if _textual(type_name) and not _pointer_like(value) and not value.startswith("json:"):
            return value
        return "json:" + json.dumps(value, ensure_ascii=False)
    if isinstance(value, (bool, int, float)) and not _textual(type_name):
        return json.dumps(value)
    return "json:" + json.dumps(value, ensure_ascii=False)


def decode_literal(text: str, type_name: str = "any") -> Any:
    """The inverse of :func:`encode_literal`, lenient with BT.CPP's own spellings
    (``True``, ``1;2;3`` for a list). ValueError when the text cannot be read."""
    if text.startswith("json:"):
        try:
            return json.loads(text[5:])
        except json.JSONDecodeError as err:
            raise ValueError(f"cannot read {text!r} as JSON: {err.msg}") from None
    if _textual(type_name):
        return text
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        pass
    if "list" in _alts(type_name) and ";" in text:
        return [t for t in text.split(";")]
    try:
        return plain(yaml.safe_load(text))
    except yaml.YAMLError:
        raise ValueError(f"cannot read {text!r} as {type_name}") from None


# ---------------------------------------------------------------------------------------
# BT.CPP scripts (Script, ScriptCondition, pre/post conditions): the subset Hearth reads
# ---------------------------------------------------------------------------------------
# BT.CPP's scripting language (docs "Introduction to Scripting") is read as far as Hearth's
# own nodes can carry it: assignments of a literal or of another entry (SetValue), and
# conditions made of comparisons, ! and the && / || joins (Check). Arithmetic, parentheses,
# the ternary operator, enums and root-blackboard entries (@key) are refused with the line.
_SCRIPT_TOKEN = re.compile(r"""\s*(?:(?P<str>'[^']*'|"[^"]*")"""
                           r"""|(?P<num>-?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+))"""
                           r"""|(?P<id>@?[A-Za-z_][A-Za-z0-9_]*)"""
                           r"""|(?P<op>:=|==|!=|<=|>=|&&|\|\||[-+*/]=|[=<>!;()+\-*/?:~^&|]))""")
_COMPARE = ("==", "!=", "<", "<=", ">", ">=")


@dataclass(frozen=True)
class _Tok:
    kind: str       # str, num, id, op
    text: str


def _script_tokens(code: str) -> list[_Tok]:
    out, pos = [], 0
    code = code.rstrip()
    while pos < len(code):
        m = _SCRIPT_TOKEN.match(code, pos)
        if not m or m.end() == pos:
            raise ValueError(f"cannot read {code[pos:].strip()[:20]!r}")
        kind = m.lastgroup
        out.append(_Tok(kind, m.group(kind)))
        pos = m.end()
    return out


def _script_literal(tok: _Tok) -> Any:
    if tok.kind == "str":
        return tok.text[1:-1]
    if tok.kind == "num":
        value = float(tok.text)
        return int(value) if value.is_integer() and not any(c in tok.text for c in ".eE") \
            else value
    return tok.text == "true"


def _is_literal(tok: _Tok) -> bool:
    return tok.kind in ("str", "num") or (tok.kind == "id" and tok.text in ("true", "false"))


def _no_root(tok: _Tok) -> None:
    if tok.kind == "id" and tok.text.startswith("@"):
        raise ValueError(f"{tok.text}: root-blackboard entries have no Hearth equivalent; "
                         "pass the value through the subtree's ports")


def script_assignments(code: str) -> list[tuple[str, Any]]:
    """``a := 1; b = 'x'; c := d`` -> [(key, value)], a value being a Python literal or
    ``{key}`` for another entry. ValueError (what cannot be read) otherwise."""
    out = []
    for stmt in _statements(_script_tokens(code)):
        if len(stmt) == 3 and stmt[0].kind == "id" and stmt[1].text in (":=", "="):
            target, value = stmt[0], stmt[2]
            _no_root(target)
            _no_root(value)
            if _is_literal(value):
                out.append((target.text, _script_literal(value)))
                continue
            if value.kind == "id":
                out.append((target.text, "{" + value.text + "}"))
                continue
        text = " ".join(t.text for t in stmt)
        raise ValueError(f"cannot read {text!r}: Hearth reads assignments of a literal or of "
                         "another entry (key := 1; key := 'text'; key := other)")
    if not out:
        raise ValueError("an empty script")
    return out


def _statements(tokens: list[_Tok]) -> list[list[_Tok]]:
    out: list[list[_Tok]] = [[]]
    for t in tokens:
        if t.text == ";" and t.kind == "op":
            out.append([])
        else:
            out[-1].append(t)
    return [s for s in out if s]


def script_condition(code: str) -> str:
    """A BT.CPP boolean script (``A == 1 && name != 'john' || !done``) as a Hearth condition
    (``{A} == 1 && {name} != 'john' || not {done}``). ValueError beyond that subset."""
    stmts = _statements(_script_tokens(code))
    if len(stmts) != 1:
        raise ValueError("a condition is one expression (no ';')")
    parts: list[list[_Tok]] = [[]]
    joins: list[str] = []
    for t in stmts[0]:
        if t.kind == "op" and t.text in ("&&", "||"):
            parts.append([])
            joins.append(t.text)
        else:
            parts[-1].append(t)

    def operand(tok: _Tok) -> str:
        _no_root(tok)
        if tok.kind == "id" and tok.text not in ("true", "false"):
            return "{" + tok.text + "}"
        if tok.kind == "str":
            return "'" + tok.text[1:-1] + "'" if "'" not in tok.text[1:-1] else tok.text
        return tok.text

    out = []
    for part in parts:
        text = " ".join(t.text for t in part)
        if len(part) == 1 and part[0].kind in ("id", "str", "num"):
            out.append(operand(part[0]))
        elif len(part) == 2 and part[0].text == "!" and part[1].kind == "id":
            out.append("not " + operand(part[1]))
        elif len(part) == 3 and part[1].kind == "op" and part[1].text in _COMPARE \
                and part[0].kind != "op" and part[2].kind != "op":
            out.append(f"{operand(part[0])} {part[1].text} {operand(part[2])}")
        else:
            raise ValueError(f"cannot read {text or code!r}: Hearth reads comparisons "
                             "(== != < <= > >=), ! and && / || (no arithmetic, no parentheses)")
    text = out[0]
    for j, o in zip(joins, out[1:]):
        text += f" {j} {o}"
    return text


# ---------------------------------------------------------------------------------------
# Export
# ---------------------------------------------------------------------------------------
def _default_name(data: LineDict, kind: str) -> str:
    """What the mission compiler names a node that has no ``name:`` (one fact: mirrors
    hearth.executive.missionfile._Compiler.node)."""
    value = data[kind]
    if kind == "skill" and isinstance(value, str):
        return value
    if kind == "include" and isinstance(value, str):
        return value.rsplit("#", 1)[-1].rsplit("/", 1)[-1].removesuffix(".yaml")
    return kind


def _kind(data: LineDict) -> str:
    from hearth.executive.missionfile import KINDS
    return next(k for k in data if k in KINDS)


@dataclass
class _Scope:
    """One tree being exported: the mission's, or a subtree's."""
    file: str
    doc: LineDict
    params: dict[str, Any]          # declared parameters: name -> raw spec
    rename: dict[str, str]          # key -> exported key (a key that is also a parameter)


class _Exporter:
    def __init__(self, mission: Mission, skills: dict[str, type], palette: bool):
        self.mission = mission
        self.skills = skills
        self.palette = palette
        self.reserved = set(skills) | BT_NAMES | set(CUSTOM)
        self.ids: dict[tuple[str, str | None], str] = {}
        self.used_ids: set[str] = set()
        self.trees: list[tuple[str, etree._Element]] = []
        self.models: dict[str, etree._Element] = {}
        self.done: set[tuple[str, str | None]] = set()
        self.used_skills: set[str] = set()
        self.used_custom: set[str] = set()
        self.written: dict[tuple[str, str | None], set[str]] = {}
        self._docs: dict[str, LineDict] = {}

    def load(self, file: str) -> LineDict:
        if file not in self._docs:
            self._docs[file] = load_yaml(file)
        return self._docs[file]

    # -- trees --------------------------------------------------------------------------
    def run(self) -> str:
        main = (self.mission.file, None)
        doc = self.load(self.mission.file)
        name = self.mission.name
        if name in self.reserved:
            raise MissionError(f"mission name {name!r} is also a node type; BehaviorTree.CPP "
                               "needs tree IDs distinct from node names", file=self.mission.file,
                               line=doc.key_lines.get("name", 1))
        self.ids[main] = name
        self.used_ids.add(name)
        self.emit(main)
        for sub in (doc.get("subtrees") or {}):
            if (self.mission.file, sub) not in self.done:
                self.tree_id(self.mission.file, sub)
                self.emit((self.mission.file, sub))
        return self.document()

    def tree_id(self, file: str, sub: str | None) -> str:
        key = (file, sub)
        if key not in self.ids:
            base = sub if sub is not None else str(self.load(file).get("name") or Path(file).stem)
            cand, n = base, 2
            while cand in self.used_ids or cand in self.reserved:
                cand, n = f"{base}_{n}", n + 1
            self.ids[key] = cand
            self.used_ids.add(cand)
        return self.ids[key]

    def body(self, key: tuple[str, str | None]) -> tuple[LineDict, LineDict]:
        file, sub = key
        doc = self.load(file)
        return (doc if sub is None else doc["subtrees"][sub]), doc

    def emit(self, key: tuple[str, str | None]) -> None:
        if key in self.done:
            return
        self.done.add(key)
        body, doc = self.body(key)
        tid = self.ids[key]
        params = dict(body.get("parameters") or {})
        scope = _Scope(file=key[0], doc=doc, params=params, rename={})
        scope.rename = self.renames(body["tree"], scope, body.get("blackboard") if key[1] is None
                                    else None)
        tree = etree.Element("BehaviorTree", ID=tid)
        if body.get("description"):
            tree.set("_description", str(body["description"]))
        pending: list[tuple[str, str | None]] = []
        root_default = self.mission.name if key == (self.mission.file, None) else None
        tree.append(self.node(body["tree"], scope, pending, root_default, tid))
        self.trees.append((tid, tree))
        self.models[tid] = self.tree_model(tid, key, body, scope)
        for k in pending:
            self.emit(k)

    def tree_model(self, tid: str, key, body: LineDict, scope: _Scope) -> etree._Element:
        model = etree.Element("SubTree", ID=tid)
        written = self.written_params(key)
        for pname, spec in scope.params.items():
            direction = "inout_port" if pname in written else "input_port"
            port = etree.SubElement(model, direction, name=str(pname))
            ptype = spec.get("type", "any")
            port.set("type", ptype)
            if spec.get("default") is not None:
                port.set("default", encode_literal(plain(spec["default"]), ptype))
            if spec.get("required") is False:
                port.set("required", "false")
            if spec.get("runtime"):
                port.set("runtime", "true")
            if spec.get("enum") is not None:
                port.set("enum", json.dumps(plain(spec["enum"]), ensure_ascii=False))
            if spec.get("items"):
                port.set("items", str(spec["items"]))
            for attr in _CHECKS:            # what submit checks against the map, and bounds
                if spec.get(attr) is not None:
                    port.set(attr, json.dumps(plain(spec[attr]), ensure_ascii=False))
            if spec.get("description"):
                port.text = str(spec["description"])
        meta = {}
        if key[1] is None:
            if body.get("utterances"):
                meta["utterances"] = "json:" + json.dumps(plain(body["utterances"]),
                                                          ensure_ascii=False)
            if body.get("interrupted") is not None:     # docs/day.md
                how = plain(body["interrupted"])
                if isinstance(how, dict) and how.get("progress"):
                    how["progress"] = scope.rename.get(how["progress"], how["progress"])
                meta["interrupted"] = "json:" + json.dumps(how, ensure_ascii=False)
            if body.get("blackboard"):
                values = {scope.rename.get(str(k), str(k)): plain(v)
                          for k, v in body["blackboard"].items()}
                meta["blackboard"] = "json:" + json.dumps(values, ensure_ascii=False)
        if meta:
            fields = etree.SubElement(model, "MetadataFields")
            for k, v in meta.items():
                etree.SubElement(fields, "Metadata", {k: v})
        return model

    def written_params(self, key) -> set[str]:
        """Parameters a tree writes (directly, or through an include): BT.CPP inout ports."""
        if key in self.written:
            return self.written[key]
        self.written[key] = set()
        body, doc = self.body(key)
        out: set[str] = set()
        for data, kind in _nodes(body["tree"]):
            if kind == "skill":
                for v in (data.get("outputs") or {}).values():
                    m = _PARAM.match(str(v))
                    if m:
                        out.add(m.group(1))
            elif kind == "include":
                target = self.resolve(key[0], data["include"])
                inner = self.written_params(target)
                for p, v in (data.get("params") or {}).items():
                    m = _PARAM.match(str(v)) if isinstance(v, str) else None
                    if m and p in inner:
                        out.add(m.group(1))
        self.written[key] = out
        return out

    def resolve(self, file: str, target: str) -> tuple[str, str | None]:
        """An include target as (file, subtree), resolved as the mission compiler does."""
        if "#" in target or target.endswith((".yaml", ".yml")):
            fpart, _, sub = target.partition("#")
            path = file
            if fpart:
                path = str((Path(file).parent / fpart).resolve())
                try:
                    path = str(Path(path).relative_to(Path.cwd()))
                except ValueError:
                    pass
            return path, (sub or None)
        return file, target

    def renames(self, tree: Any, scope: _Scope, blackboard: Any) -> dict[str, str]:
        """Keys that share a name with a parameter get another name: in BT.CPP both are
        entries of the tree's blackboard."""
        keys: set[str] = set(str(k) for k in (blackboard or {}))

        def ref(value: Any) -> None:
            if isinstance(value, str):
                m = _KEY.match(value)
                if m:
                    keys.add(m.group(1))

        for data, kind in _nodes(tree):
            if kind == "skill":
                for v in (data.get("inputs") or {}).values():
                    ref(v)
                for v in (data.get("outputs") or {}).values():
                    if not _PARAM.match(str(v)):
                        keys.add(str(v).strip("{}"))
            elif kind == "include":
                for v in (data.get("params") or {}).values():
                    ref(v)
            elif kind == "for_each":
                ref(data["in"])
                keys.add(str(data["as"]))
            elif kind in ("condition", "guard"):
                text = data["condition"] if kind == "condition" else data["while"]
                for m in _EXPR_TOKEN.finditer(str(text)):
                    if m.group(1):
                        keys.add(m.group(1))
            elif kind == "state_machine":
                for st in data["state_machine"]["states"].values():
                    if "outcome" in st:
                        ref(st["outcome"])
        out = {}
        taken = keys | set(scope.params)
        for k in sorted(keys & set(scope.params)):
            new = f"{k}_key"
            while new in taken:
                new += "_"
            taken.add(new)
            out[k] = new
        return out

    # -- nodes --------------------------------------------------------------------------
    def value(self, value: Any, scope: _Scope, type_name: str) -> str:
        if isinstance(value, str):
            m = _KEY.match(value)
            if m:
                return "{" + scope.rename.get(m.group(1), m.group(1)) + "}"
            m = _PARAM.match(value)
            if m:
                return "{" + m.group(1) + "}"
        return encode_literal(plain(value), type_name)

    def key(self, name: str, scope: _Scope) -> str:
        m = _PARAM.match(name)
        if m:
            return "{" + m.group(1) + "}"
        name = name.strip("{}")
        return "{" + scope.rename.get(name, name) + "}"

    def expr(self, text: str, scope: _Scope) -> str:
        def sub(m: re.Match) -> str:
            if m.group(1):
                return "{" + scope.rename.get(m.group(1), m.group(1)) + "}"
            if m.group(2):
                return "{" + m.group(2) + "}"
            return m.group(0)
        return _EXPR_TOKEN.sub(sub, str(text))

    def node(self, data: LineDict, scope: _Scope, pending: list, root_default: str | None,
             tid: str) -> etree._Element:
        kind = _kind(data)
        hearth_name = str(data.get("name") or root_default or _default_name(data, kind))
        attrs: dict[str, str] = {}
        children: list[Any] = _children(data, kind)
        if kind == "sequence":
            tag = SEQUENCE[bool(data.get("reactive", False))]
        elif kind == "selector":
            tag = SELECTOR[bool(data.get("reactive", False))]
        elif kind == "parallel":
            tag = "Parallel"
            n = len(data["parallel"])
            policy = data.get("policy", "all")
            need = n if policy == "all" else 1 if policy == "one" else int(data["threshold"])
            if need >= n:
                attrs.update(success_count="-1", failure_count="1")
            elif need == 1:
                attrs.update(success_count="1", failure_count="-1")
            else:
                attrs.update(success_count=str(need), failure_count=str(n - need + 1))
        elif kind == "retry":
            tag, attrs["num_attempts"] = "RetryUntilSuccessful", str(int(data["times"]))
        elif kind == "timeout":
            tag, attrs["msec"] = "Timeout", str(int(round(float(data["seconds"]) * 1000)))
        elif kind == "repeat":
            times = int(data.get("times", -1))
            # Hearth repeats once per tick, as KeepRunningUntilFailure does; BT.CPP's Repeat
            # loops within one tick while the child finishes at once.
            if times < 0:
                tag = "KeepRunningUntilFailure"
            else:
                tag, attrs["num_cycles"] = "Repeat", str(times)
        elif kind in DECORATOR_TAGS:
            tag = DECORATOR_TAGS[kind]
        elif kind == "for_each":
            tag = "ForEach"
            attrs["in"] = self.value(data["in"], scope, "list")
            attrs["as"] = self.key(str(data["as"]), scope)
            if data.get("until", "failure") != "failure":
                attrs["until"] = str(data["until"])
        elif kind == "watch":
            tag = "Watch"
            attrs["params"] = ";".join(str(p).lstrip("$") for p in data["params"])
        elif kind == "guard":
            tag, attrs["while"] = "Guard", self.expr(data["while"], scope)
        elif kind == "condition":
            tag, attrs["expr"] = "Check", self.expr(data["condition"], scope)
        elif kind in ("succeed", "fail"):
            message = data.get(kind) or ""
            if message:
                tag, attrs["message"] = kind.capitalize(), str(message)
            else:
                tag = "AlwaysSuccess" if kind == "succeed" else "AlwaysFailure"
        elif kind == "skill":
            tag = str(data["skill"])
            cls = self.skills[tag]
            self.used_skills.add(tag)
            for port, value in (data.get("inputs") or {}).items():
                p = cls.port(port)
                attrs[str(port)] = self.value(value, scope, p.type if p else "any")
            for port, value in (data.get("outputs") or {}).items():
                attrs[output_port_name(cls, str(port))] = self.key(str(value), scope)
        elif kind == "include":
            tag = "SubTree"
            target = self.resolve(scope.file, str(data["include"]))
            sub_id = self.tree_id(*target)
            if target not in self.done and target not in pending:
                pending.append(target)
            attrs["ID"] = sub_id
            body, _ = self.body(target)
            declared = body.get("parameters") or {}
            given = data.get("params") or {}
            for pname, value in given.items():
                ptype = (declared.get(pname) or {}).get("type", "any")
                attrs[str(pname)] = self.value(value, scope, ptype)
            for pname, spec in declared.items():
                # BT.CPP takes an empty default for "no default": say "" explicitly.
                if pname not in given and spec.get("default") == "":
                    attrs[str(pname)] = ""
        elif kind == "state_machine":
            tag = "StateMachine"
            sm = data["state_machine"]
            attrs["initial"] = str(sm["initial"])
            attrs["outcomes"] = _pairs(sm["outcomes"])
        else:  # pragma: no cover - KINDS and this function change together
            raise MissionError(f"cannot export node kind {kind!r}", file=scope.file,
                               line=data.line)
        if tag in CUSTOM:
            self.used_custom.add(tag)
        default = (attrs.get("ID") if kind == "include" else tag if kind == "skill"
                   else root_default or kind)
        el = etree.Element(tag)
        if kind == "include":
            el.set("ID", attrs.pop("ID"))
        if hearth_name != default:
            el.set("name", hearth_name)
        for k, v in attrs.items():
            el.set(k, v)
        if data.get("comment"):
            el.set("_description", str(data["comment"]))
        if kind == "state_machine":
            self.used_custom.add("State")
            for sname, st in data["state_machine"]["states"].items():
                state = etree.SubElement(el, "State", name=str(sname))
                state.set("transitions", _pairs(st["transitions"]))
                if "outcome" in st:
                    state.set("outcome", self.key(str(st["outcome"]), scope))
                state.append(self.node(st["do"], scope, pending, None, tid))
        else:
            for child in children:
                el.append(self.node(child, scope, pending, None, tid))
        return el

    # -- the document -------------------------------------------------------------------
    def document(self) -> str:
        root = etree.Element("root", BTCPP_format="4", main_tree_to_execute=self.mission.name)
        for _, tree in self.trees:
            root.append(tree)
        models = etree.SubElement(root, "TreeNodesModel")
        skills = sorted(self.skills) if self.palette else sorted(self.used_skills)
        custom = sorted(CUSTOM) if self.palette else sorted(self.used_custom)
        entries = [(n, skill_model(self.skills[n])) for n in skills]
        entries += [(n, custom_model(n)) for n in custom]
        entries += [(tid, self.models[tid]) for tid, _ in self.trees]
        for _, el in sorted(entries, key=lambda e: (e[1].tag, e[0])):
            models.append(el)
        etree.indent(root, space="  ")
        return etree.tostring(root, xml_declaration=True, encoding="UTF-8").decode("utf-8") + "\n"


def _nodes(data: Any) -> Iterator[tuple[dict, str]]:
    """Every node (a dict) of a mission tree with its kind, parents before children."""
    if not isinstance(data, dict):
        return
    kind = _kind(data)
    yield data, kind
    for child in _children(data, kind):
        yield from _nodes(child)


def _children(data: dict, kind: str) -> list:
    if kind in ("sequence", "selector", "parallel"):
        return list(data[kind])
    if kind in ("retry", "timeout", "repeat", "inverter", "force_success", "force_failure",
                "for_each", "guard", "watch"):
        return [data[kind]]
    if kind == "state_machine":
        return [st["do"] for st in data["state_machine"]["states"].values()]
    return []


def _pairs(mapping: dict) -> str:
    items = [(str(k), str(v)) for k, v in mapping.items()]
    if all(_IDENT.match(k) and _IDENT.match(v) for k, v in items):
        return ";".join(f"{k}:{v}" for k, v in items)
    return "json:" + json.dumps(dict(items), ensure_ascii=False)


def _read_pairs(text: str) -> dict[str, str]:
    if text.startswith("json:"):
        value = json.loads(text[5:])
        if not isinstance(value, dict):
            raise ValueError("expected a JSON object")
        return {str(k): str(v) for k, v in value.items()}
    out = {}
    for part in filter(None, (p.strip() for p in text.split(";"))):
        k, sep, v = part.partition(":")
        if not sep or not k.strip() or not v.strip():
            raise ValueError(f"expected name:target pairs separated by ';', got {part!r}")
        out[k.strip()] = v.strip()
    return out


def output_port_name(cls: type, port: str) -> str:
    """The name a skill output has in BT.CPP: its own, or ``NAME_out`` when the skill also
    has an input called NAME (BT.CPP gives a port one name and one direction)."""
    inputs = {p.name for p in cls.INPUTS}
    name = port
    while name in inputs:
        name = f"{name}_out" if name == port else name + "_"
    return name


def skill_model(cls: type) -> etree._Element:
    """A skill's ``<Action>`` model: its declared ports, as BT.CPP's writeTreeNodesModelXML
    writes them (type, default, description as the element text)."""
    el = etree.Element("Action", ID=cls.NAME)
    for direction, ports in (("input_port", cls.INPUTS), ("output_port", cls.OUTPUTS)):
        for p in ports:
            pname = p.name if direction == "input_port" else output_port_name(cls, p.name)
            port = etree.SubElement(el, direction, name=pname, type=p.type)
            if p.default is not None:
                port.set("default", encode_literal(p.default, p.type))
            if direction == "input_port" and not p.required and p.default is None:
                port.set("required", "false")
            if p.description:
                port.text = p.description
    doc = (cls.__doc__ or "").strip().split("\n\n")[0]
    if doc:
        fields = etree.SubElement(el, "MetadataFields")
        etree.SubElement(fields, "Metadata", description=" ".join(doc.split()))
    return el


def custom_model(tag: str) -> etree._Element:
    kind, ports = CUSTOM[tag]
    el = etree.Element(kind, ID=tag)
    for direction, name, type_name, default, description in ports:
        port = etree.SubElement(el, direction, name=name, type=type_name)
        if default is not None:
            port.set("default", default)
        port.text = description
    return el


def nodes_header() -> str:
    """The C++ header with Hearth's node types for BehaviorTree.CPP (Check, Guard, Watch,
    ForEach, StateMachine/State, Succeed, Fail and the generic SetValue and Wait skills), so
    that an exported mission runs in a BT.CPP application as it is."""
    from importlib import resources
    return resources.files("hearth.executive").joinpath("cpp/hearth_nodes.hpp").read_text("utf-8")


def export_mission(path: str | Path, skills: dict[str, type] | None = None,
                   palette: bool = False) -> str:
    """The mission at ``path`` (checked first) as BT.CPP v4 XML text. ``palette``: put
    every registered skill in the TreeNodesModel, not only those the mission uses."""
    skills = skills if skills is not None else skill_registry()
    mission = load_mission(path, skills)
    return _Exporter(mission, skills, palette).run()


# ---------------------------------------------------------------------------------------
# Import
# ---------------------------------------------------------------------------------------
MAX_XML_BYTES = 8 * 1024 * 1024


def _xml_parser() -> etree.XMLParser:
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                           dtd_validation=False, huge_tree=False, remove_comments=True,
                           remove_pis=True)


_BARE_AMP = re.compile(rb"&(?!(?:[A-Za-z_][\w.-]*|#[0-9]+|#x[0-9A-Fa-f]+);)")


def parse_xml(data: bytes, name: str) -> etree._Element:
    """Parse untrusted BT.CPP XML: no DTD, no entities, no network; MissionError with line."""
    if len(data) > MAX_XML_BYTES:
        raise MissionError(f"file is larger than {MAX_XML_BYTES} bytes", file=name, line=0)
    for marker in (b"<!DOCTYPE", b"<!ENTITY"):
        idx = data.find(marker)
        if idx >= 0:
            raise MissionError("DOCTYPE declarations (DTDs and entities) are not allowed",
                               file=name, line=data.count(b"\n", 0, idx) + 1)
    # BT.CPP reads its XML with tinyxml2, which keeps a bare '&' as text, and its own
    # examples write scripts as code="a && b"; read them the same way (a real entity
    # reference such as &amp; or &x; is left to the parser).
    data = _BARE_AMP.sub(b"&amp;", data)
    try:
        root = etree.fromstring(data, _xml_parser())
    except etree.XMLSyntaxError as err:
        line = err.lineno if getattr(err, "lineno", None) else 0
        msg = re.sub(r", line \d+, column \d+$", "", getattr(err, "msg", None) or str(err))
        raise MissionError(f"XML syntax error: {msg}", file=name, line=line) from None
    return root


class _Flow(dict):
    """A mapping written in YAML flow style ({a: 1, b: 2})."""


class _FlowList(list):
    """A sequence written in YAML flow style ([a, b])."""


class _Dumper(yaml.SafeDumper):
    pass


_Dumper.add_representer(_FlowList, lambda d, v: d.represent_sequence(
    "tag:yaml.org,2002:seq", v, flow_style=True))


_Dumper.add_representer(_Flow, lambda d, v: d.represent_mapping(
    "tag:yaml.org,2002:map", v.items(), flow_style=True))
_Dumper.add_representer(dict, lambda d, v: d.represent_mapping(
    "tag:yaml.org,2002:map", v.items(), flow_style=False))


def _entries(element: etree._Element) -> set[str]:
    """Every blackboard entry a BT.CPP tree names: {key} in attributes and the variables
    of its scripts (what _autoremap shares with the caller)."""
    out: set[str] = set()
    for el in element.iter():
        if not isinstance(el.tag, str):
            continue
        for a, v in el.attrib.items():
            v = v.strip()
            if _pointer_like(v) and _IDENT.match(v[1:-1]):
                out.add(v[1:-1])
            elif a in SCRIPT_ATTRS or (a == "code" and el.tag in ("Script", "ScriptCondition")) \
                    or (a == "if" and el.tag == "Precondition"):
                try:
                    out |= {t.text for t in _script_tokens(v)
                            if t.kind == "id" and t.text not in ("true", "false")
                            and not t.text.startswith("@")}
                except ValueError:
                    pass
    return out


def _case_literal(text: str) -> str:
    """A Switch case as an operand of a Hearth condition: a number as a number (BT.CPP
    compares a case with the variable as numbers when both read as numbers), else text."""
    try:
        float(text)
        return text.strip()
    except ValueError:
        return "'" + text.replace("'", "") + "'"


def _yaml_default(node: dict) -> str:
    kind = next((k for k in node if k in _KINDS_ALL), "node")
    if kind == "skill":
        return str(node["skill"])
    if kind == "include":
        return str(node["include"])
    return kind


@dataclass
class _TreeInfo:
    id: str
    element: etree._Element
    params: dict[str, dict]             # name -> Hearth parameter spec
    description: str = ""
    pointer_defaults: dict[str, str] = field(default_factory=dict)   # port -> "{key}"
    meta: dict[str, Any] = field(default_factory=dict)


class _Importer:
    def __init__(self, root: etree._Element, file: str, skills: dict[str, type]):
        self.root = root
        self.file = file
        self.skills = skills
        self.errors: list[MissionError] = []
        self.lines: dict[int, int] = {}     # id(yaml node dict) -> xml line
        self.models: dict[str, etree._Element] = {}
        self.trees: dict[str, _TreeInfo] = {}

    def error(self, message: str, line: int | None) -> None:
        self.errors.append(MissionError(message, file=self.file, line=line or 0))

    def run(self) -> dict:
        root = self.root
        if root.tag != "root":
            raise MissionError(f"expected a <root> element, found <{root.tag}>", file=self.file,
                               line=root.sourceline)
        fmt = root.get("BTCPP_format")
        if fmt is not None and fmt.strip() != "4":
            raise MissionError(f"BTCPP_format {fmt!r}: only BehaviorTree.CPP v4 XML "
                               "(BTCPP_format=\"4\") is read", file=self.file,
                               line=root.sourceline)
        for el in root:
            if el.tag == "TreeNodesModel":
                for m in el:
                    if m.tag == "SubTree" and m.get("ID"):
                        self.models[m.get("ID")] = m
                    elif m.tag in ("Action", "Condition", "Decorator", "Control"):
                        self.check_model(m)
        elements = [el for el in root if el.tag == "BehaviorTree"]
        for el in root:
            if el.tag not in ("BehaviorTree", "TreeNodesModel", "include"):
                self.error(f"unexpected <{el.tag}> under <root>", el.sourceline)
            elif el.tag == "include":
                self.error("<include> of other XML files is not supported; put every "
                           "BehaviorTree in one file", el.sourceline)
        if not elements:
            raise MissionError("no <BehaviorTree> in the file", file=self.file,
                               line=root.sourceline)
        for el in elements:
            tid = el.get("ID") or ("main" if len(elements) == 1 else None)
            if tid is None:
                self.error("a <BehaviorTree> needs an ID when the file has several",
                           el.sourceline)
                continue
            if not _IDENT.match(tid):
                self.error(f"tree ID {tid!r} is not an identifier ([A-Za-z_][A-Za-z0-9_]*)",
                           el.sourceline)
                continue
            if tid in self.trees:
                self.error(f"two <BehaviorTree> elements with ID {tid!r}", el.sourceline)
                continue
            kids = list(el)
            if len(kids) != 1:
                self.error(f"<BehaviorTree ID={tid!r}> must have exactly one child",
                           el.sourceline)
                continue
            info = _TreeInfo(tid, kids[0], {}, el.get("_description", ""))
            self.trees[tid] = info
        main = root.get("main_tree_to_execute") or (elements[0].get("ID") if len(elements) == 1
                                                    else None)
        if main is None and len(elements) == 1:
            main = "main"
        if main is None:
            raise MissionError("several <BehaviorTree> elements and no main_tree_to_execute "
                               "(a BT.CPP application names it in code, createTree(ID); "
                               "write <root main_tree_to_execute=\"ID\">)",
                               file=self.file, line=root.sourceline)
        if main not in self.trees:
            if self.errors:
                raise MissionValidationError(self.errors)
            raise MissionError(f"main_tree_to_execute {main!r}: no <BehaviorTree> with that ID",
                               file=self.file, line=root.sourceline)
        self.collect_params(main)
        doc: dict[str, Any] = {"hearth": 1, "name": main}
        minfo = self.trees[main]
        if minfo.description:
            doc["description"] = minfo.description
        if "utterances" in minfo.meta:
            doc["utterances"] = minfo.meta["utterances"]
        if "interrupted" in minfo.meta:
            doc["interrupted"] = minfo.meta["interrupted"]
        if minfo.params:
            doc["parameters"] = dict(minfo.params)
        if "blackboard" in minfo.meta:
            doc["blackboard"] = minfo.meta["blackboard"]
        doc["tree"] = self.node(minfo.element, minfo, root_default=main)
        subtrees = {}
        for tid, info in self.trees.items():
            if tid == main:
                continue
            sub: dict[str, Any] = {}
            if info.description:
                sub["description"] = info.description
            if info.params:
                sub["parameters"] = dict(info.params)
            sub["tree"] = self.node(info.element, info, root_default=None)
            subtrees[tid] = sub
        if subtrees:
            doc["subtrees"] = subtrees
        if self.errors:
            raise MissionValidationError(self.errors)
        return doc

    def check_model(self, model: etree._Element) -> None:
        """A Groot2 model of a skill or a Hearth node must declare only ports it has, each
        in its direction: a model written for another version of the skill is an error
        here, not a surprise in the middle of a mission."""
        nid = model.get("ID")
        if nid in self.skills:
            cls = self.skills[nid]
            have = {p.name: "input_port" for p in cls.INPUTS}
            have.update({output_port_name(cls, p.name): "output_port" for p in cls.OUTPUTS})
            what = f"skill {nid}"
        elif nid in CUSTOM:
            have = {name: direction for direction, name, *_ in CUSTOM[nid][1]}
            what = f"Hearth node {nid}"
        else:
            return
        for port in model:
            if port.tag not in ("input_port", "output_port", "inout_port"):
                continue
            pname = port.get("name")
            if pname not in have:
                known = ", ".join(have) or "none"
                self.error(f"the model of {nid} declares port {pname!r}, which {what} lacks "
                           f"(ports: {known})", port.sourceline)
            elif port.tag != have[pname] and port.tag != "inout_port":
                self.error(f"the model of {nid} declares {pname!r} as {port.tag}; {what} has "
                           f"it as {have[pname]}", port.sourceline)

    # -- tree parameters ----------------------------------------------------------------
    def collect_params(self, main: str) -> None:
        calls: dict[str, list[etree._Element]] = {}
        for info in self.trees.values():
            for el in info.element.iter("SubTree"):
                calls.setdefault(el.get("ID", ""), []).append(el)
        for tid, info in self.trees.items():
            model = self.models.get(tid)
            if model is not None:
                for port in model:
                    if port.tag in ("input_port", "output_port", "inout_port"):
                        default = (port.get("default") or "").strip()
                        if _pointer_like(default):
                            info.pointer_defaults[port.get("name")] = default
                            port = etree.Element(port.tag, {k: v for k, v in port.attrib.items()
                                                            if k != "default"})
                            port.text = None
                        spec = self.param_spec(port)
                        if spec is not None:
                            info.params[port.get("name")] = spec
                    elif port.tag == "MetadataFields":
                        for m in port:
                            for k, v in m.attrib.items():
                                try:
                                    info.meta[k] = decode_literal(v, "list|dict")
                                except ValueError as err:
                                    self.error(f"metadata {k}: {err}", m.sourceline)
            elif tid != main:
                # No model: the ports are what the callers remap (BT.CPP's own reading),
                # and with _autoremap every entry the subtree names.
                for call in calls.get(tid, []):
                    for attr in call.attrib:
                        if attr != "ID" and attr != "name" and not attr.startswith("_"):
                            info.params.setdefault(attr, {"type": "any"})
                    if call.get("_autoremap", "false").strip().lower() in ("true", "1"):
                        for key in sorted(_entries(info.element)):
                            info.params.setdefault(key, {"type": "any"})

    def param_spec(self, port: etree._Element) -> dict | None:
        name = port.get("name")
        if not name or not _IDENT.match(name):
            self.error(f"port name {name!r} is not an identifier", port.sourceline)
            return None
        ptype = port.get("type") or "any"
        # A port without a type (BT.CPP's AnyTypeAllowed: text converted where it is read)
        # keeps a number default a number, so that scripts compare it as BT.CPP does.
        read_as = ptype if port.get("type") else "number|boolean|list|dict"
        from hearth.executive.missionfile import TYPES
        if any(t not in TYPES for t in _alts(ptype)):
            ptype = "any"   # a C++ type name written by BT.CPP or Groot2
        spec: dict[str, Any] = {"type": ptype}
        if port.get("items"):
            spec["items"] = port.get("items")
        if port.get("default") is not None:
            try:
                spec["default"] = decode_literal(port.get("default"),
                                                 read_as if ptype == "any" else ptype)
            except ValueError as err:
                self.error(f"port {name}: default {err}", port.sourceline)
        if port.get("required") == "false":
            spec["required"] = False
        if port.get("runtime") == "true":
            spec["runtime"] = True
        if port.get("enum"):
            try:
                spec["enum"] = json.loads(port.get("enum"))
            except json.JSONDecodeError:
                self.error(f"port {name}: enum is not a JSON list", port.sourceline)
        for attr in _CHECKS:
            if port.get(attr) is not None:
                try:
                    spec[attr] = json.loads(port.get(attr))
                except json.JSONDecodeError:
                    self.error(f"port {name}: {attr} is not JSON", port.sourceline)
        text = (port.text or "").strip() or port.get("description")
        if text:
            spec["description"] = text
        return spec

    # -- values -------------------------------------------------------------------------
    def pointer(self, text: str, info: _TreeInfo, line: int) -> str | None:
        """``{name}`` -> ``$name`` (a port of this tree) or ``{name}`` (a key)."""
        inner = text[1:-1].strip()
        if inner.startswith("@"):
            self.error(f"{text}: root-blackboard keys ({{@key}}) have no Hearth equivalent; "
                       "pass the value in through the subtree's ports", line)
            return None
        if not _IDENT.match(inner):
            self.error(f"{text}: a key name must be an identifier ([A-Za-z_][A-Za-z0-9_]*)",
                       line)
            return None
        return f"${inner}" if inner in info.params else "{" + inner + "}"

    def value(self, text: str, info: _TreeInfo, type_name: str, line: int, what: str) -> Any:
        if _pointer_like(text.strip()):
            return self.pointer(text.strip(), info, line)
        try:
            return decode_literal(text, type_name)
        except ValueError as err:
            self.error(f"{what}: {err}", line)
            return None

    def expr(self, text: str, info: _TreeInfo) -> str:
        def sub(m: re.Match) -> str:
            if m.group(1):
                return f"${m.group(1)}" if m.group(1) in info.params else m.group(0)
            return m.group(0)
        return _EXPR_TOKEN.sub(sub, text)

    # -- nodes --------------------------------------------------------------------------
    def node(self, el: etree._Element, info: _TreeInfo, root_default: str | None,
             parent: str | None = None) -> dict:
        """The Hearth node for ``el`` (a child of a ``parent`` element), its BT.CPP
        pre/post-condition scripts rewritten around it."""
        out = self._node(el, info, root_default)
        scripts = {a: el.get(a) for a in SCRIPT_ATTRS if el.get(a) is not None}
        if scripts and isinstance(el.tag, str):
            base = str(out.get("name") or root_default or _yaml_default(out))
            out = self.conditions(out, scripts, parent, info, el.sourceline, base)
        self.mark(out, el.sourceline or 0, top=True)
        return out

    def mark(self, data: Any, line: int, top: bool = False) -> None:
        """Give the nodes import generated (wrappers, SetValue steps) the XML line of the
        element they came from."""
        if isinstance(data, dict):
            if id(data) in self.lines and not top:
                return
            if any(k in data for k in _KINDS_ALL):
                self.lines.setdefault(id(data), line)
            for v in data.values():
                self.mark(v, line)
        elif isinstance(data, list):
            for v in data:
                self.mark(v, line)

    # -- BT.CPP scripts -----------------------------------------------------------------
    def condition(self, code: str, info: _TreeInfo, line: int, what: str) -> dict:
        try:
            return {"condition": self.expr(script_condition(code), info)}
        except ValueError as err:
            self.error(f"{what}: {err}", line)
            return {"succeed": None}

    def assignments(self, code: str, info: _TreeInfo, line: int, what: str) -> list[dict]:
        try:
            pairs = script_assignments(code)
        except ValueError as err:
            self.error(f"{what}: {err}", line)
            return []
        return [self.set_value(key, value, info, line) for key, value in pairs]

    def set_value(self, key: str, value: Any, info: _TreeInfo, line: int) -> dict:
        """``key := value`` as Hearth's SetValue skill (BT.CPP's SetBlackboard)."""
        if "SetValue" not in self.skills:
            self.error("scripts and SetBlackboard need the SetValue skill", line)
            return {"fail": None}
        target = self.pointer("{" + key + "}", info, line) or "{" + key + "}"
        if isinstance(value, str) and _pointer_like(value):
            value = self.pointer(value, info, line)
        out = {"skill": "SetValue", "name": f"set_{key}", "inputs": _Flow({"value": value}),
               "outputs": _Flow({"output": target if target.startswith("$") else key})}
        self.lines[id(out)] = line
        return out

    def conditions(self, node: dict, scripts: dict[str, str], parent: str | None,
                   info: _TreeInfo, line: int, base: str) -> dict:
        """BT.CPP's pre-conditions (checked when the node starts: _failureIf, _successIf,
        _skipIf, then _while, which is also checked every tick while it runs) and
        post-conditions (scripts run when it, or a pre-condition, returns success or
        failure) as Hearth nodes around ``node``."""
        if "_onHalted" in scripts:
            self.error("_onHalted: Hearth runs no node when a branch is halted (a skill's "
                       "terminate stops what it started); no equivalent", line)
        if ("_skipIf" in scripts or "_while" in scripts) and parent not in SKIP_AS:
            which = "_skipIf" if "_skipIf" in scripts else "_while"
            self.error(f"{which}: BT.CPP's SKIPPED has a Hearth reading only for a child of a "
                       f"Sequence or a Fallback (here under <{parent or 'BehaviorTree'}>)", line)
            return node
        n = node
        if "_successIf" in scripts:
            n = {"selector": [self.condition(scripts["_successIf"], info, line, "_successIf"),
                              n], "name": f"{base}_successIf"}
        if "_failureIf" in scripts:
            n = {"sequence": [{"inverter": self.condition(scripts["_failureIf"], info, line,
                                                          "_failureIf")}, n],
                 "name": f"{base}_failureIf"}
        post = scripts.get("_post")
        on_s = [s for c in (scripts.get("_onSuccess"), post) if c
                for s in self.assignments(c, info, line, "_onSuccess" if c != post else "_post")]
        on_f = [s for c in (scripts.get("_onFailure"), post) if c
                for s in self.assignments(c, info, line, "_onFailure" if c != post else "_post")]
        if on_s and on_f:
            n = {"selector": [{"sequence": [n, *on_s], "name": f"{base}_onSuccess"},
                              {"sequence": [*on_f, {"fail": None}], "name": f"{base}_onFailure"}],
                 "name": f"{base}_post"}
        elif on_s:
            n = {"sequence": [n, *on_s], "name": f"{base}_onSuccess"}
        elif on_f:
            n = {"selector": [n, {"sequence": [*on_f, {"fail": None}], "name": "onFailure"}],
                 "name": f"{base}_onFailure"}
        skipped = SKIP_AS.get(parent or "")
        if "_skipIf" in scripts:
            # Skipped only when no earlier pre-condition triggers (BT.CPP's order).
            checks = [{"inverter": self.condition(scripts[a], info, line, a)}
                      for a in ("_failureIf", "_successIf") if a in scripts]
            checks.append(self.condition(scripts["_skipIf"], info, line, "_skipIf"))
            skip = checks[0] if len(checks) == 1 else {"sequence": checks, "name": "skip"}
            if skipped == "success":
                n = {"selector": [skip, n], "name": f"{base}_skipIf"}
            else:
                n = {"sequence": [{"inverter": skip}, n], "name": f"{base}_skipIf"}
        if "_while" in scripts:
            held = self.condition(scripts["_while"], info, line, "_while")
            if "condition" in held:
                n = {"guard": n, "while": held["condition"], "name": f"{base}_while"}
                if skipped == "success":
                    # A guard fails when its condition stops holding: a skip, read as a
                    # success under a sequence; the child's own failure stays a failure.
                    n = {"selector": [n, {"inverter": dict(held)}], "name": f"{base}_whileSkip"}
        return n

    def _node(self, el: etree._Element, info: _TreeInfo, root_default: str | None) -> dict:
        line = el.sourceline
        tag = el.tag
        if not isinstance(tag, str):
            return {"fail": "not a node"}
        attrs = dict(el.attrib)
        if tag in ("Action", "Condition", "Decorator", "Control") and "ID" in attrs:
            tag = attrs.pop("ID")
        comment = attrs.get("_description")
        for a in [a for a in attrs if a.startswith("_")]:
            attrs.pop(a)
        name = attrs.pop("name", None)
        kids = [k for k in el if isinstance(k.tag, str)]
        out: dict[str, Any] = {}

        def want(n_min: int, n_max: int | None) -> bool:
            if len(kids) < n_min or (n_max is not None and len(kids) > n_max):
                if n_max == 0:
                    self.error(f"<{tag}> is a leaf and must not have children", line)
                elif n_max == 1:
                    self.error(f"<{tag}> must have exactly one child (it has {len(kids)})",
                               line)
                else:
                    self.error(f"<{tag}> must have at least one child", line)
                return False
            return True

        def ports(allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> bool:
            ok = True
            for a in attrs:
                if a not in allowed:
                    known = ", ".join(allowed) or "none"
                    self.error(f"<{tag}> has no port {a!r} (ports: {known})", line)
                    ok = False
            for r in required:
                if r not in attrs:
                    self.error(f"<{tag}> needs {r}=", line)
                    ok = False
            return ok

        def integer(a: str) -> int | None:
            try:
                return int(attrs[a])
            except ValueError:
                self.error(f"<{tag}> {a}={attrs[a]!r}: expected an integer", line)
                return None

        def children() -> list:
            return [self.node(k, info, None, tag) for k in kids]

        default = root_default
        own: str | None = None      # the name of a node import rewrites (Script, Switch...)
        if tag in ("Sequence", "ReactiveSequence", "SequenceWithMemory", "Fallback",
                   "ReactiveFallback"):
            ports(())
            want(1, None)
            kind = "sequence" if "Sequence" in tag else "selector"
            out[kind] = children()
            if tag.startswith("Reactive"):
                out["reactive"] = True
        elif tag == "Parallel":
            ports(("success_count", "failure_count"))
            want(1, None)
            n = len(kids)
            s = integer("success_count") if "success_count" in attrs else -1
            f = integer("failure_count") if "failure_count" in attrs else 1
            if s is not None and f is not None:
                s = n if s < 0 else s
                f = n if f < 0 else f
                if s > n or f > n or s < 1 or f < 1:
                    self.error(f"<Parallel> success_count {s} / failure_count {f} do not fit "
                               f"its {n} children", line)
                elif s == n and f == 1:
                    pass
                elif s == 1 and f == n:
                    out["policy"] = "one"
                elif s + f == n + 1:
                    out["policy"] = "threshold"
                    out["threshold"] = s
                else:
                    self.error(f"<Parallel> success_count {s} with failure_count {f}: Hearth "
                               "fails a parallel only once its success count cannot be "
                               f"reached (failure_count {n - s + 1} here)", line)
            out = {"parallel": children(), **out}
        elif tag == "RetryUntilSuccessful":
            ports(("num_attempts",), ("num_attempts",))
            want(1, 1)
            times = integer("num_attempts") if "num_attempts" in attrs else None
            if times is not None and times < 1:
                self.error("<RetryUntilSuccessful> num_attempts must be >= 1 (Hearth has no "
                           "retry forever)", line)
            out = {"retry": children()[0] if kids else None, "times": times}
        elif tag in ("Repeat", "KeepRunningUntilFailure"):
            want(1, 1)
            if tag == "Repeat":
                ports(("num_cycles",), ("num_cycles",))
                times = integer("num_cycles") if "num_cycles" in attrs else -1
            else:
                ports(())
                times = -1
            out = {"repeat": children()[0] if kids else None}
            if times is not None and times >= 0:
                out["times"] = times
        elif tag == "Timeout":
            ports(("msec",), ("msec",))
            want(1, 1)
            msec = integer("msec") if "msec" in attrs else None
            out = {"timeout": children()[0] if kids else None,
                   "seconds": (msec or 0) / 1000.0}
        elif tag in ("Inverter", "ForceSuccess", "ForceFailure"):
            ports(())
            want(1, 1)
            kind = {"Inverter": "inverter", "ForceSuccess": "force_success",
                    "ForceFailure": "force_failure"}[tag]
            out = {kind: children()[0] if kids else None}
        elif tag in ("AlwaysSuccess", "AlwaysFailure", "Succeed", "Fail"):
            ports(("message",) if tag in ("Succeed", "Fail") else ())
            want(0, 0)
            kind = "succeed" if tag in ("AlwaysSuccess", "Succeed") else "fail"
            out = {kind: attrs.get("message") or None}
        elif tag == "ForEach":
            ports(("in", "as", "until"), ("in", "as"))
            want(1, 1)
            out = {"for_each": children()[0] if kids else None}
            if "in" in attrs:
                out["in"] = self.value(attrs["in"], info, "list", line, "ForEach in")
            if "as" in attrs:
                target = self.value(attrs["as"], info, "any", line, "ForEach as")
                if not (isinstance(target, str) and _KEY.match(target)):
                    self.error(f"<ForEach> as={attrs['as']!r}: expected a {{key}} (not a port "
                               "of the tree)", line)
                else:
                    out["as"] = target[1:-1]
            if attrs.get("until", "failure") != "failure":
                out["until"] = attrs["until"]
        elif tag == "Watch":
            ports(("params",), ("params",))
            want(1, 1)
            out = {"watch": children()[0] if kids else None,
                   "params": _FlowList(p.strip() for p in attrs.get("params", "").split(";")
                                       if p.strip())}
        elif tag == "Guard":
            ports(("while",), ("while",))
            want(1, 1)
            out = {"guard": children()[0] if kids else None,
                   "while": self.expr(attrs.get("while", ""), info)}
        elif tag == "Check":
            ports(("expr",), ("expr",))
            want(0, 0)
            out = {"condition": self.expr(attrs.get("expr", ""), info)}
        elif tag == "Script":
            ports(("code",), ("code",))
            want(0, 0)
            steps = self.assignments(attrs.get("code", ""), info, line, "<Script> code")
            if len(steps) == 1:
                out = steps[0]
            else:
                out = {"sequence": steps or [{"succeed": None}], "name": "script"}
            own = out.pop("name")
        elif tag == "ScriptCondition":
            ports(("code",), ("code",))
            want(0, 0)
            out = self.condition(attrs.get("code", ""), info, line, "<ScriptCondition> code")
        elif tag == "SetBlackboard":
            ports(("value", "output_key"), ("value", "output_key"))
            want(0, 0)
            key = attrs.get("output_key", "").strip()
            key = key[1:-1] if _pointer_like(key) else key
            if not _IDENT.match(key):
                self.error(f"<SetBlackboard> output_key={key!r}: expected a key name", line)
                return {"fail": None}
            text = attrs.get("value", "")
            value = text if _pointer_like(text.strip()) else self.value(text, info, "any", line,
                                                                        "SetBlackboard value")
            out = self.set_value(key, value, info, line)
            own = out.pop("name")
        elif tag == "Precondition":
            ports(("if", "else"), ("if", "else"))
            want(1, 1)
            cond = self.condition(attrs.get("if", ""), info, line, "<Precondition> if")
            other = attrs.get("else", "").strip().upper()
            kid = children()[0] if kids else {"succeed": None}
            if other == "FAILURE":
                out = {"sequence": [cond, kid]}
            elif other == "SUCCESS":
                out = {"selector": [{"inverter": cond}, kid]}
            else:
                self.error(f"<Precondition> else={attrs.get('else')!r}: Hearth reads SUCCESS or "
                           "FAILURE", line)
                return {"fail": None}
            own = "precondition"
        elif tag in ("Delay", "Sleep"):
            port = "delay_msec" if tag == "Delay" else "msec"
            ports((port,), (port,))
            want(1, 1) if tag == "Delay" else want(0, 0)
            msec = integer(port) if port in attrs else None
            wait = {"skill": "Wait", "inputs": _Flow({"seconds": (msec or 0) / 1000.0})}
            if tag == "Delay":
                out = {"sequence": [wait, *children()]}
                own = "delay"
            else:
                out = wait
        elif tag == "RunOnce":
            ports(("then_skip",))
            want(1, 1)
            skip = attrs.get("then_skip", "true").strip().lower() not in ("false", "0")
            kid = children()[0] if kids else {"succeed": None}
            out = self.run_once(kid, skip, el, info, line)
            own = "run_once"
        elif tag == "IfThenElse":
            ports(())
            if len(kids) not in (2, 3):
                self.error(f"<IfThenElse> must have 2 or 3 children (it has {len(kids)})", line)
            parts = children()
            if len(parts) in (2, 3):
                states = {"if": {"do": parts[0], "transitions": _Flow(
                    {"success": "then", "failure": "else" if len(parts) == 3 else "failed"})},
                    "then": {"do": parts[1], "transitions": _Flow(
                        {"success": "succeeded", "failure": "failed"})}}
                if len(parts) == 3:
                    states["else"] = {"do": parts[2], "transitions": _Flow(
                        {"success": "succeeded", "failure": "failed"})}
                out = {"state_machine": {"initial": "if", "states": states, "outcomes": _Flow(
                    {"succeeded": "success", "failed": "failure"})}}
            else:
                out = {"fail": None}
            own = "if_then_else"
        elif tag in LOWERED_PORTS and tag.startswith("Switch"):
            n = int(tag[len("Switch"):])
            ports(LOWERED_PORTS[tag], LOWERED_PORTS[tag])
            if len(kids) != n + 1:
                self.error(f"<{tag}> must have {n + 1} children ({n} cases and the default; it "
                           f"has {len(kids)})", line)
                return {"fail": None}
            var = attrs.get("variable", "").strip()
            ref = self.pointer(var, info, line) if _pointer_like(var) else None
            if ref is None:
                if not _pointer_like(var):
                    self.error(f"<{tag}> variable={var!r}: expected a {{key}}", line)
                return {"fail": None}
            operand = ref if ref.startswith("$") else ref
            branches = []
            cases = [_case_literal(attrs.get(f"case_{i}", "")) for i in range(1, n + 1)]
            for i, kid in enumerate(children()):
                checks = [{"condition": f"{operand} != {c}"} for c in cases[:i]]
                if i < n:
                    checks.append({"condition": f"{operand} == {cases[i]}"})
                branches.append({"sequence": [*checks, kid], "reactive": True,
                                 "name": f"case_{i + 1}" if i < n else "default"})
            # Reactive, as BT.CPP's Switch reads the variable every tick and halts the running
            # case when another one matches.
            out = {"selector": branches, "reactive": True}
            own = "switch"
        elif tag == "StateMachine":
            ports(("initial", "outcomes"), ("initial", "outcomes"))
            want(1, None)
            states = {}
            for k in kids:
                if k.tag != "State":
                    self.error(f"<StateMachine> children are <State> elements, not <{k.tag}>",
                               k.sourceline)
                    continue
                st = self.state(k, info)
                if st is not None:
                    states[k.get("name")] = st
            try:
                outcomes = _read_pairs(attrs.get("outcomes", ""))
            except ValueError as err:
                self.error(f"<StateMachine> outcomes: {err}", line)
                outcomes = {}
            out = {"state_machine": {"initial": attrs.get("initial"), "states": states,
                                     "outcomes": outcomes}}
        elif tag == "State":
            self.error("<State> belongs directly under a <StateMachine>", line)
            return {"fail": None}
        elif tag == "SubTree":
            out, default = self.subtree(el, attrs, info, kids)
        elif tag in REFUSED:
            self.error(f"<{tag}>: {REFUSED[tag]}", line)
            return {"fail": None}
        elif tag in self.skills:
            want(0, 0)
            out = self.skill(tag, attrs, info, line)
            default = default or tag
        else:
            close = [s for s in sorted(self.skills) if s.lower() == tag.lower()]
            hint = f"; did you mean {close[0]}?" if close else ""
            self.error(f"<{tag}> is neither a BehaviorTree.CPP node Hearth maps nor a "
                       f"registered skill{hint}", line)
            return {"fail": None}
        kind = next(iter(out))
        if own is not None:
            name = name or own
            default = _yaml_default(out)
        if default is None:
            default = kind
        if name is not None and name != default:
            out["name"] = name
        if comment:
            out["comment"] = comment
        self.lines[id(out)] = line
        return out

    def run_once(self, kid: dict, then_skip: bool, el: etree._Element, info: _TreeInfo,
                 line: int) -> dict:
        """BT.CPP's RunOnce: the child runs to its end once per run of the mission; after
        that the node is skipped (``then_skip``) or returns the child's status again. The
        memory is a blackboard key named after the line (unset reads false)."""
        key = f"run_once_{line}"
        done = self.set_value(key + "_ok", True, info, line)
        failed = self.set_value(key + "_failed", True, info, line)
        run = {"selector": [{"sequence": [kid, done]},
                            {"sequence": [failed, {"fail": None}]}]}
        ran = {"condition": "{%s_ok} || {%s_failed}" % (key, key)}
        if then_skip:
            parent = el.getparent()
            skipped = SKIP_AS.get(parent.tag if parent is not None else "")
            if skipped is None:
                self.error("<RunOnce then_skip=true>: BT.CPP's SKIPPED has a Hearth reading "
                           "only for a child of a Sequence or a Fallback", line)
                return run
            if skipped == "success":
                return {"selector": [ran, run]}
            return {"sequence": [{"inverter": ran}, run]}
        return {"selector": [{"condition": "{%s_ok}" % key},
                             {"sequence": [{"inverter": {"condition": "{%s_failed}" % key}},
                                           run]}]}

    def state(self, el: etree._Element, info: _TreeInfo) -> dict | None:
        line = el.sourceline
        if not el.get("name"):
            self.error("<State> needs name= (the state's name)", line)
            return None
        for a in el.attrib:
            if a not in ("name", "transitions", "outcome") and not a.startswith("_"):
                self.error(f"<State> has no port {a!r} (ports: transitions, outcome)", line)
        kids = [k for k in el if isinstance(k.tag, str)]
        if len(kids) != 1:
            self.error(f"<State> must have exactly one child (it has {len(kids)})", line)
            return None
        try:
            transitions = _read_pairs(el.get("transitions", ""))
        except ValueError as err:
            self.error(f"<State> transitions: {err}", line)
            transitions = {}
        st: dict[str, Any] = {"do": self.node(kids[0], info, None)}
        if el.get("outcome"):
            ref = self.value(el.get("outcome"), info, "any", line, "State outcome")
            if not (isinstance(ref, str) and _KEY.match(ref)):
                self.error(f"<State> outcome={el.get('outcome')!r}: expected a {{key}}", line)
            else:
                st["outcome"] = ref
        st["transitions"] = _Flow(transitions)
        self.lines[id(st)] = line
        return st

    def subtree(self, el, attrs, info: _TreeInfo, kids) -> tuple[dict, str]:
        line = el.sourceline
        tid = attrs.pop("ID", None)
        if kids:
            self.error("<SubTree> must not have children", line)
        if tid is None:
            self.error("<SubTree> needs ID=", line)
            return {"fail": None}, "fail"
        target = self.trees.get(tid)
        if target is None:
            self.error(f"<SubTree ID={tid!r}>: no <BehaviorTree> with that ID in this file",
                       line)
            return {"fail": None}, "fail"
        autoremap = el.get("_autoremap", "false").strip().lower() in ("true", "1")
        if tid == self.root.get("main_tree_to_execute"):
            self.error(f"<SubTree ID={tid!r}>: the main tree cannot also be a subtree", line)
        params: dict[str, Any] = {}
        for a, text in attrs.items():
            if a not in target.params:
                known = ", ".join(target.params) or "none"
                self.error(f"<SubTree ID={tid!r}> has no port {a!r} (ports: {known})", line)
                continue
            if text == "{=}":
                text = "{" + a + "}"
            ptype = target.params[a].get("type", "any")
            value = self.value(text, info, ptype, line, f"SubTree {tid} {a}")
            if value == "" and target.params[a].get("default") == "":
                continue   # the explicit "" export writes for BT.CPP
            params[a] = value
        for a in target.params:
            if a in params or a in attrs:
                continue
            if a in target.pointer_defaults:
                # A model port whose default is a {key}: BT.CPP remaps it to that key.
                params[a] = self.pointer(target.pointer_defaults[a], info, line)
            elif autoremap:
                # _autoremap: every port not remapped reads and writes the caller's entry
                # of the same name.
                params[a] = self.pointer("{" + a + "}", info, line)
        out: dict[str, Any] = {"include": tid}
        if params:
            out["params"] = _Flow(params)
        return out, tid

    def skill(self, tag: str, attrs: dict, info: _TreeInfo, line: int) -> dict:
        cls = self.skills[tag]
        inputs, outputs = {}, {}
        outs_by_name = {output_port_name(cls, p.name): p for p in cls.OUTPUTS}
        for a, text in attrs.items():
            pin, pout = cls.port(a), outs_by_name.get(a)
            if pin is None and pout is None:
                ins = ", ".join(p.name for p in cls.INPUTS) or "none"
                outs = ", ".join(outs_by_name) or "none"
                self.error(f"skill {tag} has no port {a!r} (inputs: {ins}; outputs: {outs})",
                           line)
                continue
            if pin is not None:
                inputs[a] = self.value(text, info, pin.type, line, f"{tag} {a}")
            else:
                ref = self.pointer(text.strip(), info, line) if _pointer_like(text.strip()) \
                    else None
                if ref is None:
                    if not _pointer_like(text.strip()):
                        self.error(f"{tag} {a}={text!r}: an output port takes a {{key}}", line)
                    continue
                outputs[pout.name] = ref if ref.startswith("$") else ref[1:-1]
        out: dict[str, Any] = {"skill": tag}
        if inputs:
            out["inputs"] = _Flow(inputs)
        if outputs:
            out["outputs"] = _Flow(outputs)
        return out


def _node_lines(mine: Any, loaded: Any, table: dict[int, int], out: list[tuple[int, int]]):
    """Pair each node of the built document with its line in the dumped YAML."""
    if isinstance(mine, dict) and isinstance(loaded, LineDict):
        if id(mine) in table:
            out.append((loaded.line, table[id(mine)]))
        for k, v in mine.items():
            if k in loaded:
                _node_lines(v, loaded[k], table, out)
    elif isinstance(mine, list) and isinstance(loaded, LineList):
        for a, b in zip(mine, loaded):
            _node_lines(a, b, table, out)


def import_tree(path: str | Path, skills: dict[str, type] | None = None,
                source_name: str | None = None) -> tuple[str, Mission]:
    """Read BT.CPP v4 XML at ``path``; return the mission's YAML text and the checked
    Mission. Problems raise MissionError / MissionValidationError with the XML file and line
    (the mission checks too: a problem they find is reported at the XML element it came
    from)."""
    name = source_name or str(path)
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise MissionError("no such file", file=name, line=0) from None
    skills = skills if skills is not None else skill_registry()
    root = parse_xml(data, name)
    imp = _Importer(root, name, skills)
    doc = imp.run()
    header = f"# Imported by hearth import from {Path(name).name} (BehaviorTree.CPP v4 XML).\n"
    text = header + yaml.dump(doc, Dumper=_Dumper, sort_keys=False, allow_unicode=True,
                              width=100)
    pairs: list[tuple[int, int]] = []
    _node_lines(doc, load_yaml_text(text), imp.lines, pairs)
    pairs.sort()
    fd, tmp = tempfile.mkstemp(suffix=".yaml", prefix="hearth-import-")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        mission, errors = compile_mission(tmp, skills)
    finally:
        os.unlink(tmp)
    if errors or mission is None:
        def xml_line(yline: int | None) -> int:
            best = root.sourceline or 1
            for y, x in pairs:
                if y <= (yline or 0):
                    best = x
            return best
        raise MissionValidationError([MissionError(e.message, file=name, line=xml_line(e.line))
                                      for e in errors] or [MissionError("invalid mission",
                                                                        file=name, line=0)])
    mission.file = name
    return text, mission


# ---------------------------------------------------------------------------------------
# The live tree, for the Groot2 protocol
# ---------------------------------------------------------------------------------------
@dataclass
class LiveTree:
    """A compiled mission as BT.CPP's ``WriteTreeToXML(tree, true, true)`` shows it: the
    XML (every node with ``_uid``), each Hearth node path's uid, the uids of ``<State>``
    wrappers that mirror their child's status, and the subtree instances (name -> the
    include's path, "" for the mission tree) in the order Groot2 lists them."""
    xml: str
    uid: dict[str, int]
    mirrors: dict[str, list[int]]
    order: list[int]
    instances: dict[str, str]


def _ref_text(ref: Any, type_name: str = "any") -> str:
    if isinstance(ref, BBKey):
        return "{" + ref.key.rsplit("/", 1)[-1] + "}"
    if isinstance(ref, Param):
        return "{" + ref.name + "}"
    if isinstance(ref, Lit):
        return encode_literal(ref.value, type_name)
    return str(ref)


def live_tree(mission: Mission) -> LiveTree:
    uid: dict[str, int] = {}
    mirrors: dict[str, list[int]] = {}
    order: list[int] = []
    trees: list[etree._Element] = []
    instances: dict[str, str] = {}
    counter = iter(range(1, 65536))
    used_skills: set[type] = set()
    used_custom: set[str] = set()

    def new_uid(el: etree._Element) -> int:
        n = next(counter)
        el.set("_uid", str(n))
        order.append(n)
        return n

    def subtree_id(spec: NodeSpec) -> str:
        target = str(spec.attrs.get("target", spec.name))
        return target.rsplit("#", 1)[-1].rsplit("/", 1)[-1].removesuffix(".yaml")

    def make(spec: NodeSpec, fullpath: str) -> etree._Element:
        k, a = spec.kind, spec.attrs
        attrs: dict[str, str] = {}
        if k == "sequence":
            tag = SEQUENCE[a["reactive"]]
        elif k == "selector":
            tag = SELECTOR[a["reactive"]]
        elif k == "parallel":
            tag = "Parallel"
            n = len(spec.children)
            need = n if a["policy"] == "all" else 1 if a["policy"] == "one" else a["threshold"]
            attrs.update(success_count=str(need), failure_count=str(n - need + 1))
        elif k == "retry":
            tag, attrs["num_attempts"] = "RetryUntilSuccessful", str(a["times"])
        elif k == "timeout":
            tag, attrs["msec"] = "Timeout", str(int(round(a["seconds"] * 1000)))
        elif k == "repeat":
            tag = "KeepRunningUntilFailure" if a["times"] < 0 else "Repeat"
            if a["times"] >= 0:
                attrs["num_cycles"] = str(a["times"])
        elif k in DECORATOR_TAGS:
            tag = DECORATOR_TAGS[k]
        elif k == "for_each":
            tag = "ForEach"
            attrs["in"] = _ref_text(a["source"], "list")
            attrs["as"] = "{" + a["target"].rsplit("/", 1)[-1] + "}"
            attrs["until"] = a["until"]
        elif k == "watch":
            tag, attrs["params"] = "Watch", ";".join(a["params"])
        elif k in ("guard", "condition"):
            tag = "Guard" if k == "guard" else "Check"
            attrs["while" if k == "guard" else "expr"] = a["expr"].text
        elif k in ("succeed", "fail"):
            tag = k.capitalize()
            attrs["message"] = a.get("message") or ""
        elif k == "skill":
            tag = spec.skill_name
            used_skills.add(spec.skill)
            for port, ref in spec.inputs.items():
                p = spec.skill.port(port)
                attrs[port] = _ref_text(ref, p.type if p else "any")
            for port, ref in spec.outputs.items():
                attrs[output_port_name(spec.skill, port)] = _ref_text(ref)
        elif k == "include":
            tag = "SubTree"
        elif k == "state_machine":
            tag = "StateMachine"
            attrs["initial"] = a["initial"]
            attrs["outcomes"] = _pairs(a["outcomes"])
        else:  # pragma: no cover
            tag = k
        if tag in CUSTOM:
            used_custom.add(tag)
        el = etree.Element(tag)
        if k == "include":
            sid = subtree_id(spec)
            inst = spec.path.lstrip("/")
            el.set("ID", sid)
            el.set("name", spec.name)       # viewers label a SubTree node by its name
            el.set("_fullpath", inst)
            uid[spec.path] = new_uid(el)
            instances[inst] = spec.path
            tree = etree.Element("BehaviorTree", ID=sid, _fullpath=inst)
            trees.append(tree)
            tree.append(make(spec.children[0], inst + "/"))
            return el
        el.set("name", spec.name)
        for key, value in attrs.items():
            el.set(key, value)
        uid[spec.path] = new_uid(el)
        if k == "state_machine":
            used_custom.add("State")
            table = dict(a["states"])
            for child in spec.children:
                sname = child.attrs.get("state", child.name)
                state = etree.SubElement(el, "State", name=sname,
                                         transitions=_pairs(table.get(sname, {})))
                mirrors.setdefault(child.path, []).append(new_uid(state))
                state.append(make(child, fullpath))
        else:
            for child in spec.children:
                el.append(make(child, fullpath))
        return el

    main = etree.Element("BehaviorTree", ID=mission.name, _fullpath="")
    trees.append(main)
    instances[mission.name] = ""
    main.append(make(mission.root, ""))
    root = etree.Element("root", BTCPP_format="4", main_tree_to_execute=mission.name)
    for t in trees:
        root.append(t)
    models = etree.SubElement(root, "TreeNodesModel")
    for cls in sorted(used_skills, key=lambda c: c.NAME):
        models.append(skill_model(cls))
    for tag in sorted(used_custom):
        models.append(custom_model(tag))
    etree.indent(root, space="  ")
    xml = etree.tostring(root, encoding="unicode")
    return LiveTree(xml=xml, uid=uid, mirrors=mirrors, order=order, instances=instances)
