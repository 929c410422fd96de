"""Mission files: YAML with line numbers, a JSON Schema, typed parameters, compile-time checks.

``load_mission(path)`` reads a mission file (and the files it includes), checks everything
that can be checked before anything runs, and returns a :class:`Mission`: a tree of
:class:`NodeSpec` with every skill input and output resolved to a literal, a mission
parameter or a blackboard key. Nothing here creates behaviours; ``hearth.executive.tree`` builds a
py_trees tree from a Mission, once per run.

Problems are :class:`~hearth.executive.errors.MissionError` with file and line; ``load_mission``
raises :class:`~hearth.executive.errors.MissionValidationError` carrying all of them, and
``validate_file`` returns them. The file format is documented in docs/missions.md.

YAML is read with a ``SafeLoader`` subclass: no Python objects, no tags beyond plain data,
finite numbers only, and aliases, nesting and tree size bounded (the limits in
missionfile_format.py; docs/missions.md, "Limits"), so that no file makes validation slow,
deep or large.

This module is the compiler and the public API (``load_mission``, ``compile_mission``,
``validate_file``, ``skill_registry``, ``schema``); its neighbours, bottom first:
missionfile_format.py (format version, node kinds, identifiers, limits), missionfile_yaml.py
(YAML with line numbers), missionfile_types.py (parameter and port types, values given as
text), missionfile_refs.py (literals, blackboard keys, parameters, conditions) and
missionfile_spec.py (the compiled ``Mission``, ``NodeSpec``, ``ParamSpec``).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Callable

import fastjsonschema
import jsonschema

from hearth.executive.errors import MissionError, MissionValidationError
from hearth.executive.missionfile_format import (
    COMMON_ATTRS, _IDENT_RE, _KEY_RE, KINDS, MAX_TREE_DEPTH, MAX_TREE_NODES, _PARAM_RE,
)
from hearth.executive.missionfile_refs import BBKey, Expr, Lit, Param, parse_expression, Ref
from hearth.executive.missionfile_spec import Mission, NodeSpec, ParamSpec
from hearth.executive.missionfile_types import (
    _alternatives, check_value, compatible, infer_type, _is_number, plain, _short, TYPES,
)
from hearth.executive.missionfile_yaml import line_of, LineDict, load_yaml


# ---------------------------------------------------------------------------------------
# Compiler
# ---------------------------------------------------------------------------------------
_SCHEMA: dict | None = None


def schema() -> dict:
    """The mission JSON Schema (``hearth/executive/schema/mission.schema.json``)."""
    global _SCHEMA
    if _SCHEMA is None:
        text = resources.files("hearth.executive").joinpath("schema/mission.schema.json").read_text()
        _SCHEMA = json.loads(text)
    return _SCHEMA


class _NodeValidator:
    """One node kind's schema: fastjsonschema (compiled to Python, some thirty times faster)
    lets a valid node through; jsonschema, the reference, finds the errors of any other, so
    the messages are jsonschema's. A node the fast check cannot handle goes to jsonschema."""

    def __init__(self, node_schema: dict):
        self.slow = jsonschema.Draft202012Validator(node_schema)
        try:
            self.fast = fastjsonschema.compile(node_schema)
        except Exception:  # noqa: BLE001 - a schema it cannot compile: jsonschema alone
            self.fast = None

    def valid_fast(self, data: Any) -> bool:
        if self.fast is None:
            return False
        try:
            self.fast(data)
        except Exception:  # noqa: BLE001 - JsonSchemaException, or data it cannot handle
            return False
        return True

    def iter_errors(self, data: Any):
        if self.valid_fast(data):
            return iter(())
        return self.slow.iter_errors(data)


_VALIDATORS: dict[str, _NodeValidator] = {}


def _validator(ref: str) -> _NodeValidator:
    """A validator for one node kind whose children are only checked to be mappings (the
    compiler checks each child itself, so every error points at its own node)."""
    if ref not in _VALIDATORS:
        defs = dict(schema()["$defs"])
        defs["child"] = {"type": "object"}
        defs["children"] = {"type": "array", "minItems": 1, "items": {"type": "object"}}
        _VALIDATORS[ref] = _NodeValidator({"$ref": ref, "$defs": defs})
    return _VALIDATORS[ref]


@dataclass
class _Scope:
    """Where names resolve while compiling one tree (the mission's, or an include's)."""
    file: str
    prefix: str                        # blackboard key prefix, "" at mission level
    params: dict[str, Ref]             # $name -> what it stands for
    param_types: dict[str, str]
    stack: tuple                       # (file, subtree) chain, for cycle detection
    subtrees: dict[str, Any]           # this file's subtrees section
    data: Any                          # this file's loaded YAML


