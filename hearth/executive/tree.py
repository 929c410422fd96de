"""Build a py_trees tree from a checked Mission, once per run.

Every run gets its own blackboard namespace ``ns`` (e.g. ``/hearth/r3``): mission keys live
under ``{ns}/bb/``, parameters under ``{ns}/params/``, so several missions (queued,
preempted, tests side by side) never see each other's values. ``teardown`` removes them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import py_trees
from py_trees import common
from py_trees.behaviour import Behaviour
from py_trees.blackboard import Blackboard

from hearth.executive import nodes
from hearth.executive.missionfile import BBKey, Lit, Mission, NodeSpec, Param, Ref
from hearth.skills.base import Bindings, Key, Literal

#: ``make_skill(spec, bindings) -> Behaviour``: how a skill node is instantiated; the default
#: makes ``spec.skill``; substitution and replay give stand-ins.
SkillFactory = Callable[[NodeSpec, Bindings], Behaviour]


def default_factory(spec: NodeSpec, bindings: Bindings) -> Behaviour:
    return spec.skill(name=spec.name, bindings=bindings)


@dataclass
class BuiltTree:
    """A run's behaviours: ``root``, each node by tree path, and the key helpers."""
    root: Behaviour
    ns: str
    mission: Mission
    nodes: dict[str, Behaviour] = field(default_factory=dict)
    path_of: dict[int, str] = field(default_factory=dict)     # id(behaviour) -> path
    specs: dict[str, NodeSpec] = field(default_factory=dict)

    def bb_key(self, key: str) -> str:
        return f"{self.ns}/bb/{key}"

    def param_key(self, name: str) -> str:
        return f"{self.ns}/params/{name}"

    def short_key(self, full: str) -> str:
        """``/hearth/r3/bb/pose`` -> ``pose``; ``.../params/presence`` -> ``$presence``."""
        if full.startswith(f"{self.ns}/bb/"):
            return full[len(self.ns) + 4:]
        if full.startswith(f"{self.ns}/params/"):
            return "$" + full[len(self.ns) + 8:]
        return full

    def read(self, ref: Ref) -> Any:
        if isinstance(ref, Lit):
            return ref.value
        full = self.bb_key(ref.key) if isinstance(ref, BBKey) else self.param_key(ref.name)
        return Blackboard.storage.get(full, nodes.MISSING)

    def read_key(self, full: str) -> Any:
        return Blackboard.storage.get(full, nodes.MISSING)

    def write_param(self, name: str, value: Any) -> None:
        Blackboard.set(self.param_key(name), value)

    def blackboard(self) -> dict[str, Any]:
        """Mission keys and parameters with their current values (short names)."""
        prefix = self.ns + "/"
        return {self.short_key(k): v for k, v in sorted(Blackboard.storage.items())
                if k.startswith(prefix)}

    def outputs(self) -> dict[str, Any]:
        """The mission's own keys (not parameters, not include-private keys)."""
        prefix = f"{self.ns}/bb/"
        return {k[len(prefix):]: v for k, v in Blackboard.storage.items()
                if k.startswith(prefix) and "/" not in k[len(prefix):]}

    def setup(self, **kwargs: Any) -> None:
        """py_trees setup on every node, deepest first (world=, robot=, clock=...)."""
        for node in self.root.iterate():
            node.setup(**kwargs)

    def teardown(self) -> None:
        """Unregister blackboard clients and remove this run's keys."""
        for node in self.root.iterate():
            for client in getattr(node, "blackboards", []):
                try:
                    client.unregister(clear=False)
                except Exception:  # noqa: BLE001 - best effort cleanup
                    pass
            try:
                node.shutdown()
            except Exception:  # noqa: BLE001
                pass
        prefix = self.ns + "/"
        for k in [k for k in Blackboard.storage if k.startswith(prefix)]:
            Blackboard.storage.pop(k, None)
            Blackboard.metadata.pop(k, None)


def _reads(spec: NodeSpec, built: BuiltTree) -> list[str]:
    """Blackboard keys a condition, guard, watch or for-each node reads."""
    refs: list[Ref] = []
    if spec.kind in ("condition", "guard"):
        refs = spec.attrs["expr"].refs()
    elif spec.kind == "for_each":
        refs = [spec.attrs["source"]]
    elif spec.kind == "watch":
        return [built.param_key(p) for p in spec.attrs["params"]]
    out = []
    for r in refs:
        if isinstance(r, BBKey):
            out.append(built.bb_key(r.key))
        elif isinstance(r, Param):
            out.append(built.param_key(r.name))
    return out


