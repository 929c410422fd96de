"""Parameters are checked against the belief map when a mission is submitted: a node_id must
name a node of the kind the mission needs, integers keep to their bounds, object words must
match something. One line, exit 2 on the CLI; 422 with the same sentence over HTTP. And a
mission never reports success for a place it did not reach."""
from __future__ import annotations

import pytest

from hearth.cli.main import main
from hearth.executive.errors import MissionError
from hearth.executive.missionfile import load_mission
from hearth.executive.testing import Script as S
from hearth import missions_dir
from hearth.worldmodel import load_world

MISSIONS = missions_dir()

# (mission, parameters, the one line the user sees)
BAD = [
    ("go_to_rest", ["rest_near_user=../../etc/passwd"],
     "parameter rest_near_user: no node '../../etc/passwd' in the map; try one of: "
     "bathroom_cabinet, bathroom_counter, chair, cupboard, drawer_unit, fridge and 3 more"),
    ("go_to_rest", ["rest_near_user=kitchen"],
     "parameter rest_near_user: kitchen is a Room, not a LargeObject or LargeArticulatedObject; "
     "try one of: bathroom_cabinet, bathroom_counter, chair, cupboard, drawer_unit, fridge "
     "and 3 more"),
    ("refine_localisation", ["at=nowhere"],
     "parameter at: no node 'nowhere' in the map; try one of: bathroom_cabinet, "
     "bathroom_counter, chair, cupboard, drawer_unit, fridge and 3 more"),
    ("fetch_object", ["object=blue cup", "bring_to=nowhere"],
     "parameter bring_to: no node 'nowhere' in the map; try one of: bathroom_cabinet, "
     "bathroom_counter, chair, cupboard, drawer_unit, fridge and 3 more"),
    ("turn_off_oven", ["oven=blue_cup"],
     "parameter oven: blue_cup is a SmallObject, not a LargeArticulatedObject; try one of: oven"),
    ("turn_off_oven", ["oven=fridge"],
     "parameter oven: fridge holds no Knob; try one of: oven"),
    ("fetch_object", ["object=zebra"],
     "parameter object: no SmallObject in the map matches 'zebra'; try one of: blue_cup, bowl, "
     "glass_jar, pill_box, red_cup, sugar"),
    ("fetch_object", ["object=blue cup", "max_places=-5"],
     "parameter max_places: expected at least 1, got -5"),
    ("search_object", ["object=bowl", "user_room=garage"],
     "parameter user_room: no Room in the map matches 'garage'; try one of: bathroom, kitchen"),
]


@pytest.mark.parametrize("mission, params, line", BAD, ids=[f"{m}:{p[-1]}" for m, p, _ in BAD])
def test_a_parameter_the_map_refutes_is_one_line_and_exit_2(mission, params, line, tmp_path,
                                                           capsys):
    argv = ["run", f"missions/{mission}.yaml", "--runs-dir", str(tmp_path)]
    for p in params:
        argv += ["--param", p]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err.strip() == line
    assert captured.out == ""
    assert not list(tmp_path.glob("*.jsonl"))          # nothing started


@pytest.fixture(scope="module")
def api():
    """The shipped missions served over HTTP on the demo home (nothing is run: every
    request below is refused at submit)."""
    import httpx

    from hearth.executive.command.api import create_app
    from hearth.executive.command.server import ServerThread, make_service
    from hearth import demo_world_path
    from hearth.robot.clock import SimClock
    world = load_world(demo_world_path())
    service = make_service(world, None, [str(MISSIONS)], clock=SimClock(), runs_dir=None)
    thread = ServerThread(create_app(service)).start()
    client = httpx.Client(base_url=thread.url, timeout=30.0)
    yield client
    client.close()
    thread.stop()
    service.executive.shutdown()
    service.close()


def _typed(mission: str, params: list[str]) -> dict:
    """What a JSON client sends for these NAME=VALUE pairs (numbers as numbers)."""
    m = load_mission(MISSIONS / f"{mission}.yaml")
    out = {}
    for p in params:
        name, _, text = p.partition("=")
        out[name] = int(text) if m.parameters[name].type == "integer" else text
    return out


@pytest.mark.parametrize("mission, params, line", BAD, ids=[f"{m}:{p[-1]}" for m, p, _ in BAD])
def test_the_api_refuses_the_same_parameters_with_422_and_the_same_sentence(api, mission,
                                                                           params, line):
    r = api.post("/api/runs", json={"mission": mission, "params": _typed(mission, params)})
    assert r.status_code == 422, r.text
    assert r.json()["error"]["message"] == line
    assert api.get("/api/runs").json() == []           # nothing was queued


@pytest.mark.parametrize("mission, value", [("refine_localisation", {"at": "here"}),
                                            ("fetch_object", {"object": "blue cup"}),
                                            ("fetch_object", {"object": "red_cup",
                                                              "user_room": "kitchen"}),
                                            ("go_to_rest", {"rest_near_user": "cupboard"})])
def test_declared_sentinels_ids_and_words_are_let_through(mission, value, demo_world):
    m = load_mission(MISSIONS / f"{mission}.yaml")
    assert m.resolve_in_map(value, demo_world) == value