class _Siblings:
    """The names taken among one node's children. ``claim`` makes a name unique by appending
    ``_2``, ``_3``, ...; a counter per base name keeps a wide tree linear (trying ``_2``
    upwards afresh for every ``skill: Say`` among 10,000 made validation quadratic)."""

    def __init__(self):
        self.taken: set[str] = set()
        self.next: dict[str, int] = {}

    def claim(self, name: str) -> str:
        if name in self.taken:
            base, n = name, self.next.get(name, 2)
            while f"{base}_{n}" in self.taken:
                n += 1
            name = f"{base}_{n}"
            self.next[base] = n + 1
        self.taken.add(name)
        return name


class _Compiler:
    def __init__(self, skills: dict[str, type], resolve_file: Callable[[str], str] | None = None):
        self.skills = skills
        self.root_dir: str | None = None    # includes stay inside the mission file's folder
        self.depth = 0
        self.count = 0
        self.errors: list[MissionError] = []
        self.writers: dict[str, tuple[str, str, int]] = {}
        self.readers: list[tuple[str, str, str, int]] = []
        self.files: list[str] = []
        self.params: dict[str, ParamSpec] = {}
        self.include_counter = 0
        self._docs: dict[str, Any] = {}

    # -- errors ------------------------------------------------------------------------
    def error(self, message: str, file: str, line: int) -> None:
        if len(message) > 300:      # a problem is one line a person reads
            message = message[:280] + " ..."
        self.errors.append(MissionError(message, file=file, line=line))

    # -- files -------------------------------------------------------------------------
    def load_doc(self, path: str) -> Any:
        if path in self._docs:
            return self._docs[path]
        data = load_yaml(path)
        self._docs[path] = data
        if path not in self.files:
            self.files.append(path)
        if not isinstance(data, LineDict):
            raise MissionError("a mission file is a YAML mapping with name and tree", file=path,
                               line=getattr(data, "line", 1) or 1)
        self.check_top(data, path)
        return data

    def check_top(self, data: LineDict, path: str) -> None:
        """Schema-check everything but the trees (those are checked node by node)."""
        top = {k: v for k, v in data.items() if k not in ("tree", "subtrees")}
        top["tree"] = {}
        sub = dict(schema())
        sub["properties"] = dict(sub["properties"], tree={"type": "object"},
                                 subtrees={"type": "object"})
        for err in jsonschema.Draft202012Validator(sub).iter_errors(top):
            self.error(_schema_message(err), path, line_of(data, list(err.absolute_path)))
        subtrees = data.get("subtrees")
        if subtrees is not None and not isinstance(subtrees, dict):
            self.error("subtrees: expected a mapping of NAME: {tree: ...}", path,
                       data.key_lines.get("subtrees", data.line))
        if isinstance(subtrees, dict):
            for name, st in subtrees.items():
                if not _IDENT_RE.match(str(name)):
                    self.error(f"subtree name {name!r} is not an identifier", path,
                               subtrees.key_lines.get(name, 0))
                if not isinstance(st, LineDict):
                    self.error(f"subtree {name}: expected a mapping with tree", path,
                               subtrees.key_lines.get(name, 0))
                    continue
                top = {k: v for k, v in st.items() if k != "tree"}
                top["tree"] = {}
                s2 = {"$defs": schema()["$defs"], **schema()["$defs"]["subtree"]}
                s2["properties"] = dict(s2["properties"], tree={"type": "object"})
                for err in jsonschema.Draft202012Validator(s2).iter_errors(top):
                    self.error(f"subtree {name}: {_schema_message(err)}", path,
                               line_of(st, list(err.absolute_path)) or st.line)

    def parse_params(self, section: Any, file: str, allow_runtime: bool) -> dict[str, ParamSpec]:
        out: dict[str, ParamSpec] = {}
        if not isinstance(section, LineDict):
            return out
        for name, spec in section.items():
            line = section.key_lines.get(name, 0)
            if not isinstance(spec, dict) or "type" not in spec or spec["type"] not in TYPES:
                continue  # the schema check has reported it
            # A malformed enum or items has been reported by the schema check too; leave it
            # out rather than compare values with it.
            enum, items = spec.get("enum"), spec.get("items")
            p = ParamSpec(name=name, type=spec["type"], default=plain(spec.get("default")),
                          required=bool(spec.get("required", spec.get("default") is None)),
                          runtime=bool(spec.get("runtime", False)),
                          enum=plain(enum) if isinstance(enum, list) else None,
                          items=items if items in TYPES else None,
                          description=str(spec.get("description", "")), line=line,
                          minimum=_bound(spec.get("minimum")), maximum=_bound(spec.get("maximum")),
                          kinds=_names(spec.get("kinds")), having=_names(spec.get("having")),
                          sentinels=_names(spec.get("sentinels")),
                          pick_only=spec.get("pick_only") is True)
            self.check_param_spec(p, file, line)
            if p.runtime and not allow_runtime:
                self.error(f"subtree parameter {name}: only mission parameters can be runtime",
                           file, line)
            if p.default is not None:
                try:
                    p.check(p.default)
                except MissionError as err:
                    self.error(f"parameter {name}: default {err.message}", file, line)
            out[name] = p
        return out

    def check_param_spec(self, p: ParamSpec, file: str, line: int) -> None:
        """What the schema cannot say about a parameter's map and bound declarations."""
        types = _alternatives(p.type)
        if (p.minimum is not None or p.maximum is not None) and \
                not any(t in ("integer", "number") for t in types):
            self.error(f"parameter {p.name}: minimum and maximum are for integer and number "
                       f"parameters", file, line)
        if p.minimum is not None and p.maximum is not None and p.minimum > p.maximum:
            self.error(f"parameter {p.name}: minimum {p.minimum:g} is above maximum "
                       f"{p.maximum:g}", file, line)
        if p.kinds and not any(t in ("node_id", "string") for t in types):
            self.error(f"parameter {p.name}: kinds are for node_id and string parameters",
                       file, line)
        if not p.kinds and (p.having or p.sentinels is not None or p.pick_only):
            self.error(f"parameter {p.name}: having, sentinels and pick_only need kinds",
                       file, line)

    # -- entry -------------------------------------------------------------------------
    def compile(self, path: str) -> Mission | None:
        self.root_dir = os.path.realpath(os.path.dirname(os.path.abspath(path)))
        data = self.load_doc(path)
        self.params = self.parse_params(data.get("parameters"), path, allow_runtime=True)
        blackboard: dict[str, Any] = {}
        bb = data.get("blackboard")
        if isinstance(bb, LineDict):
            for key, value in bb.items():
                blackboard[str(key)] = plain(value)
                self.writers.setdefault(str(key), (infer_type(value), path, bb.key_lines[key]))
        scope = _Scope(file=path, prefix="", params={n: Param(n) for n in self.params},
                       param_types={n: p.type for n, p in self.params.items()},
                       stack=((path, None),), subtrees=data.get("subtrees") or {}, data=data)
        root = None
        if "tree" in data:
            name = data.get("name")
            root = self.node(data["tree"], scope, "", data.key_lines.get("tree", data.line),
                             default_name=name if isinstance(name, str) else None)
        elif isinstance(data.get("subtrees"), LineDict):
            self.check_library(data, path)
        self.check_keys()
        if root is None and not self.errors:
            self.error("the file has subtrees but no tree: it can be included, not run", path,
                       data.line)
        if self.errors or root is None:
            return None
        interrupted = self.interrupted(data, path)
        if self.errors:
            return None
        return Mission(name=str(data.get("name")), description=str(data.get("description", "")),
                       file=path, parameters=self.params, root=root, blackboard=blackboard,
                       key_types={k: w[0] for k, w in self.writers.items()}, files=self.files,
                       interrupted=interrupted)

    def interrupted(self, data: LineDict, path: str) -> dict[str, str]:
        """The ``interrupted:`` declaration (the schema checked its shape): a resumed
        mission's progress key must be one its tree writes, its parameter a list it declares."""
        value = data.get("interrupted", "restart")
        line = data.key_lines.get("interrupted", data.line)
        if isinstance(value, str):
            if value == "resume":
                self.error("interrupted: resume needs progress (a key) and param (a "
                           "parameter): {then: resume, progress: KEY, param: NAME}", path, line)
            return {"then": value}
        out = {k: str(v) for k, v in value.items()}
        if out.get("then") == "resume":
            key, param = out.get("progress"), out.get("param")
            if key is None or param is None:
                self.error("interrupted: resume needs progress (a key) and param (a parameter)",
                           path, line)
            else:
                if key not in self.writers:
                    self.error(f"interrupted: progress key {{{key}}} is not written by the tree",
                               path, line)
                spec = self.params.get(param)
                if spec is None:
                    self.error(f"interrupted: param {param} is not a parameter of the mission",
                               path, line)
                elif spec.type not in ("list", "any"):
                    self.error(f"interrupted: param {param} is {spec.type}, a list is needed",
                               path, line)
        return out

    def check_library(self, data: LineDict, path: str) -> None:
        """A file of subtrees only: check each as if it were a mission of its own, its
        parameters standing for whatever an include will bind."""
        mission_params = self.params
        for name, body in data["subtrees"].items():
            if not isinstance(body, LineDict) or "tree" not in body:
                continue
            self.params = self.parse_params(body.get("parameters"), path, allow_runtime=False)
            scope = _Scope(file=path, prefix=f"{name}/", params={n: Param(n) for n in self.params},
                           param_types={n: p.type for n, p in self.params.items()},
                           stack=((path, name),), subtrees=data["subtrees"], data=data)
            self.node(body["tree"], scope, f"/{name}", body.key_lines.get("tree", body.line))
        self.params = mission_params

    def check_keys(self) -> None:
        for key, type_name, file, line in self.readers:
            w = self.writers.get(key)
            if w is None:
                shown = key.rsplit("/", 1)[-1]
                self.error(f"reads key {{{shown}}} that nothing writes", file, line)
            elif not compatible(w[0], type_name):
                self.error(f"key {{{key.rsplit('/', 1)[-1]}}} holds {w[0]} (written at "
                           f"{w[1]}:{w[2]}) but {type_name} is expected here", file, line)

    # -- refs --------------------------------------------------------------------------
    def key(self, scope: _Scope, name: str) -> str:
        return scope.prefix + name

    def ref(self, value: Any, scope: _Scope, line: int, what: str) -> Ref | None:
        """Resolve a mission-file value: '{key}', '$param' or a literal."""
        if isinstance(value, str):
            m = _KEY_RE.match(value)
            if m:
                return BBKey(self.key(scope, m.group(1)))
            m = _PARAM_RE.match(value)
            if m:
                if m.group(1) not in scope.params:
                    known = ", ".join(sorted(scope.params)) or "none"
                    self.error(f"{what}: unknown parameter ${m.group(1)} (declared: {known})",
                               scope.file, line)
                    return None
                return scope.params[m.group(1)]
        return Lit(plain(value))

    def ref_type(self, ref: Ref) -> str | None:
        if isinstance(ref, Param):
            return self.params[ref.name].type
        return None

    def use(self, ref: Ref, type_name: str, file: str, line: int, what: str) -> None:
        """Record/check that ``ref`` is read where ``type_name`` is expected."""
        if isinstance(ref, Lit):
            if not check_value(type_name, ref.value):
                self.error(f"{what}: expected {type_name}, got {_short(ref.value)}", file, line)
        elif isinstance(ref, Param):
            ptype = self.params[ref.name].type
            if not compatible(ptype, type_name):
                self.error(f"{what}: parameter ${ref.name} is {ptype}, {type_name} expected",
                           file, line)
        else:
            self.readers.append((ref.key, type_name, file, line))

    def write(self, key: str, type_name: str, file: str, line: int) -> None:
        old = self.writers.get(key)
        if old is not None and not compatible(old[0], type_name):
            self.error(f"key {{{key.rsplit('/', 1)[-1]}}} is written as {type_name} here but as "
                       f"{old[0]} at {old[1]}:{old[2]}", file, line)
        if old is None or old[0] == "any":
            self.writers[key] = (type_name, file, line)

    # -- nodes -------------------------------------------------------------------------
    def node(self, data: Any, scope: _Scope, parent_path: str, line: int,
             siblings: _Siblings | None = None, default_name: str | None = None
             ) -> NodeSpec | None:
        file = scope.file
        self.count += 1
        if self.count > MAX_TREE_NODES:
            # Stop compiling at once: an include bomb would go on doubling.
            raise MissionError(f"the tree has more than {MAX_TREE_NODES} nodes (includes counted "
                               "each time they are included)", file=file,
                               line=getattr(data, "line", 0) or line)
        if self.depth >= MAX_TREE_DEPTH:
            raise MissionError(f"the tree is more than {MAX_TREE_DEPTH} nodes deep", file=file,
                               line=getattr(data, "line", 0) or line)
        self.depth += 1
        try:
            return self._node(data, scope, parent_path, line, siblings, default_name)
        finally:
            self.depth -= 1

    def _node(self, data: Any, scope: _Scope, parent_path: str, line: int,
              siblings: _Siblings | None, default_name: str | None) -> NodeSpec | None:
        file = scope.file
        if not isinstance(data, LineDict):
            self.error(f"a tree node is a mapping with one kind ({', '.join(KINDS)}), "
                       f"not {type(data).__name__}", file, line)
            return None
        line = data.line or line
        kinds = [k for k in data if k in KINDS]
        if not kinds:
            unknown = [k for k in data if k not in COMMON_ATTRS]
            if unknown:
                self.error(f"unknown node kind {unknown[0]!r} (known: {', '.join(KINDS)})", file,
                           data.key_lines.get(unknown[0], line))
            else:
                self.error("node has no kind", file, line)
            return None
        if len(kinds) > 1:
            self.error(f"node has several kinds: {', '.join(kinds)}", file, line)
            return None
        kind = kinds[0]
        ok = True
        for err in _validator(f"#/$defs/{kind}").iter_errors(data):
            self.error(_schema_message(err), file, line_of(data, list(err.absolute_path)) or line)
            ok = False
        if not ok:
            return None
        default = data[kind] if kind in ("skill", "include") and isinstance(data[kind], str) else kind
        if kind == "include":
            default = str(default).rsplit("#", 1)[-1].rsplit("/", 1)[-1].removesuffix(".yaml")
        name = str(data.get("name") or default_name or default)
        if siblings is not None:
            name = siblings.claim(name)
        path = f"{parent_path}/{name}"
        spec = NodeSpec(kind=kind, name=name, path=path, file=file, line=line)
        handler = getattr(self, f"node_{kind}")
        return handler(spec, data, scope)

    def child(self, spec: NodeSpec, data: LineDict, scope: _Scope) -> NodeSpec | None:
        c = self.node(data[spec.kind], scope, spec.path, data.key_lines.get(spec.kind, spec.line))
        if c is None:
            return None
        spec.children = [c]
        return spec

    def children(self, spec: NodeSpec, data: LineDict, scope: _Scope) -> NodeSpec | None:
        seen = _Siblings()
        items = data[spec.kind]
        out = []
        for i, item in enumerate(items):
            c = self.node(item, scope, spec.path, items.item_lines[i], seen)
            if c is not None:
                out.append(c)
        if len(out) != len(items):
            return None
        spec.children = out
        return spec

    def node_sequence(self, spec, data, scope):
        spec.attrs["reactive"] = bool(data.get("reactive", False))
        return self.children(spec, data, scope)

    node_selector = node_sequence

    def node_parallel(self, spec, data, scope):
        policy = data.get("policy", "all")
        spec.attrs["policy"] = policy
        if policy == "threshold":
            if "threshold" not in data:
                self.error("parallel with policy threshold needs threshold: N", spec.file, spec.line)
                return None
            if data["threshold"] > len(data["parallel"]):
                self.error(f"threshold {data['threshold']} exceeds the {len(data['parallel'])} "
                           "children", spec.file, data.key_lines["threshold"])
                return None
            spec.attrs["threshold"] = int(data["threshold"])
        elif "threshold" in data:
            self.error("threshold only applies to policy: threshold", spec.file,
                       data.key_lines["threshold"])
            return None
        return self.children(spec, data, scope)

    def node_retry(self, spec, data, scope):
        spec.attrs["times"] = int(data["times"])
        return self.child(spec, data, scope)

    def node_repeat(self, spec, data, scope):
        spec.attrs["times"] = int(data.get("times", -1))
        return self.child(spec, data, scope)

    def node_timeout(self, spec, data, scope):
        spec.attrs["seconds"] = float(data["seconds"])
        return self.child(spec, data, scope)

    def node_inverter(self, spec, data, scope):
        return self.child(spec, data, scope)

    node_force_success = node_force_failure = node_inverter

    def node_for_each(self, spec, data, scope):
        line = data.key_lines["in"]
        source = self.ref(data["in"], scope, line, "for_each in")
        if source is None:
            return None
        item_type = "any"
        if isinstance(source, Param):
            item_type = self.params[source.name].items or "any"
        self.use(source, "list", spec.file, line, "for_each in")
        target = self.key(scope, data["as"])
        self.write(target, item_type, spec.file, data.key_lines["as"])
        spec.attrs.update(source=source, target=target, until=data.get("until", "failure"))
        return self.child(spec, data, scope)

    def expression(self, spec, text, scope, line) -> Expr | None:
        try:
            expr = parse_expression(text)
        except ValueError as err:
            self.error(str(err), spec.file, line)
            return None
        if not expr.either:
            return self._resolve(expr, spec, text, scope, line)
        groups = []
        for group in expr.either:
            done = [self._resolve(e, spec, text, scope, line) for e in group]
            if any(e is None for e in done):
                return None
            groups.append(tuple(done))
        return Expr(text=text, left=None, either=tuple(groups))

    def _resolve(self, expr: Expr, spec, text, scope, line) -> Expr | None:
        resolved = []
        for r in (expr.left, expr.right):
            if r is None:
                resolved.append(None)
                continue
            if isinstance(r, BBKey):
                r = BBKey(self.key(scope, r.key))
                self.readers.append((r.key, "any", spec.file, line))
            elif isinstance(r, Param):
                if r.name not in scope.params:
                    self.error(f"condition: unknown parameter ${r.name}", spec.file, line)
                    return None
                r = scope.params[r.name]
            resolved.append(r)
        if expr.op in ("<", "<=", ">", ">="):
            for r in resolved:
                if isinstance(r, Lit) and not _is_number(r.value):
                    self.error(f"condition {text!r}: {expr.op} compares numbers, not {r.value!r}",
                               spec.file, line)
                    return None
        return Expr(text=expr.text, left=resolved[0], op=expr.op, right=resolved[1],
                    negate=expr.negate)

    def node_condition(self, spec, data, scope):
        expr = self.expression(spec, data["condition"], scope, data.key_lines["condition"])
        if expr is None:
            return None
        spec.attrs["expr"] = expr
        return spec

    def node_guard(self, spec, data, scope):
        expr = self.expression(spec, data["while"], scope, data.key_lines["while"])
        if expr is None:
            return None
        spec.attrs["expr"] = expr
        return self.child(spec, data, scope)

    def node_watch(self, spec, data, scope):
        names = []
        for i, raw in enumerate(data["params"]):
            line = data["params"].item_lines[i]
            pname = raw.lstrip("$")
            ref = scope.params.get(pname)
            if ref is None:
                self.error(f"watch: unknown parameter ${pname}", spec.file, line)
                return None
            if not isinstance(ref, Param) or not self.params[ref.name].runtime:
                self.error(f"watch: ${pname} is not a runtime parameter (declare it with "
                           "runtime: true)", spec.file, line)
                return None
            names.append(ref.name)
        spec.attrs["params"] = names
        return self.child(spec, data, scope)

    def node_succeed(self, spec, data, scope):
        spec.attrs["message"] = data.get(spec.kind) or ""
        return spec

    node_fail = node_succeed

    def node_skill(self, spec, data, scope):
        name = data["skill"]
        cls = self.skills.get(name)
        if cls is None:
            close = [s for s in sorted(self.skills) if s.lower() == name.lower()]
            hint = f"; did you mean {close[0]}?" if close else ""
            self.error(f"unknown skill {name!r}{hint}", spec.file, data.key_lines["skill"])
            return None
        spec.skill, spec.skill_name = cls, name
        inputs = data.get("inputs") or LineDict()
        outputs = data.get("outputs") or LineDict()
        ok = True
        for port_name, value in inputs.items():
            line = inputs.key_lines.get(port_name, spec.line)
            port = cls.port(port_name)
            if port is None:
                known = ", ".join(p.name for p in cls.INPUTS) or "none"
                self.error(f"skill {name} has no input {port_name!r} (inputs: {known})",
                           spec.file, line)
                ok = False
                continue
            ref = self.ref(value, scope, line, f"{name}.{port_name}")
            if ref is None:
                ok = False
                continue
            self.use(ref, port.type, spec.file, line, f"input {port_name} of {name}")
            spec.inputs[port_name] = ref
        for port in cls.INPUTS:
            if port.required and port.default is None and port.name not in inputs:
                self.error(f"skill {name}: missing required input {port.name!r} ({port.type})",
                           spec.file, spec.line)
                ok = False
        for port_name, value in outputs.items():
            line = outputs.key_lines.get(port_name, spec.line)
            port = cls.port(port_name, outputs=True)
            if port is None:
                known = ", ".join(p.name for p in cls.OUTPUTS) or "none"
                self.error(f"skill {name} has no output {port_name!r} (outputs: {known})",
                           spec.file, line)
                ok = False
                continue
            ref = self.ref(value if _KEY_RE.match(value) or _PARAM_RE.match(value)
                           else "{" + value + "}", scope, line, f"{name}.{port_name}")
            if ref is None or not _IDENT_RE.match(value.strip("{}$")):
                if ref is not None:
                    self.error(f"output {port_name}: {_short(value)} is not a key name", spec.file,
                               line)
                ok = False
                continue
            if not isinstance(ref, BBKey):
                self.error(f"output {port_name} of {name}: {value} is not bound to a blackboard "
                           "key here", spec.file, line)
                ok = False
                continue
            self.write(ref.key, port.type, spec.file, line)
            spec.outputs[port_name] = ref
        return spec if ok else None

    def node_include(self, spec, data, scope):
        target = data["include"]
        line = data.key_lines["include"]
        file, sub = scope.file, target
        if "\x00" in target:
            self.error(f"include {_short(target)}: the path holds a NUL byte", scope.file, line)
            return None
        if "#" in target or target.endswith((".yaml", ".yml")):
            fpart, _, sub = target.partition("#")
            file = str((Path(scope.file).parent / fpart).resolve()) if fpart else scope.file
            if fpart and not self.inside_root(file):
                self.error(f"include {target!r}: the file is outside the mission's folder "
                           f"({_display_path(self.root_dir)})", scope.file, line)
                return None
            file = _display_path(file)
            sub = sub or None
            try:
                doc = self.load_doc(file)
            except MissionError as err:
                self.error(f"include {target!r}: {err}", scope.file, line)
                return None
        else:
            doc = scope.data if file == scope.file else self.load_doc(file)
        if not isinstance(doc, dict):       # an empty or truncated file (a document of nothing)
            self.error(f"include {target!r}: {Path(file).name} holds no mission document",
                       scope.file, line)
            return None
        key = (file, sub)
        if key in scope.stack:
            chain = " -> ".join(f"{Path(f).name}#{s}" if s else Path(f).name
                                for f, s in scope.stack + (key,))
            self.error(f"cyclic include: {chain}", scope.file, line)
            return None
        if sub is None:
            body, params_section = doc, doc.get("parameters")
        else:
            subtrees = doc.get("subtrees")
            if not isinstance(subtrees, dict):   # a malformed section: reported by check_top
                subtrees = {}
            if sub not in subtrees or not isinstance(subtrees[sub], LineDict):
                known = ", ".join(sorted(subtrees)) or "none"
                self.error(f"include: no subtree {sub!r} in {Path(file).name} (subtrees: {known})",
                           scope.file, line)
                return None
            body = subtrees[sub]
            params_section = body.get("parameters")
        if "tree" not in body:
            self.error(f"include {target!r}: it has no tree", scope.file, line)
            return None
        declared = self.parse_params(params_section, file, allow_runtime=sub is None)
        given = data.get("params") or LineDict()
        bound: dict[str, Ref] = {}
        ok = True
        for pname, value in given.items():
            pline = given.key_lines.get(pname, line)
            if pname not in declared:
                known = ", ".join(sorted(declared)) or "none"
                self.error(f"include {target}: unknown parameter {pname!r} (declared: {known})",
                           scope.file, pline)
                ok = False
                continue
            ref = self.ref(value, scope, pline, f"include {target} param {pname}")
            if ref is None:
                ok = False
                continue
            self.use(ref, declared[pname].type, scope.file, pline, f"include param {pname}")
            bound[pname] = ref
        for pname, p in declared.items():
            if pname not in bound:
                if p.default is not None:
                    bound[pname] = Lit(plain(p.default))
                elif p.required:
                    self.error(f"include {target}: missing parameter {pname!r} ({p.type})",
                               scope.file, line)
                    ok = False
        if not ok:
            return None
        self.include_counter += 1
        inner = _Scope(file=file, prefix=f"{scope.prefix}{spec.name}_{self.include_counter}/",
                       params=bound, param_types={n: p.type for n, p in declared.items()},
                       stack=scope.stack + (key,), subtrees=doc.get("subtrees") or {}, data=doc)
        spec.attrs["target"] = target
        c = self.node(body["tree"], inner, spec.path, body.key_lines.get("tree", body.line))
        if c is None:
            return None
        spec.children = [c]
        return spec

    def inside_root(self, file: str) -> bool:
        """Whether ``file`` (symbolic links followed) is inside the top mission file's folder:
        a mission from elsewhere must not make Hearth read ``/etc/passwd`` or ``/proc``."""
        real = os.path.realpath(file)
        return self.root_dir is not None and os.path.commonpath([self.root_dir, real]) == self.root_dir

    def node_state_machine(self, spec, data, scope):
        sm = data["state_machine"]
        states: LineDict = sm["states"]
        outcomes: LineDict = sm["outcomes"]
        ok = True
        if sm["initial"] not in states:
            self.error(f"state_machine: initial state {sm['initial']!r} is not a state",
                       spec.file, sm.key_lines["initial"])
            ok = False
        for name in outcomes:
            if name in states:
                self.error(f"state_machine: {name!r} is both a state and an outcome", spec.file,
                           outcomes.key_lines[name])
                ok = False
        table = []
        seen = _Siblings()
        for sname, sdata in states.items():
            sline = states.key_lines[sname]
            child = self.node(sdata["do"], scope, spec.path, sdata.key_lines["do"], seen)
            if child is None:
                ok = False
                continue
            child.attrs["state"] = sname
            trans: LineDict = sdata["transitions"]
            outcome_key = None
            if "outcome" in sdata:
                # A named outcome read from a key when the node succeeds (SMACH's outcome
                # strings); failure stays "failure". Any name may be mapped.
                if child.kind == "state_machine":
                    self.error(f"state {sname}: a nested state machine has its own outcomes; "
                               "outcome: is for other nodes", spec.file,
                               sdata.key_lines["outcome"])
                    ok = False
                outcome_key = self.key(scope, sdata["outcome"][1:-1])
                self.readers.append((outcome_key, "string", spec.file, sdata.key_lines["outcome"]))
                possible = list(dict.fromkeys(["failure", *trans]))
            elif child.kind == "state_machine":
                possible = list(child.attrs["outcomes"])
            else:
                possible = ["success", "failure"]
            for outcome, target in trans.items():
                tline = trans.key_lines[outcome]
                if outcome not in possible:
                    self.error(f"state {sname}: {outcome!r} is not an outcome of its node "
                               f"(outcomes: {', '.join(possible)})", spec.file, tline)
                    ok = False
                if target not in states and target not in outcomes:
                    self.error(f"state {sname}: transition to unknown state or outcome "
                               f"{target!r}", spec.file, tline)
                    ok = False
            for outcome in possible:
                if outcome not in trans:
                    self.error(f"state {sname}: outcome {outcome!r} has no transition", spec.file,
                               sline)
                    ok = False
            spec.children.append(child)
            table.append((sname, dict(trans)))
            if outcome_key is not None:
                child.attrs["outcome_key"] = outcome_key
        if not ok:
            return None
        spec.attrs.update(initial=sm["initial"], states=table, outcomes=dict(outcomes))
        return spec


