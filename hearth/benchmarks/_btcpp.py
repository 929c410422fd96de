"""BehaviorTree.CPP's side: exported missions loaded and ticked by BT.CPP itself, through
``behaviortreepy`` (Python bindings of BehaviorTree.CPP v4; the ``btcpp`` extra).

``standin_tree(xml)`` loads ``hearth export`` XML in BT.CPP's factory with every Hearth node
type of the file's ``<TreeNodesModel>`` registered as a Python stand-in: skills and leaves as
actions or conditions that record their calls and succeed (or, for the benchmark, run a
number of ticks), Hearth's decorators (ForEach, Watch, Guard, State) as decorators that
pass their child's status on.

One limit of behaviortreepy 0.1.4: a node registered from Python has no ports (its
``register_simple_*`` take no port list), and BT.CPP refuses a port attribute that a node's
manifest does not declare. So before loading, each port attribute of a stand-in node is
checked here against the model and renamed ``_NAME`` (an attribute BT.CPP keeps as a non-port
attribute). Everything else is BT.CPP's own check: the document, the tree IDs, every
built-in node and its typed ports (RetryUntilSuccessful num_attempts, Timeout msec,
Parallel counts, Repeat num_cycles), the number of children of each node, SubTree references
and remapping, the mandatory ports of each ``<SubTree>`` model. BT.CPP cannot register a
Python control node at all, so a mission with a state machine cannot be loaded this way.

``tick_times(path, skills, ...)`` is ``hearth bench executive``'s BT.CPP figure: the same
200-node tree, exported by ``hearth export`` and ticked by BT.CPP with Python leaves.
"""
from __future__ import annotations

import gc
import statistics
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from lxml import etree

#: Tags BT.CPP knows (never stand-ins), and the model element kinds.
_KINDS = ("Action", "Condition", "Decorator", "Control")


def missing() -> str | None:
    """Why BT.CPP cannot be used here (None: behaviortreepy imports)."""
    try:
        import behaviortreepy  # noqa: F401
    except ImportError as err:
        return f"behaviortreepy is not installed ({err}); pip install -e '.[btcpp]'"
    return None


@dataclass
class StandinTree:
    """A BT.CPP tree of stand-ins: ``tree`` (behaviortreepy Tree), ``calls`` (the name of
    each stand-in leaf ticked, in order), ``xml`` (what was handed to the factory)."""
    tree: Any
    factory: Any
    xml: str
    calls: list[str] = field(default_factory=list)
    models: dict[str, tuple[str, set[str]]] = field(default_factory=dict)


def read_models(root: etree._Element) -> dict[str, tuple[str, set[str]]]:
    """``<TreeNodesModel>`` entries other than SubTree: ID -> (kind, port names)."""
    out: dict[str, tuple[str, set[str]]] = {}
    for models in root.iter("TreeNodesModel"):
        for m in models:
            if m.tag in _KINDS and m.get("ID"):
                names = {p.get("name") for p in m
                         if p.tag in ("input_port", "output_port", "inout_port")}
                out[m.get("ID")] = (m.tag, names)
    return out


def prepare(xml: str) -> tuple[str, dict[str, tuple[str, set[str]]]]:
    """The XML with each stand-in node's port attributes renamed ``_NAME`` (see the module
    docstring), after checking that each is a port of its model; ValueError if not."""
    root = etree.fromstring(xml.encode("utf-8"), etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, remove_comments=True))
    models = read_models(root)
    for tree in root.iter("BehaviorTree"):
        for el in tree.iter():
            if el.tag not in models:
                continue
            ports = models[el.tag][1]
            for attr in list(el.attrib):
                if attr == "name" or attr.startswith("_"):
                    continue
                if attr not in ports:
                    raise ValueError(f"line {el.sourceline}: <{el.tag}> has no port {attr!r} "
                                     "in its model")
                el.set(f"_{attr}", el.attrib.pop(attr))
    return etree.tostring(root, encoding="unicode"), models