def test_turn_off_oven_finds_the_appliance_with_knobs_in_any_home(demo_world):
    from hearth.executive.scenarios import resolve_world
    oven = load_mission(MISSIONS / "turn_off_oven.yaml")
    assert oven.parameters["oven"].default == ""
    assert oven.resolve_in_map({}, demo_world) == {"oven": "oven"}
    assert oven.resolve_in_map({}, resolve_world("home:3")) == {"oven": "cooker_1"}
    with pytest.raises(MissionError) as err:           # two appliances with knobs: which?
        oven.resolve_in_map({}, resolve_world("home:16"))
    assert str(err.value) == ("parameter oven: which LargeArticulatedObject with a Knob do you "
                              "mean: the kitchen hob (hob_1) or the kitchen oven (oven_1)? Name it: "
                              "oven=hob_1")


def test_the_command_layer_still_says_turn_off_the_oven(demo_world):
    from hearth.executive.command.commands import interpret
    from hearth.executive.command.vocabulary import Vocabulary, load_catalogue
    catalogue, _ = load_catalogue([str(MISSIONS)], load_mission)
    vocab = Vocabulary(demo_world, catalogue)
    try:
        it = interpret("please turn off the oven", vocab.templates, demo_world)
    finally:
        vocab.close()
    assert (it.outcome, it.mission, it.params) == ("run", "turn_off_oven", {"oven": "oven"})


def test_bounds_and_map_declarations_are_checked_when_the_mission_loads(mission_file):
    path = mission_file("""
        name: m
        parameters:
          n: {type: integer, default: 0, minimum: 1}
          s: {type: string, minimum: 2}
          p: {type: node_id, sentinels: [here]}
          k: {type: integer, kinds: [Room]}
        tree: {skill: Say, inputs: {text: hi}}
    """)
    with pytest.raises(MissionError) as err:
        load_mission(path)
    lines = str(err.value).splitlines()
    assert any(line.endswith("parameter n: default expected at least 1, got 0") for line in lines)
    assert any("parameter s: minimum and maximum are for integer and number" in line
               for line in lines)
    assert any("parameter p: having, sentinels and pick_only need kinds" in line
               for line in lines)
    assert any("parameter k: kinds are for node_id and string parameters" in line
               for line in lines)


def test_an_unknown_node_kind_is_a_schema_error_with_its_line(mission_file):
    path = mission_file("""
        name: m
        parameters:
          p: {type: node_id, kinds: [Sofa]}
        tree: {skill: Say, inputs: {text: hi}}
    """)
    with pytest.raises(MissionError) as err:
        load_mission(path)
    assert f"{path}:4:" in str(err.value) and "Sofa" in str(err.value)


def test_go_to_rest_says_it_did_not_reach_the_place_near_the_user(make_executive, demo_world):
    ex = make_executive([S("*/drive_near_user", outcomes=["failure"]),
                         S("*/drive_out_of_the_way_instead", outcomes=["success"])],
                        world=demo_world, skills=None)
    h = ex.submit(str(MISSIONS / "go_to_rest.yaml"))
    ex.run_until_idle(1000)
    assert h.result.outcome == "failed"
    assert h.result.reason.endswith("I could not reach the side table to rest near you")
    # it still got out of the way rather than staying in it
    sub = ex.make_skill
    assert sub.made["/follow_presence/choose_rest_place/user_home/fall_back/force_success/"
                    "drive_out_of_the_way_instead"].seen_inputs[0]["target"] == "kitchen_table"


def test_go_to_rest_away_fails_when_the_place_out_of_the_way_is_not_reached(make_executive,
                                                                            demo_world):
    ex = make_executive([S("*/drive_out_of_the_way", outcomes=["failure"])], world=demo_world,
                        skills=None)
    h = ex.submit(str(MISSIONS / "go_to_rest.yaml"), presence="away")
    ex.run_until_idle(1000)
    assert h.result.outcome == "failed"
    assert h.result.reason.endswith("I could not reach the kitchen table to rest out of the way")


def test_bounds_and_kinds_survive_a_round_trip_through_behaviortree_cpp(tmp_path):
    from hearth.executive.btcpp import export_mission, import_tree
    xml = tmp_path / "m.xml"
    xml.write_text(export_mission(MISSIONS / "turn_off_oven.yaml"))
    oven = import_tree(xml)[1].parameters["oven"]
    assert (oven.kinds, oven.having, oven.pick_only, oven.default) == \
        (["LargeArticulatedObject"], ["Knob"], True, "")
    xml.write_text(export_mission(MISSIONS / "fetch_object.yaml"))
    places = import_tree(xml)[1].parameters["max_places"]
    assert (places.minimum, places.maximum) == (1, 100)


def test_a_command_the_map_refutes_is_refused_with_the_same_sentence(api):
    r = api.post("/api/commands", json={"text": "turn off the fridge"})
    assert r.status_code == 422, r.text
    assert r.json()["error"]["message"] == "parameter oven: fridge holds no Knob; try one of: oven"
    assert api.get("/api/runs").json() == []