def _display_path(path: str) -> str:
    try:
        return str(Path(path).resolve().relative_to(Path.cwd()))
    except ValueError:
        return path


def _bound(value: Any) -> float | None:
    return value if _is_number(value) else None


def _names(value: Any) -> list[str] | None:
    return [str(v) for v in value] if isinstance(value, list) else None


def _schema_message(err: jsonschema.ValidationError) -> str:
    where = ".".join(str(p) for p in err.absolute_path)
    if err.validator == "additionalProperties":
        extra = sorted(set(map(str, err.instance)) - set(err.schema.get("properties", {})))
        msg = f"unknown attribute {_short(extra[0])}" if extra else err.message
    elif err.validator == "required":
        msg = err.message.replace("is a required property", "is required")
    elif err.validator == "pattern":
        msg = f"{_short(err.instance)} is not a valid name"
    elif err.validator in ("enum", "const"):
        allowed = err.schema.get("enum", [err.schema.get("const")])
        msg = f"{_short(err.instance)} is not one of {_short(allowed)}"
    elif err.validator == "type":
        msg = f"{_short(err.instance)} is not of type {_short(err.validator_value)}"
    elif err.validator == "maxLength":
        msg = (f"{_short(err.instance)} is too long ({len(err.instance)} characters; at most "
               f"{err.validator_value})")
    else:
        msg = err.message
    if len(msg) > 240:
        msg = msg[:200] + " ..."
    return f"{where}: {msg}" if where else msg


