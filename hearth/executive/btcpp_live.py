"""The tree a running mission shows over the Groot2 protocol (``live_tree``;
hearth.executive.groot2): the compiled tree with every include expanded, each node with its
``_uid``, as BT.CPP's ``WriteTreeToXML(tree, add_metadata=true)`` writes it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lxml import etree

from hearth.executive.btcpp_export import custom_model, output_port_name, _pairs, skill_model
from hearth.executive.btcpp_format import (
    CUSTOM, DECORATOR_TAGS, encode_literal, SELECTOR, SEQUENCE,
)
from hearth.executive.missionfile import BBKey, Lit, Mission, NodeSpec, Param


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