def standin_tree(xml: str, leaf: Callable[[Any], Any] | None = None,
                 stateful: dict[str, tuple[Callable, Callable]] | None = None,
                 blackboard: Any = None) -> StandinTree:
    """Load ``xml`` (``hearth export`` output) in BT.CPP's factory with stand-ins from its
    model (on ``blackboard``, a behaviortreepy Blackboard, when given). ``leaf(node)`` is
    what a plain stand-in leaf returns (default SUCCESS);
    ``stateful`` maps a node ID to (on_start, on_running) for stateful stand-ins. Raises
    RuntimeError (BT.CPP's own message) when the factory refuses the tree."""
    import behaviortreepy as bt

    prepared, models = prepare(xml)
    factory = bt.BehaviorTreeFactory()
    out = StandinTree(tree=None, factory=factory, xml=prepared, models=models)
    success = bt.NodeStatus.SUCCESS

    def record(node: Any) -> Any:
        out.calls.append(node.name())
        return leaf(node) if leaf is not None else success

    for tid, (kind, _) in sorted(models.items()):
        if stateful and tid in stateful:
            on_start, on_running = stateful[tid]
            factory.register_simple_stateful_action(tid, on_start, on_running)
        elif kind == "Action":
            factory.register_simple_action(tid, record)
        elif kind == "Condition":
            factory.register_simple_condition(tid, record)
        elif kind == "Decorator":
            factory.register_simple_decorator(tid, lambda status, node: status)
        else:
            raise RuntimeError(f"{tid}: behaviortreepy cannot register a Python control node")
    out.tree = factory.create_tree_from_text(prepared, blackboard)
    return out


# ---------------------------------------------------------------------------------------
# hearth bench executive: the same tree ticked by BehaviorTree.CPP
# ---------------------------------------------------------------------------------------
def tick_times(path: str, skills: dict[str, type], ticks: int, warmup: int = 50,
               leaf_id: str = "BenchWork", port: str = "ticks",
               on_start: Callable[[str], None] | None = None) -> list[float] | str:
    """Per-tick wall times (s) of the mission at ``path`` exported and ticked by BT.CPP
    (``tick_exactly_once``), each ``leaf_id`` leaf a Python stateful action that runs for
    its ``port`` input's number of ticks, as the Hearth skill does (``on_start(name)`` is
    called at each start, for tests). A string says why not."""
    reason = missing()
    if reason:
        return reason
    import behaviortreepy as bt

    from hearth.executive.btcpp import export_mission
    from hearth.executive.missionfile import load_mission

    mission = load_mission(path, skills)
    duration = {n.name: int(n.inputs[port].value) for n in mission.nodes()
                if n.kind == "skill" and n.skill_name == leaf_id}
    left: dict[str, int] = {}
    RUNNING, SUCCESS = bt.NodeStatus.RUNNING, bt.NodeStatus.SUCCESS

    def step(name: str) -> Any:
        n = left[name]
        if n > 0:
            left[name] = n - 1
            return RUNNING
        return SUCCESS

    def start(node: Any) -> Any:
        name = node.name()
        left[name] = duration[name]
        if on_start is not None:
            on_start(name)
        return step(name)

    def on_running(node: Any) -> Any:
        return step(node.name())

    try:
        st = standin_tree(export_mission(path, skills), stateful={leaf_id: (start, on_running)})
    except RuntimeError as err:
        return f"BehaviorTree.CPP refused the tree: {err}"
    tick = st.tree.tick_exactly_once
    perf = time.perf_counter
    for _ in range(warmup):
        tick()
    gc.collect()
    times = []
    for _ in range(ticks):
        t0 = perf()
        tick()
        times.append(perf() - t0)
    return times


def figures(times: list[float] | str, hearth_median_s: float) -> dict:
    """``btcpp_tick_ms`` (median), its mean and ``tick_ratio_vs_btcpp`` (Hearth / BT.CPP),
    or nulls and ``btcpp_note`` saying why."""
    if isinstance(times, str):
        return {"btcpp_tick_ms": None, "btcpp_tick_ms_mean": None, "tick_ratio_vs_btcpp": None,
                "btcpp_note": times}
    med = statistics.median(times)
    return {"btcpp_tick_ms": round(med * 1e3, 4),
            "btcpp_tick_ms_mean": round(statistics.fmean(times) * 1e3, 4),
            "tick_ratio_vs_btcpp": round(hearth_median_s / med, 2)}
