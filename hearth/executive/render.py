"""Drawing mission trees: ASCII (with statuses while running) and Graphviz dot."""
from __future__ import annotations

from typing import Any

from hearth.executive.missionfile import BBKey, Lit, NodeSpec, Ref

_MARK = {"SUCCESS": "+", "FAILURE": "x", "RUNNING": "*", "INVALID": "-"}


def ref_text(ref: Ref) -> str:
    if isinstance(ref, Lit):
        return repr(ref.value)
    if isinstance(ref, BBKey):
        return "{" + ref.key + "}"
    return "$" + ref.name


def describe(spec: NodeSpec) -> str:
    """One line about a node: kind, name and the attributes that matter."""
    a = spec.attrs
    if spec.kind == "skill":
        ins = ", ".join(f"{k}={ref_text(v)}" for k, v in spec.inputs.items())
        outs = ", ".join(f"{k}->{{{v.key}}}" for k, v in spec.outputs.items())
        name = "" if spec.name == spec.skill_name else f" {spec.name}"
        return f"{spec.skill_name}{name}({ins})" + (f" -> {outs}" if outs else "")
    extra = {
        "sequence": lambda: "reactive" if a["reactive"] else "memory",
        "selector": lambda: "reactive" if a["reactive"] else "memory",
        "parallel": lambda: a["policy"] + (f" {a['threshold']}" if "threshold" in a else ""),
        "retry": lambda: f"{a['times']} attempts",
        "repeat": lambda: "forever" if a["times"] < 0 else f"{a['times']} times",
        "timeout": lambda: f"{a['seconds']:g} s",
        "for_each": lambda: f"{{{a['target']}}} in {ref_text(a['source'])}, until {a['until']}",
        "condition": lambda: a["expr"].text,
        "guard": lambda: f"while {a['expr'].text}",
        "watch": lambda: ", ".join("$" + p for p in a["params"]),
        "include": lambda: a["target"],
        "state_machine": lambda: f"initial {a['initial']}, outcomes "
                                 + ", ".join(f"{k}={v}" for k, v in a["outcomes"].items()),
        "succeed": lambda: a.get("message") or "",
        "fail": lambda: a.get("message") or "",
    }.get(spec.kind, lambda: "")()
    state = f"[{a['state']}] " if "state" in a else ""
    name = "" if spec.name == spec.kind else f" {spec.name}"
    return f"{state}{spec.kind}{name}" + (f" ({extra})" if extra else "")


def ascii_tree(root: NodeSpec, statuses: dict[str, str] | None = None,
               feedback: dict[str, str] | None = None) -> str:
    """The tree as indented lines; with ``statuses`` (path -> status name) each line starts
    with + success, x failure, * running, - not running."""
    lines: list[str] = []

    def walk(spec: NodeSpec, prefix: str, last: bool, top: bool) -> None:
        branch = "" if top else ("`-- " if last else "|-- ")
        mark = ""
        if statuses is not None:
            mark = _MARK.get(statuses.get(spec.path, "INVALID"), "?") + " "
        fb = ""
        if feedback and feedback.get(spec.path):
            fb = f"  -- {feedback[spec.path]}"
        lines.append(f"{mark}{prefix}{branch}{describe(spec)}{fb}")
        child_prefix = prefix if top else prefix + ("    " if last else "|   ")
        for i, c in enumerate(spec.children):
            walk(c, child_prefix, i == len(spec.children) - 1, False)

    walk(root, "", True, True)
    return "\n".join(lines)


def dot_tree(root: NodeSpec, title: str = "mission") -> str:
    """Graphviz dot source for the tree (render with ``dot -Tsvg``)."""
    shapes = {"sequence": "box", "selector": "octagon", "parallel": "parallelogram",
              "skill": "ellipse", "condition": "diamond", "state_machine": "box3d",
              "include": "folder"}
    out = [f'digraph "{title}" {{', "  node [fontname=Helvetica];"]
    ids: dict[str, str] = {}
    for i, spec in enumerate(root.walk()):
        ids[spec.path] = f"n{i}"
        label = describe(spec).replace('"', '\\"')
        shape = shapes.get(spec.kind, "box" if spec.children else "ellipse")
        out.append(f'  n{i} [label="{label}", shape={shape}];')
    for spec in root.walk():
        for c in spec.children:
            out.append(f"  {ids[spec.path]} -> {ids[c.path]};")
    out.append("}")
    return "\n".join(out)


def blackboard_text(values: dict[str, Any]) -> str:
    if not values:
        return "(blackboard empty)"
    width = max(len(k) for k in values)
    return "\n".join(f"{k:<{width}} = {v!r}" for k, v in values.items())
