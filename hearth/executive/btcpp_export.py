"""A checked mission as BT.CPP v4 XML (``export_mission``): one ``<BehaviorTree>`` per tree,
``{key}`` remapping, a ``<TreeNodesModel>`` with every skill's ports (``skill_model``) and
Hearth's own node types (``custom_model``); ``nodes_header`` is their C++ header."""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

from lxml import etree

from hearth.executive.btcpp_format import (
    BT_NAMES, _CHECKS, CUSTOM, DECORATOR_TAGS, encode_literal, _EXPR_TOKEN, _IDENT, _KEY,
    _PARAM, SELECTOR, SEQUENCE,
)
from hearth.executive.errors import MissionError
from hearth.executive.missionfile import Mission, load_mission, plain, skill_registry
from hearth.executive.missionfile_yaml import LineDict, load_yaml


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