# ---------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------
def _registry(skills: dict[str, type] | None) -> dict[str, type]:
    if skills is not None:
        return skills
    return skill_registry()


def skill_registry() -> dict[str, type]:
    """``hearth.skills.base.registry()``, with a broken skill module reported as one MissionError
    line instead of a traceback."""
    from hearth.skills.base import registry
    try:
        return registry()
    except Exception as err:  # noqa: BLE001 - any import-time failure of a skill module
        raise MissionError(f"cannot load the skill registry: {type(err).__name__}: {err}") \
            from None


def compile_mission(path: str | Path, skills: dict[str, type] | None = None
                    ) -> tuple[Mission | None, list[MissionError]]:
    comp = _Compiler(_registry(skills))
    try:
        mission = comp.compile(str(path))
    except MissionError as err:
        return None, comp.errors + [err]
    return mission, comp.errors


def load_mission(path: str | Path, skills: dict[str, type] | None = None) -> Mission:
    """Load and check a mission file; raises MissionValidationError listing every problem.

    ``skills`` maps skill names to classes (default: ``hearth.skills.base.registry()``).
    """
    mission, errors = compile_mission(path, skills)
    if errors or mission is None:
        raise MissionValidationError(errors or [MissionError("invalid mission", file=str(path))])
    return mission


def validate_file(path: str | Path, skills: dict[str, type] | None = None) -> list[MissionError]:
    """Every problem in a mission file (and its includes), each with file and line. A file
    with subtrees and no tree (a library for includes) is valid when every subtree is."""
    errors = compile_mission(path, skills)[1]
    return [e for e in errors if not e.message.startswith("the file has subtrees but no tree")]
