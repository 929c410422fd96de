"""BehaviorTree.CPP's scripts, pre/post conditions, _autoremap and the nodes import rewrites
(Script, ScriptCondition, SetBlackboard, Precondition, Delay, RunOnce, IfThenElse, Switch):
BT.CPP's own tutorial trees (tests/btcpp/tutorials) import, run in Hearth, and end as they
end in BehaviorTree.CPP itself (behaviortreepy) with the same leaves ticked."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from lxml import etree

from hearth.executive.btcpp import import_tree, skill_model
from hearth.executive.executive import Executive
from hearth.executive.testing import Script, Substitution
from hearth.robot.clock import SimClock
from hearth.skills.base import Port, Skill, registry

TUTORIALS = Path(__file__).parent / "tutorials"


def _leaf(name: str, inputs: tuple = (), outputs: tuple = ()) -> type:
    return type(name, (Skill,), {
        "NAME": name, "__module__": __name__,
        "INPUTS": tuple(Port(p, "any", required=False) for p in inputs),
        "OUTPUTS": tuple(Port(p, "any", required=False) for p in outputs)})


#: The tutorials' leaves (dummy_nodes.h, movebase_node.h, crossdoor_nodes.h): ports only.
LEAVES = [_leaf("SaySomething", ("message",)), _leaf("MoveBase", ("goal",)),
          _leaf("UpdatePosition", outputs=("pos", "vec_double", "vec_string", "waypoints"))] + \
    [_leaf(n) for n in ("IsDoorClosed", "OpenDoor", "PickLock", "SmashDoor", "PassThroughDoor",
                        "TestA", "TestB", "TestC")]


@pytest.fixture(scope="module")
def skills() -> dict[str, type]:
    return {**registry(), **{c.NAME: c for c in LEAVES}}


#: fixture -> (leaf outcomes in call order, expected status, blackboard entries at the end,
#: the leaves ticked in order).
CASES = {
    "t06_subtree_port_remapping": ({}, "SUCCESS", {"move_result": "goal reached"},
                                   ["MoveBase", "SaySomething"]),
    "t11_groot_howto": ({"OpenDoor": ["failure"], "PickLock": ["failure", "failure", "success"]},
                        "SUCCESS", {"door_open": True},
                        ["UpdatePosition", "IsDoorClosed", "OpenDoor", "PickLock", "PickLock",
                         "PickLock", "PassThroughDoor"]),
    "t14_subtree_model": ({}, "SUCCESS", {"out_result": 69, "out_state": "ACTIVE"}, []),
    "t17_blackboard_backup": ({}, "SUCCESS", {"reply": "done"}, ["SaySomething"] * 5),
    "gtest_skipping_sequence": ({}, "SUCCESS", {"A": 1}, ["TestB"]),
    "gtest_postconditions_basic": ({}, "SUCCESS", {"B": 42, "C": 42, "D": 42}, []),
}


#: Entries a real node's typed port creates in the tutorial (see run_btcpp).
PORT_ENTRIES = {"t06_subtree_port_remapping": ("move_goal",)}


#: A tree of our own with every node import rewrites, its expectations as in CASES.
REWRITTEN = """\
<root BTCPP_format="4" main_tree_to_execute="main">
  <BehaviorTree ID="main">
    <Sequence>
      <SetBlackboard value="hello" output_key="greeting"/>
      <Script code="mode := 2; ok := true"/>
      <Switch3 variable="{mode}" case_1="1" case_2="2" case_3="three">
        <TestA/>
        <TestB/>
        <TestC/>
        <TestA/>
      </Switch3>
      <IfThenElse>
        <ScriptCondition code="mode == 1 || ok"/>
        <TestC _onSuccess="branch := 'then'"/>
        <TestA/>
      </IfThenElse>
      <Fallback>
        <TestA _skipIf="mode == 2"/>
        <TestB _while="ok"/>
      </Fallback>
      <Delay delay_msec="200">
        <TestC/>
      </Delay>
      <Precondition if="mode != 2" else="SUCCESS">
        <TestA/>
      </Precondition>
      <RetryUntilSuccessful num_attempts="3">
        <RunOnce then_skip="false">
          <TestB name="once"/>
        </RunOnce>
      </RetryUntilSuccessful>
    </Sequence>
  </BehaviorTree>
