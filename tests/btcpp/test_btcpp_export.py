"""`hearth export --format btcpp`: BehaviorTree.CPP v4 XML from the shipped missions."""
from __future__ import annotations

from pathlib import Path

from lxml import etree

from hearth.executive.btcpp import CUSTOM, export_mission
from hearth.cli.main import main
from hearth.executive.missionfile import load_mission
from hearth import missions_dir
from hearth.skills.base import registry

MISSIONS = Path(missions_dir())


def parse(xml: str) -> etree._Element:
    return etree.fromstring(xml.encode("utf-8"))


def test_export_writes_one_behaviortree_per_mission_and_included_subtree():
    root = parse(export_mission(MISSIONS / "fetch_object.yaml"))
    assert root.get("BTCPP_format") == "4"
    assert root.get("main_tree_to_execute") == "fetch_object"
    ids = [t.get("ID") for t in root.iter("BehaviorTree")]
    assert ids == ["fetch_object", "find_object", "search_known_places", "search_at", "note",
                   "localise_here", "open_closed_parts", "look_here", "search_places"]
    calls = {s.get("ID") for s in root.iter("SubTree") if s.getparent().tag != "TreeNodesModel"}
    assert calls == set(ids) - {"fetch_object"}


def test_every_mission_node_is_an_xml_node_none_dropped(shipped_mission):
    """Each node of the compiled mission is one element in its tree (includes expanded
    once per include), so watch, for_each and the rest are never silently lost."""
    mission = load_mission(shipped_mission)
    root = parse(export_mission(shipped_mission))
    trees = {t.get("ID"): t[0] for t in root.iter("BehaviorTree")}

    def count(el) -> int:
        n = 1
        if el.tag == "SubTree":
            n += count(trees[el.get("ID")])
        return n + sum(count(c) for c in el if c.tag != "State")

    main = trees[root.get("main_tree_to_execute")]
    assert count(main) == sum(1 for _ in mission.nodes())


def test_custom_node_types_are_in_the_model_with_their_ports():
    root = parse(export_mission(MISSIONS / "go_to_rest.yaml"))
    model = root.find("TreeNodesModel")
    watch = model.find("Decorator[@ID='Watch']")
    assert [p.get("name") for p in watch] == ["params"]
    assert root.find(".//Watch").get("params") == "presence"
    check = model.find("Condition[@ID='Check']")
    assert check is not None and root.find(".//Check").get("expr") == "{presence} != home"
    for_each = parse(export_mission(MISSIONS / "turn_off_oven.yaml")).find(
        "TreeNodesModel/Decorator[@ID='ForEach']")
    assert {p.get("name"): p.tag for p in for_each} == {
        "in": "input_port", "as": "output_port", "until": "input_port"}
    assert set(CUSTOM) >= {"ForEach", "Watch", "Guard", "Check", "StateMachine", "State"}


def test_the_model_carries_every_used_skills_declared_ports(shipped_mission):
    root = parse(export_mission(shipped_mission))
    skills = registry()
    used = {el.tag for t in root.iter("BehaviorTree") for el in t.iter() if el.tag in skills}
    actions = {a.get("ID"): a for a in root.find("TreeNodesModel").iter("Action")}
    assert used <= set(actions)
    for name in used:
        cls = skills[name]
        ports = {p.get("name"): p for p in actions[name]
                 if p.tag in ("input_port", "output_port")}
        for port in cls.INPUTS:
            el = ports[port.name]
            assert el.tag == "input_port" and el.get("type") == port.type
            assert (el.text or "") == port.description
            assert (el.get("default") is None) == (port.default is None)
        assert len([p for p in ports.values() if p.tag == "output_port"]) == len(cls.OUTPUTS)


def test_tree_ports_are_the_parameters_with_types_and_defaults():
    root = parse(export_mission(MISSIONS / "go_to_rest.yaml"))
    model = root.find("TreeNodesModel/SubTree[@ID='go_to_rest']")
    presence = model.find("input_port[@name='presence']")
    assert presence.get("type") == "string" and presence.get("default") == "home"
    assert presence.get("runtime") == "true"
    # a parameter passed on as a port is the blackboard entry of the same name (go_to_rest's
    # place comes from the map unless the parameter names it: RestPlace, issue 43)
    place = root.find(".//RestPlace[@name='place_near_user']")
    assert place.get("place") == "{rest_near_user}"
    drive = root.find(".//NavigateTo[@name='drive_near_user']")
    assert drive.get("target") == "{near_target}"


def test_subtree_outputs_through_a_parameter_are_inout_ports():
    root = parse(export_mission(MISSIONS / "search_object.yaml"))
    model = root.find("TreeNodesModel/SubTree[@ID='search_at']")
    kinds = {p.get("name"): p.tag for p in model if p.get("name")}
    assert kinds["searched"] == "inout_port" and kinds["notes"] == "inout_port"
    assert kinds["object_id"] == "input_port"


def test_a_key_named_like_a_parameter_gets_its_own_name():
    # search_object reads $user_room and writes a key user_room: one blackboard in BT.CPP.
    root = parse(export_mission(MISSIONS / "search_object.yaml"))
    locate = root.find(".//LocateUser")
    assert locate.get("room") == "{user_room}"          # the input: the parameter
    assert locate.get("room_out") == "{user_room_key}"  # the output: the key, renamed
    plan = root.find(".//SubTree[@ID='find_object']")
    assert plan.get("user_room") == "{user_room_key}"


def test_literals_keep_their_type():
    root = parse(export_mission(MISSIONS / "fetch_object.yaml"))
    detect = root.find(".//DetectObject[@name='detect_again']")
    assert detect.get("update_map") == "false"
    loop = root.find(".//ForEach[@name='other_landmarks']")
    assert loop.get("in") == "json:[0, 1, 2]" and loop.get("until") == "success"
    again = root.find(".//ForEach[@name='look_again']")
    assert again.get("in") == "{levels_again}"


def test_cli_export_writes_the_file(tmp_path, capsys):
    out = tmp_path / "oven.xml"
    assert main(["export", str(MISSIONS / "turn_off_oven.yaml"), "--format", "btcpp",
                 "-o", str(out)]) == 0
    assert parse(out.read_text()).get("main_tree_to_execute") == "turn_off_oven"
    assert main(["export", str(MISSIONS / "go_to_rest.yaml")]) == 0
    assert "<BehaviorTree ID=\"go_to_rest\"" in capsys.readouterr().out


def test_cli_export_of_a_bad_mission_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\ntree:\n  skill: FlyTo\n")
    out = tmp_path / "bad.xml"
    assert main(["export", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{bad}:3: unknown skill 'FlyTo'"]
    assert not out.exists()


def test_without_behaviortreepy_the_btcpp_figures_are_null_with_a_reason(monkeypatch, tmp_path):
    import sys
    from hearth.benchmarks import _btcpp
    from hearth.benchmarks.executive import Work, mission_yaml
    monkeypatch.setitem(sys.modules, "behaviortreepy", None)   # import fails
    path = tmp_path / "bench.yaml"
    path.write_text(mission_yaml(0))
    times = _btcpp.tick_times(str(path), {"BenchWork": Work}, 10)
    out = _btcpp.figures(times, 0.0003)
    assert out["btcpp_tick_ms"] is None and out["tick_ratio_vs_btcpp"] is None
    assert "behaviortreepy is not installed" in out["btcpp_note"]
