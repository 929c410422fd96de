"""The executive's direct tick (hearth/executive/treetick.py) is py_trees' generator tick, call for
call: random trees of every node kind, ticked both ways side by side, visit the same nodes
with the same statuses, make the same skill calls and end in the same state."""
from __future__ import annotations

import yaml
from hypothesis import HealthCheck, example, given, settings, strategies as st
from py_trees import common

from hearth.executive import treetick
from hearth.executive.missionfile import load_mission
from hearth.executive.testing import test_skills
from hearth.executive.tree import build_tree
from hearth.robot.clock import SimClock
from hearth.skills.base import Skill

Status = common.Status


class Recorder(Skill):
    """A leaf playing a fixed list of (outcome, ticks) activations and journaling its calls."""
    NAME = "Act"

    def __init__(self, name, bindings, plan, journal):
        super().__init__(name=name, bindings=bindings)
        self.plan, self.journal, self.n, self.left = plan, journal, 0, 0

    def initialise(self):
        outcome, self.left = self.plan[min(self.n, len(self.plan) - 1)]
        self.n += 1
        self.journal.append(("initialise", self.hearth_path))

    def update(self):
        self.journal.append(("update", self.hearth_path))
        if self.left > 0:
            self.left -= 1
            self.feedback_message = f"{self.left} to go"
            return Status.RUNNING
        outcome = self.plan[min(self.n, len(self.plan)) - 1][0]
        self.feedback_message = outcome
        return Status.SUCCESS if outcome == "success" else Status.FAILURE

    def terminate(self, new_status):
        self.journal.append(("terminate", self.hearth_path, self.status.value, new_status.value))


PLAN = st.lists(st.tuples(st.sampled_from(["success", "failure"]), st.integers(0, 2)),
                min_size=1, max_size=3)
LEAF = st.one_of(
    st.builds(lambda p: {"skill": "Act", "_plan": p}, PLAN),
    st.just({"condition": "$mode == a"}),
    st.just({"succeed": "ok"}),
    st.just({"fail": "no"}))


def _machine(kids):
    def transitions(i, kid):
        ok, bad = (f"s{i + 1}" if i + 1 < len(kids) else "done"), ("s0" if i else "gave_up")
        if "state_machine" in kid:       # a nested machine ends in one of its outcomes
            return {"done": ok, "gave_up": bad}
        return {"success": ok, "failure": bad}
    states = {f"s{i}": {"do": k, "transitions": transitions(i, k)} for i, k in enumerate(kids)}
    return {"state_machine": {"initial": "s0", "states": states,
                              "outcomes": {"done": "success", "gave_up": "failure"}}}


def _tree(children):
    kids = st.lists(children, min_size=1, max_size=3)
    return st.one_of(
        st.builds(lambda c, r: {"sequence": c, "reactive": r}, kids, st.booleans()),
        st.builds(lambda c, r: {"selector": c, "reactive": r}, kids, st.booleans()),
        st.builds(lambda c, p: {"parallel": c, "policy": p}, kids, st.sampled_from(["all", "one"])),
        st.builds(lambda c: {"parallel": c, "policy": "threshold", "threshold": 1}, kids),
        st.builds(lambda c, n: {"retry": c, "times": n}, children, st.integers(1, 3)),
        st.builds(lambda c, n: {"repeat": c, "times": n}, children, st.integers(1, 3)),
        st.builds(lambda c: {"timeout": c, "seconds": 0.25}, children),
        st.builds(lambda c: {"inverter": c}, children),
        st.builds(lambda c: {"force_success": c}, children),
        st.builds(lambda c: {"force_failure": c}, children),
        st.builds(lambda c, u: {"for_each": c, "in": "{items}", "as": "item", "until": u},
                  children, st.sampled_from(["success", "failure"])),
        st.builds(lambda c: {"guard": c, "while": "$mode == a"}, children),
        st.builds(lambda c: {"watch": c, "params": ["mode"]}, children),
        st.builds(_machine, kids),
    )


TREES = st.recursive(LEAF, _tree, max_leaves=10)


def _name_leaves(node, plans, counter):
    if isinstance(node, list):
        for n in node:
            _name_leaves(n, plans, counter)
    elif isinstance(node, dict):
        if "_plan" in node:
            counter[0] += 1
            node["name"] = f"leaf{counter[0]}"
            plans[node["name"]] = node.pop("_plan")
            return
        for value in node.values():
            _name_leaves(value, plans, counter)


