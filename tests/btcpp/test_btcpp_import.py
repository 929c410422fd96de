"""`hearth import`: BehaviorTree.CPP v4 XML back into missions; the round trip; bad XML."""
from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

from hearth.executive.btcpp import REFUSED, export_mission, import_tree
from hearth.cli.main import main
from hearth.executive.testing import MissionCase, Script, Substitution, run_mission_case
from hearth import missions_dir

from .conftest import branching_case, timeline

MISSIONS = Path(missions_dir())


def imported(tmp_path: Path, mission: str) -> tuple[str, str]:
    """Export ``mission``, import the XML; return (xml text, imported mission path)."""
    xml = export_mission(mission)
    xml_path = tmp_path / f"{Path(mission).stem}.xml"
    xml_path.write_text(xml)
    text, _ = import_tree(xml_path)
    out = tmp_path / f"{Path(mission).stem}.imported.yaml"
    out.write_text(text)
    return xml, str(out)


def test_export_import_export_is_identical(tmp_path, shipped_mission):
    xml, back = imported(tmp_path, shipped_mission)
    assert export_mission(back) == xml


def test_imported_mission_behaves_the_same(tmp_path, shipped_mission):
    """Same outcome, same status changes and writes at the same ticks, with the same
    scripted stand-ins (the imported mission keeps every node's path)."""
    _, back = imported(tmp_path, shipped_mission)
    case = branching_case(shipped_mission)
    a = run_mission_case(shipped_mission, case, runs_dir=str(tmp_path / "a"))
    b = run_mission_case(back, case, runs_dir=str(tmp_path / "b"))
    assert (b.outcome, b.reason, b.ticks) == (a.outcome, a.reason, a.ticks)
    assert b.nodes == a.nodes and b.never_ticked == a.never_ticked
    ta, tb = timeline(a.log_path), timeline(b.log_path)
    assert len(ta) >= 3
    assert tb == ta


def test_test_mission_gives_the_same_report_for_the_imported_mission(tmp_path, capsys):
    case = Path(__file__).parents[1] / "executive" / "cases" / "go_to_rest_presence_change.yaml"
    _, back = imported(tmp_path, str(MISSIONS / "go_to_rest.yaml"))
    assert main(["test-mission", str(MISSIONS / "go_to_rest.yaml"), "--substitute",
                 str(case)]) == 0
    original = capsys.readouterr().out
    assert main(["test-mission", back, "--substitute", str(case)]) == 0
    assert capsys.readouterr().out == original
    assert "outcome: succeeded" in original