</root>
"""
CASES["rewritten_nodes"] = ({"once": ["failure", "success"]}, "FAILURE",
                            {"greeting": "hello", "mode": 2, "branch": "then"},
                            ["TestB", "TestC", "TestB", "TestC", "once"])


def fixture(tmp_path: Path, name: str) -> Path:
    if name == "rewritten_nodes":
        path = tmp_path / "rewritten_nodes.xml"
        path.write_text(REWRITTEN)
        return path
    return TUTORIALS / f"{name}.xml"


def run_hearth(tmp_path: Path, xml: Path, skills: dict, outcomes: dict[str, list[str]]):
    """Import ``xml`` and run it with stand-in leaves: (outcome, the last value written to
    each key, the leaves started in order)."""
    text, _ = import_tree(xml, skills)
    path = tmp_path / (xml.stem + ".yaml")
    path.write_text(text)
    scripts = [Script(f"*/{k}", outcomes=v) for k, v in outcomes.items()
               if k not in {c.NAME for c in LEAVES}]
    scripts += [Script(c.NAME, outcomes=outcomes.get(c.NAME, ["success"])) for c in LEAVES]
    ex = Executive(clock=SimClock(), make_skill=Substitution(scripts), skills=skills,
                   background=False, runs_dir=str(tmp_path / "runs"))
    handle = ex.submit(str(path))
    ex.run_until_idle(2000)
    leaves = {c.NAME for c in LEAVES} | set(outcomes)
    values, started = {}, []
    for line in open(handle.log_path, encoding="utf-8"):
        e = json.loads(line)
        if e["e"] == "write":
            values[e["key"]] = e["value"]
        elif e["e"] == "status" and e["status"] != "INVALID" and e["previous"] != "RUNNING":
            leaf = re.sub(r"_\d+$", "", e["path"].rsplit("/", 1)[-1])   # SaySomething_2
            if leaf in leaves:
                started.append(leaf)
    return handle.result.outcome, values, started


def run_btcpp(xml: Path, outcomes: dict[str, list[str]]):
    """The same XML in BehaviorTree.CPP's factory with Python stand-ins for the leaves:
    (status, the root blackboard, the leaves ticked in order).

    behaviortreepy's stand-ins have no ports, so a typed port remapped to an entry does not
    create the entry as the tutorial's real node would (t06 writes ``move_goal='1;2;3'``
    with ``=``, which needs it): such entries are created empty first (PORT_ENTRIES)."""
    bt = pytest.importorskip("behaviortreepy")
    from hearth.benchmarks._btcpp import standin_tree
    root = etree.fromstring(xml.read_bytes().replace(b"&&", b"&amp;&amp;"))
    models = root.find("TreeNodesModel")
    if models is None:
        models = etree.SubElement(root, "TreeNodesModel")
    for cls in LEAVES:
        models.append(skill_model(cls))
    counts: dict[str, int] = {}

    def leaf(node):
        name = node.name()
        plan = outcomes.get(name, ["success"])
        i = counts.get(name, 0)
        counts[name] = i + 1
        return bt.NodeStatus.SUCCESS if plan[min(i, len(plan) - 1)] == "success" \
            else bt.NodeStatus.FAILURE

    board = bt.Blackboard.create()
    for key in PORT_ENTRIES.get(xml.stem, ()):
        board.set_string(key, "")
    st = standin_tree(etree.tostring(root, encoding="unicode"), leaf=leaf, blackboard=board)
    status = st.tree.tick_while_running(0)
    return str(status).rsplit(".", 1)[-1], st.tree.root_blackboard(), st.calls


def _read(board, key: str, like):
    if isinstance(like, bool):
        return board.get_bool(key)
    if isinstance(like, int):
        return board.get_int(key)
    return board.get_string(key)


@pytest.mark.parametrize("name", sorted(CASES))
def test_btcpp_tutorial_trees_import_and_run_as_in_btcpp(tmp_path, skills, name):
    outcomes, status, entries, leaves = CASES[name]
    xml = fixture(tmp_path, name)
    outcome, values, started = run_hearth(tmp_path, xml, skills, outcomes)
    assert outcome == ("succeeded" if status == "SUCCESS" else "failed")
    assert {k: values.get(k) for k in entries} == entries
    assert started == leaves
    # BehaviorTree.CPP itself, on the same file.
    bt_status, board, calls = run_btcpp(xml, outcomes)
    assert bt_status == status
    assert calls == leaves
    assert {k: _read(board, k, v) for k, v in entries.items()} == entries
