"""BT.CPP v4 XML back into a mission (``import_tree``): the XML read safely (``parse_xml``: no
entities, no DTD, no network), BT.CPP idioms lowered into Hearth nodes, and every problem a
MissionError with the XML file and line."""
from __future__ import annotations

import json
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from lxml import etree

from hearth.executive.btcpp_export import output_port_name, _read_pairs
from hearth.executive.btcpp_format import (
    _alts, _CHECKS, CUSTOM, decode_literal, _EXPR_TOKEN, _IDENT, _KEY, LOWERED_PORTS,
    _pointer_like, REFUSED, SCRIPT_ATTRS, SKIP_AS,
)
from hearth.executive.btcpp_script import script_assignments, script_condition, _script_tokens
from hearth.executive.errors import MissionError, MissionValidationError
from hearth.executive.missionfile import KINDS as _KINDS_ALL
from hearth.executive.missionfile import Mission, compile_mission, skill_registry
from hearth.executive.missionfile_yaml import LineDict, LineList, load_yaml_text


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