HAND_WRITTEN = """\
<?xml version="1.0" encoding="UTF-8"?>
<root BTCPP_format="4" main_tree_to_execute="Fetch">
  <BehaviorTree ID="Fetch">
    <Sequence name="fetch">
      <ReactiveSequence name="while_home">
        <Say name="greet" text="on my way"/>
        <Fallback name="reach">
          <NavigateTo name="first_try" target="kitchen_table"/>
          <RetryUntilSuccessful num_attempts="3">
            <NavigateTo name="again" target="side_table"/>
          </RetryUntilSuccessful>
        </Fallback>
      </ReactiveSequence>
      <SubTree ID="Report" what="{where}" place="side_table"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Report">
    <Sequence>
      <Say name="tell" text="I am at the {place}" place="{place}" said="{what}"/>
      <Say name="echo" text="{what}"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def test_hand_written_btcpp_xml_runs_with_stand_in_skills(tmp_path):
    xml = tmp_path / "fetch.xml"
    xml.write_text(HAND_WRITTEN)
    text, mission = import_tree(xml)
    assert mission.name == "Fetch"
    out = tmp_path / "fetch.yaml"
    out.write_text(text)
    case = MissionCase(scripts=[Script("*/first_try", outcomes=["failure"]),
                                Script("*/again", outcomes=["failure", "success"], duration=0.2),
                                Script("Say", outputs={"said": "I am at the side table"})])
    sub = Substitution(case.scripts, case.default)
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock
    ex = Executive(clock=SimClock(), make_skill=sub, background=False,
                   runs_dir=str(tmp_path / "runs"))
    handle = ex.submit(str(out))
    ex.run_until_idle(1000)
    assert handle.result.outcome == "succeeded"
    starts = [(e[2].rsplit("/", 1)[-1], e[3]) for e in timeline(handle.log_path)
              if e[1] == "status" and e[2].rsplit("/", 1)[-1] in
              ("greet", "first_try", "again", "tell", "echo")
              and e[3] in ("SUCCESS", "FAILURE")]
    # The fallback tries first_try, then the retry runs "again" until it succeeds; the
    # reactive sequence ticks greet again on every tick while that runs.
    assert [s for s in starts if s[0] != "greet"] == [
        ("first_try", "FAILURE"), ("again", "FAILURE"), ("again", "SUCCESS"),
        ("tell", "SUCCESS"), ("echo", "SUCCESS")]
    assert starts.count(("greet", "SUCCESS")) > 3
    # SubTree remapping: a literal and a key of the caller reach the subtree's skills.
    tell = sub.made["/fetch/Report/sequence/tell"]
    assert tell.seen_inputs[-1]["place"] == "side_table"
    echo = sub.made["/fetch/Report/sequence/echo"]
    assert echo.seen_inputs[-1]["text"] == "I am at the side table"
    assert handle.result.outputs["where"] == "I am at the side table"


def bad(body: str) -> str:
    return ('<root BTCPP_format="4">\n  <BehaviorTree ID="main">\n'
            + textwrap.indent(textwrap.dedent(body), "    ") + "  </BehaviorTree>\n</root>\n")


BAD_CASES = {
    "unknown node": (bad("""\
        <Sequence>
          <FlyTo target="moon"/>
        </Sequence>
        """), 4, "<FlyTo> is neither a BehaviorTree.CPP node Hearth maps nor a registered skill"),
    "case slip": (bad("<navigateto target='kitchen_table'/>\n"), 3, "did you mean NavigateTo?"),
    "undeclared port": (bad("""\
        <Sequence>
          <NavigateTo target="kitchen_table" speed="3"/>
        </Sequence>
        """), 4, "skill NavigateTo has no port 'speed'"),
    "undeclared subtree port": (
        '<root BTCPP_format="4" main_tree_to_execute="main">\n'
        '  <BehaviorTree ID="main"><SubTree ID="s" wat="1"/></BehaviorTree>\n'
        '  <BehaviorTree ID="s"><Say text="{x}"/></BehaviorTree>\n'
        '  <TreeNodesModel><SubTree ID="s"><input_port name="x" type="string"/></SubTree>'
        '</TreeNodesModel>\n</root>\n', 2, "<SubTree ID='s'> has no port 'wat' (ports: x)"),
    "xml entity": ('<?xml version="1.0"?>\n<!DOCTYPE root [<!ENTITY x "lol">]>\n'
                   '<root BTCPP_format="4"><BehaviorTree ID="m"><Say text="&x;"/>'
                   '</BehaviorTree></root>\n', 2, "DOCTYPE declarations (DTDs and entities)"),
    "undefined entity": ('<root BTCPP_format="4">\n<BehaviorTree ID="m">\n<Say text="&x;"/>'
                         '</BehaviorTree></root>\n', 3, "XML syntax error: Entity 'x' not defined"),
    "syntax error": (bad("""\
        <Sequence>
          <Say text="hi">
        """), 5, "XML syntax error: Opening and ending tag mismatch"),
    "nav2 RecoveryNode": (bad("""\
        <RecoveryNode number_of_retries="2">
          <NavigateTo target="kitchen_table"/>
          <Say text="clearing"/>
        </RecoveryNode>
        """), 3, "Nav2's RecoveryNode"),
    "nav2 PipelineSequence": (bad("""\
        <PipelineSequence>
          <NavigateTo target="kitchen_table"/>
        </PipelineSequence>
        """), 3, "Nav2's PipelineSequence"),
    "nav2 RateController": (bad("""\
        <RateController hz="1.0">
          <NavigateTo target="kitchen_table"/>
        </RateController>
        """), 3, "Nav2's RateController"),
    "skip at the root": (bad('<Say text="hi" _skipIf="x == 1"/>\n'), 3,
                         "_skipIf: BT.CPP's SKIPPED has a Hearth reading only for a child of a "
                         "Sequence or a Fallback"),
    "script arithmetic": (bad("""\
        <Sequence>
          <Script code="x := 1"/>
          <Script code="y := x + 1"/>
        </Sequence>
        """), 5, "<Script> code: cannot read 'y := x + 1': Hearth reads assignments of a "
                 "literal or of another entry"),
    "script parentheses": (bad("""\
        <Sequence>
          <Script code="x := 1"/>
          <ScriptCondition code="(x == 1)"/>
        </Sequence>
        """), 5, "no arithmetic, no parentheses"),
    "on halted": (bad("""\
        <Sequence>
          <Script code="x := 1"/>
          <Say text="hi" _onHalted="x := 2"/>
        </Sequence>
        """), 5, "_onHalted: Hearth runs no node when a branch is halted"),
    "model port the skill lacks": (
        '<root BTCPP_format="4">\n  <BehaviorTree ID="m"><Say text="hi"/></BehaviorTree>\n'
        '  <TreeNodesModel>\n    <Action ID="Say">\n'
        '      <input_port name="text" type="string"/>\n'
        '      <input_port name="volume" type="double"/>\n'
        '    </Action>\n  </TreeNodesModel>\n</root>\n', 6,
        "the model of Say declares port 'volume', which skill Say lacks (ports: text, values, "
        "object, place, part, count, places, detail, say, said)"),
    "key read but never written": (bad('<Say text="{nothing}"/>\n'), 3,
                                   "reads key {nothing} that nothing writes"),
    "literal of the wrong type": (bad('<RetryUntilSuccessful num_attempts="two">\n'
                                      '  <Say text="hi"/>\n</RetryUntilSuccessful>\n'), 3,
                                  "num_attempts='two': expected an integer"),
    "v3 format": ('<root BTCPP_format="3">\n<BehaviorTree ID="m"><Say text="hi"/>'
                  '</BehaviorTree></root>\n', 1, "only BehaviorTree.CPP v4 XML"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_xml_is_one_clean_line_and_exit_2(tmp_path, capsys, case):
    text, line, message = BAD_CASES[case]
    path = tmp_path / "tree.xml"
    path.write_text(text)
    out = tmp_path / "tree.yaml"
    assert main(["import", str(path), "-o", str(out)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert re.match(rf"^{re.escape(str(path))}:{line}: ", lines[0]), lines[0]
    assert message in lines[0]
    assert "Traceback" not in captured.err and captured.out == ""
    assert not out.exists()


def test_every_refused_node_says_why():
    assert {"RecoveryNode", "PipelineSequence", "RateController", "RoundRobin",
            "DistanceController", "SpeedController", "GoalUpdater", "SingleTrigger"} <= set(REFUSED)
    assert all(len(reason) > 20 for reason in REFUSED.values())


def test_parallel_counts_map_to_policies(tmp_path):
    xml = tmp_path / "p.xml"
    xml.write_text(bad("""\
        <Sequence>
          <Parallel success_count="2" failure_count="2">
            <Say text="a"/><Say text="b"/><Say text="c"/>
          </Parallel>
          <Parallel success_count="1" failure_count="-1">
            <Say text="a"/><Say text="b"/>
          </Parallel>
          <Parallel success_count="-1" failure_count="1">
            <Say text="a"/><Say text="b"/>
          </Parallel>
        </Sequence>
        """))
    _, mission = import_tree(xml)
    policies = [(n.attrs["policy"], n.attrs.get("threshold")) for n in mission.nodes()
                if n.kind == "parallel"]
    assert policies == [("threshold", 2), ("one", None), ("all", None)]
    xml.write_text(bad("""\
        <Parallel success_count="2" failure_count="1">
          <Say text="a"/><Say text="b"/><Say text="c"/>
        </Parallel>
        """))
    with pytest.raises(Exception, match=r"p\.xml:3: <Parallel> success_count 2 with failure_count 1"):
        import_tree(xml)


def test_cli_import_writes_a_mission_that_validates(tmp_path, capsys):
    xml = tmp_path / "fetch.xml"
    xml.write_text(HAND_WRITTEN)
    out = tmp_path / "fetch.yaml"
    assert main(["import", str(xml), "-o", str(out)]) == 0
    assert "mission Fetch" in capsys.readouterr().err
    assert main(["validate", str(out)]) == 0
    assert main(["import", str(xml)]) == 0
    assert capsys.readouterr().out == out.read_text()


STATE_MACHINE = """\
hearth: 1
name: sm
parameters:
  object: {type: string, default: cup}