def _build(mission, plans, ns):
    journal = []
    clock = SimClock()

    def make(spec, bindings):
        return Recorder(spec.name, bindings, plans[spec.name], journal)

    built = build_tree(mission, {"mode": "a"}, ns, make)
    built.setup(clock=clock)
    return built, journal, clock


def _state(built):
    def current(n):
        child = getattr(n, "current_child", None)
        return None if child is None else child.hearth_path
    return [(p, n.status, n.feedback_message, current(n)) for p, n in built.nodes.items()]


def _act(outcome="success", ticks=2, *more):
    return {"skill": "Act", "_plan": [(outcome, ticks), *more]}


COND = {"condition": "$mode == a"}
FLIPS = ["tick", "mode", "tick", "tick", "mode", "tick", "tick", "halt", "tick", "tick"]


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(TREES, st.lists(st.sampled_from(["tick", "tick", "tick", "mode", "halt"]),
                       min_size=5, max_size=25))
# Cases the random search reaches only now and then, each a branch of the transcription:
# a reactive selector/sequence halting a running child when an earlier one changes,
# a memory selector resuming, a parallel failing with children running, a timeout, a guard,
# a watch restart, a looping state machine, a for-each search, retries.
@example({"selector": [COND, _act()], "reactive": True}, FLIPS)
@example({"sequence": [COND, _act()], "reactive": True}, FLIPS)
@example({"selector": [_act("failure", 1), _act()], "reactive": False}, FLIPS)
@example({"parallel": [_act("failure", 1), _act("success", 3)], "policy": "all"}, FLIPS)
@example({"parallel": [_act("failure", 1), _act("success", 3)], "policy": "one"}, FLIPS)
@example({"timeout": _act("success", 5), "seconds": 0.25}, FLIPS)
@example({"guard": _act("success", 3), "while": "$mode == a"}, FLIPS)
@example({"watch": {"sequence": [_act(), _act()]}, "params": ["mode"]}, FLIPS)
@example(_machine([_act("failure", 0), _act("success", 1, ("failure", 0))]), FLIPS * 2)
@example({"for_each": _act("failure", 1), "in": "{items}", "as": "item", "until": "success"},
         FLIPS)
@example({"retry": _act("failure", 1), "times": 3}, FLIPS)
def test_direct_tick_equals_py_trees_generators(tmp_path_factory, tree, steps):
    plans = {}
    _name_leaves(tree, plans, [0])
    path = tmp_path_factory.mktemp("tt") / "m.yaml"
    path.write_text(yaml.safe_dump({
        "name": "t", "blackboard": {"items": [1, 2]},
        "parameters": {"mode": {"type": "string", "default": "a", "runtime": True}},
        "tree": tree}))
    mission = load_mission(path, test_skills())
    gen, gen_journal, gen_clock = _build(mission, plans, "/tt/gen")
    fast, fast_journal, fast_clock = _build(mission, plans, "/tt/fast")
    mode = "a"
    for step in steps:
        if step == "mode":
            mode = "b" if mode == "a" else "a"
            gen.write_param("mode", mode)
            fast.write_param("mode", mode)
            continue
        if step == "halt":
            if gen.root.status != Status.INVALID:
                gen.root.stop(Status.INVALID)
            if fast.root.status != Status.INVALID:
                treetick.stop(fast.root, Status.INVALID)
        else:
            seen_gen = [(n.hearth_path, s) for n, s in
                        {n: n.status for n in gen.root.tick()}.items()]
            seen_fast = [(n.hearth_path, s) for n, s in treetick.tick(fast.root).items()]
            assert seen_fast == seen_gen
        gen_clock.advance(0.1)
        fast_clock.advance(0.1)
        assert fast_journal == gen_journal
        assert _state(fast) == _state(gen)
    gen.teardown()
    fast.teardown()


def test_a_tree_with_a_class_of_its_own_tick_is_ticked_by_py_trees_generators():
    from py_trees.behaviour import Behaviour
    from py_trees.composites import Sequence

    class Twice(Behaviour):
        def tick(self):       # yields itself running, then succeeds: the parent reacts early
            self.status = Status.RUNNING
            yield self
            self.status = Status.SUCCESS
            yield self

        def update(self):
            return self.status

    def tree():
        return Sequence("s", memory=True, children=[Twice("a"), Twice("b")])

    expected = [(n.name, n.status) for n in tree().tick()]
    root = tree()
    assert not treetick.direct(root)
    assert [(n.name, s) for n, s in treetick.tick(root).items()] == expected == [
        ("a", Status.RUNNING), ("s", Status.RUNNING)]