def build_tree(mission: Mission, params: dict[str, Any], ns: str,
               make_skill: SkillFactory | None = None) -> BuiltTree:
    """Create the behaviours of ``mission`` and write its parameters and initial keys."""
    make_skill = make_skill or default_factory
    built = BuiltTree(root=None, ns=ns, mission=mission)  # type: ignore[arg-type]

    def binding(ref: Ref) -> Literal | Key:
        if isinstance(ref, Lit):
            return Literal(ref.value)
        if isinstance(ref, BBKey):
            return Key(built.bb_key(ref.key))
        return Key(built.param_key(ref.name))

    def make(spec: NodeSpec) -> Behaviour:
        kids = [make(c) for c in spec.children]
        k, a, name = spec.kind, spec.attrs, spec.name
        if k == "sequence":
            node = py_trees.composites.Sequence(name, memory=not a["reactive"], children=kids)
        elif k == "selector":
            node = py_trees.composites.Selector(name, memory=not a["reactive"], children=kids)
        elif k == "parallel":
            if a["policy"] == "all":
                node = py_trees.composites.Parallel(
                    name, policy=common.ParallelPolicy.SuccessOnAll(synchronise=True),
                    children=kids)
            else:   # "one" is threshold 1: succeed at the first success, fail when all fail
                node = nodes.ThresholdParallel(name, kids, a.get("threshold", 1))
        elif k == "retry":
            node = nodes.Retry(name, kids[0], num_failures=a["times"])
        elif k == "repeat":
            node = nodes.Repeat(name, kids[0], num_success=a["times"])
        elif k == "timeout":
            node = nodes.Timeout(name, kids[0], duration=a["seconds"])
        elif k == "inverter":
            node = nodes.Inverter(name, kids[0])
        elif k == "force_success":
            node = nodes.ForceSuccess(name, kids[0])
        elif k == "force_failure":
            node = nodes.ForceFailure(name, kids[0])
        elif k == "for_each":
            source = a["source"]
            node = nodes.ForEach(name, kids[0], source=lambda s=source: built.read(s),
                                 target_key=built.bb_key(a["target"]), until=a["until"])
        elif k == "condition":
            node = nodes.Condition(name, a["expr"], built.read)
        elif k == "guard":
            node = nodes.Guard(name, kids[0], a["expr"], built.read)
        elif k == "watch":
            node = nodes.Watch(name, kids[0], {p: built.param_key(p) for p in a["params"]},
                               built.read_key)
        elif k == "include":
            node = nodes.PassThrough(name, kids[0])
        elif k == "state_machine":
            states = [(state, kid, table) for (state, table), kid in zip(a["states"], kids)]
            readers = {c.attrs["state"]: (lambda k=c.attrs["outcome_key"]: built.read(BBKey(k)))
                       for c in spec.children if "outcome_key" in c.attrs}
            node = nodes.StateMachine(name, states, a["initial"], a["outcomes"], readers)
        elif k == "succeed":
            node = nodes.Message(name, common.Status.SUCCESS, a.get("message", ""))
        elif k == "fail":
            node = nodes.Message(name, common.Status.FAILURE, a.get("message", ""))
        elif k == "skill":
            b = Bindings(inputs={p: binding(r) for p, r in spec.inputs.items()},
                         outputs={p: Key(built.bb_key(r.key)) for p, r in spec.outputs.items()})
            node = make_skill(spec, b)
        else:  # pragma: no cover - the loader only produces the kinds above
            raise AssertionError(k)
        reads = _reads(spec, built)
        if reads:
            # Declare what the node reads, the py_trees way (blackboard introspection, access
            # checks); the node itself reads through BuiltTree.read for speed.
            client = node.attach_blackboard_client(name=f"{spec.name}.reads")
            for key in reads:
                client.register_key(key=key, access=common.Access.READ)
        node.hearth_path = spec.path
        built.nodes[spec.path] = node
        built.path_of[id(node)] = spec.path
        built.specs[spec.path] = spec
        return node

    for name, value in params.items():
        if value is not None:
            built.write_param(name, value)
    for key, value in mission.blackboard.items():
        Blackboard.set(built.bb_key(key), value)
    built.root = make(mission.root)
    return built