tree:
  state_machine:
    initial: look
    states:
      look:
        do: {skill: DetectObject, inputs: {object: $object}}
        transitions: {success: grasp, failure: move}
      move:
        do:
          guard: {skill: NavigateTo, inputs: {target: kitchen_table}}
          while: "$object != nothing"
        transitions: {success: look, failure: gave_up}
      grasp:
        do: {skill: Grasp, inputs: {object_id: $object}}
        transitions: {success: done, failure: gave_up}
    outcomes: {done: success, gave_up: failure}
"""


def test_state_machines_and_guards_round_trip(tmp_path):
    src = tmp_path / "sm.yaml"
    src.write_text(STATE_MACHINE)
    xml, back = imported(tmp_path, str(src))
    assert "<StateMachine" in xml and '<State name="look" transitions="success:grasp;failure:move">' in xml
    assert '<Guard while="{object} != nothing">' in xml
    assert export_mission(back) == xml
    case = MissionCase(scripts=[Script("DetectObject", outcomes=["failure", "success"]),
                                Script("NavigateTo", duration=0.2)])
    a = run_mission_case(str(src), case, runs_dir=str(tmp_path / "a"))
    b = run_mission_case(back, case, runs_dir=str(tmp_path / "b"))
    assert a.outcome == "succeeded" and timeline(b.log_path) == timeline(a.log_path)


def test_initial_blackboard_and_a_key_named_like_a_parameter_round_trip(tmp_path):
    src = tmp_path / "bb.yaml"
    src.write_text(textwrap.dedent("""\
        name: bb
        parameters:
          room: {type: string, default: kitchen}
        blackboard: {room: hall, count: 2}
        tree:
          sequence:
            - skill: Say
              inputs: {text: "{room}"}
            - skill: Say
              name: param
              inputs: {text: $room}
            - condition: "{room} == hall"
            - condition: "{count} == 2"
        """))
    xml, back = imported(tmp_path, str(src))
    assert '<Say text="{room_key}"/>' in xml and 'text="{room}"' in xml
    assert export_mission(back) == xml
    case = MissionCase(scripts=[])
    a = run_mission_case(str(src), case, runs_dir=str(tmp_path / "a"))
    b = run_mission_case(back, case, runs_dir=str(tmp_path / "b"))
    assert a.outcome == b.outcome == "succeeded"
    seen = [e for e in timeline(b.log_path) if e[1] == "status"]
    assert seen == [e for e in timeline(a.log_path) if e[1] == "status"]