# -- py_trees' own classes, as someone might assemble them by hand (the benchmark does) -------
class Leaf(Recorder):
    def __init__(self, name, plan, journal):
        super().__init__(name, None, plan, journal)
        self.hearth_path = name


def _py_trees_tree(shape, journal, flag, counter):
    from py_trees import composites, decorators
    kind, arg, kids = shape
    counter[0] += 1
    name = f"{kind}{counter[0]}"
    if kind == "leaf":
        return Leaf(name, arg, journal)
    children = [_py_trees_tree(k, journal, flag, counter) for k in kids]
    if kind == "sequence":
        node = composites.Sequence(name, memory=arg, children=children)
    elif kind == "selector":
        node = composites.Selector(name, memory=arg, children=children)
    elif kind == "parallel":
        policy = (common.ParallelPolicy.SuccessOnOne() if arg == "one" else
                  common.ParallelPolicy.SuccessOnAll(synchronise=arg == "all_sync"))
        node = composites.Parallel(name, policy=policy, children=children)
    elif kind == "guard":
        node = decorators.EternalGuard(name, children[0], condition=lambda: flag[0])
    else:
        cls = {"repeat": decorators.Repeat, "retry": decorators.Retry}.get(kind)
        if cls is decorators.Repeat:
            node = cls(name, children[0], num_success=arg)
        elif cls is decorators.Retry:
            node = cls(name, children[0], num_failures=arg)
        else:
            node = getattr(decorators, kind)(name, children[0])
    node.hearth_path = name
    return node


DECORATORS = ["Inverter", "RunningIsFailure", "RunningIsSuccess", "FailureIsSuccess",
              "SuccessIsFailure", "PassThrough", "guard"]
SHAPES = st.recursive(
    st.builds(lambda p: ("leaf", p, []), PLAN),
    lambda c: st.one_of(
        st.builds(lambda m, k: ("sequence", m, k), st.booleans(), st.lists(c, min_size=0, max_size=3)),
        st.builds(lambda m, k: ("selector", m, k), st.booleans(), st.lists(c, min_size=0, max_size=3)),
        st.builds(lambda p, k: ("parallel", p, k), st.sampled_from(["all_sync", "all", "one"]),
                  st.lists(c, min_size=0, max_size=3)),
        st.builds(lambda n, k: ("repeat", n, [k]), st.sampled_from([-1, 1, 2]), c),
        st.builds(lambda n, k: ("retry", n, [k]), st.integers(1, 3), c),
        st.builds(lambda d, k: (d, None, [k]), st.sampled_from(DECORATORS), c)),
    max_leaves=10)


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(SHAPES, st.lists(st.sampled_from(["tick", "tick", "tick", "flag", "halt"]),
                        min_size=5, max_size=25))
@example(("RunningIsSuccess", None, [("leaf", [("success", 2)], [])]), ["tick"] * 4)
def test_direct_tick_equals_py_trees_generators_on_py_trees_classes(shape, steps):
    flag = [True]
    gen_journal, fast_journal = [], []
    gen = _py_trees_tree(shape, gen_journal, flag, [0])
    fast = _py_trees_tree(shape, fast_journal, flag, [0])
    assert treetick.direct(fast) == treetick.ENABLED     # ENABLED: py_trees 2.6, transcribed

    def state(root):
        return [(n.name, n.status, n.feedback_message,
                 getattr(getattr(n, "current_child", None), "name", None)) for n in root.iterate()]

    for step in steps:
        if step == "flag":
            flag[0] = not flag[0]
        elif step == "halt":
            if gen.status != Status.INVALID:
                gen.stop(Status.INVALID)
            if fast.status != Status.INVALID:
                treetick.stop(fast, Status.INVALID)
        else:
            seen_gen = [(n.name, s) for n, s in {n: n.status for n in gen.tick()}.items()]
            seen_fast = [(n.name, s) for n, s in treetick.tick(fast).items()]
            assert seen_fast == seen_gen
        assert fast_journal == gen_journal
        assert state(fast) == state(gen)
