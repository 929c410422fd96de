"""Utterance templates, interpretation and the vocabulary, without a server."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hearth.executive.autonomy import APPROVED, EXPIRED, PENDING, Approvals
from hearth.executive.command.commands import interpret
from hearth.executive.command.vocabulary import Vocabulary, load_catalogue, normalise, read_templates
from hearth.executive.errors import MissionError
from hearth.executive.missionfile import load_mission
from hearth.worldmodel.pose import Pose

HERE = Path(__file__).parent
ROOT = HERE.parents[1]


def _registry():
    import importlib.util
    spec = importlib.util.spec_from_file_location("command_conftest", HERE / "conftest.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.registry()


REG = _registry()


def _load(path):
    return load_mission(path, REG)


@pytest.fixture(scope="module")
def catalogue():
    entries, problems = load_catalogue([HERE / "missions"], _load)
    assert problems == []
    return entries


def _say(text, catalogue, world):
    templates = [t for e in catalogue.values() for t in e.templates]
    return interpret(text, templates, world, {n: e.mission for n, e in catalogue.items()})


@pytest.mark.parametrize("text, mission, params", [
    ("bring me the blue cup", "fetch_test", {"object": "blue_cup"}),
    ("Bring me my BLUE cup!", "fetch_test", {"object": "blue_cup"}),
    ("please fetch the pill box", "fetch_test", {"object": "pill_box"}),
    ("Where is my pill box?", "where_test", {"object": "pill_box"}),
    ("where are my red cups", "where_test", {"object": "red_cup"}),
    ("turn off the oven", "oven_test", {"oven": "oven"}),
    ("switch off oven", "oven_test", {"oven": "oven"}),
    ("I am going out", "rest_test", {"presence": "away"}),
    ("count to 7", "rest_test", {"n": 7}),
])
def test_utterance_maps_to_mission_and_parameters(text, mission, params, catalogue, demo_world):
    it = _say(text, catalogue, demo_world)
    assert (it.outcome, it.mission, it.params) == ("run", mission, params)


def test_the_slot_class_limits_what_words_can_name(catalogue, demo_world):
    # "oven" also names the oven door, handle and knobs; an appliance slot means the oven.
    assert _say("turn off the oven", catalogue, demo_world).params == {"oven": "oven"}
    it = _say("turn off the kitchen table", catalogue, demo_world)
    assert it.outcome == "clarify" and it.say == "I do not know a kitchen table."


def test_ambiguous_words_list_every_candidate(catalogue, demo_world):
    it = _say("bring me a cup", catalogue, demo_world)
    assert it.outcome == "clarify" and it.text_id == "T_CLARIFY_WHICH"
    assert it.args == {"words": "cup", "candidates": ["blue cup", "red cup"]}
    assert it.mission == "fetch_test" and it.slot == "object"


@pytest.mark.parametrize("text", ["bring me the cup please", "could you please bring me a cup",
                                  "bring me the cup, thank you"])
def test_courtesy_words_are_not_part_of_what_is_asked_for(text, catalogue, demo_world):
    it = _say(text, catalogue, demo_world)
    assert it.outcome == "clarify" and it.args["words"] == "cup"
    assert it.say.startswith("Which cup do you mean: ")


def test_not_understood_gives_examples_a_person_can_say(catalogue, demo_world):
    it = _say("sing me a song", catalogue, demo_world)
    assert it.outcome == "not_understood"
    assert "{" not in it.say and "(" not in it.say and "|" not in it.say
    assert "bring me the " in it.say


def test_a_value_slot_that_does_not_parse_asks_again(catalogue, demo_world):
    it = _say("count to seven", catalogue, demo_world)
    assert it.outcome == "clarify" and it.say == "I did not get the n: expected integer, got 'seven'."


def test_templates_are_checked_with_file_and_line(tmp_path):
    def mission(utterance):
        p = tmp_path / "m.yaml"
        p.write_text(textwrap.dedent(f"""\
            hearth: 1
            name: m
            utterances:
              - "go home"
              - {utterance}
            parameters:
              object: {{type: string}}
              n: {{type: integer, default: 1}}
            tree:
              skill: Act
            """))
        return p

    for utterance, message in [
        ('"bring {thing}"', "{thing} is not a parameter of mission m (known: n, object)"),
        ('"bring {object:gadget}"', "unknown slot class 'gadget'"),
        ('"bring {object} {n}"', "two slots need a word between them"),
        ('{say: "go", params: {n: many}}', "params: n: expected integer, got 'many'"),
    ]:
        path = mission(utterance)
        with pytest.raises(MissionError) as err:
            read_templates(_load(str(path)), str(path))
        assert err.value.line == 5 and message in str(err.value)
        assert str(err.value).startswith(f"{path}:5: utterance ")
        _, problems = load_catalogue([path], _load)
        assert len(problems) == 1 and message in problems[0]


def test_the_schema_refuses_a_malformed_utterances_list(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text("hearth: 1\nname: m\nutterances: [{params: {}}]\ntree:\n  skill: Act\n")
    with pytest.raises(MissionError):
        _load(str(p))


def test_every_mission_in_missions_has_templates_that_compile():
    from hearth.executive.missionfile import skill_registry
    reg = skill_registry()
    entries, problems = load_catalogue([ROOT / "missions"], lambda f: load_mission(f, reg))
    assert problems == []
    assert {"fetch_object", "search_object", "turn_off_oven"} <= set(entries)
    assert all(e.templates for e in entries.values())


def test_real_missions_understand_the_issue_examples(demo_world):
    from hearth.executive.missionfile import skill_registry
    reg = skill_registry()
    entries, _ = load_catalogue([ROOT / "missions"], lambda f: load_mission(f, reg))
    for text, mission, params in [("bring me the blue cup", "fetch_object", {"object": "blue_cup"}),
                                  ("turn off the oven", "turn_off_oven", {"oven": "oven"}),
                                  ("where is my pill box?", "search_object", {"object": "pill_box"})]:
        it = _say(text, entries, demo_world)
        assert (it.outcome, it.mission, it.params) == ("run", mission, params)


def test_vocabulary_follows_the_map(catalogue, demo_world):
    revisions = []
    vocab = Vocabulary(demo_world, catalogue, on_change=revisions.append)
    snap = vocab.snapshot()
    assert vocab.snapshot() is snap                     # cached until the map changes
    assert {"blue_cup", "red_cup", "pill_box"} <= {o["id"] for o in snap["objects"]}
    assert next(o for o in snap["objects"] if o["id"] == "blue_cup")["label"] == "blue cup"
    demo_world.move_object("pill_box", "kitchen_table", Pose(0.2, 0.0, 0.75), source="test")
    assert revisions and vocab.revision == revisions[-1] > snap["revision"]
    moved = next(o for o in vocab.snapshot()["objects"] if o["id"] == "pill_box")
    assert moved["where"] == "on the kitchen table" and moved["room"] == "kitchen"
    vocab.close()


_WORLD: dict = {}   # read-only here, loaded once for all examples
words = st.text(alphabet="abcdefghijklmnopqrstuvwxyz", min_size=1, max_size=8)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(prefix=st.lists(words, min_size=1, max_size=4), article=st.booleans(),
       obj=st.sampled_from(["blue cup", "red cup", "pill box", "bowl", "glass jar"]))
def test_a_template_matches_its_own_sentences(prefix, article, obj, tmp_path_factory):
    from hearth.worldmodel import load_world
    demo_world = _WORLD.get("w") or _WORLD.setdefault("w", load_world(ROOT / "data/demo_home/world.xml"))
    d = tmp_path_factory.mktemp("t")
    template = " ".join(prefix) + " (the|my) {object:thing}"
    (d / "m.yaml").write_text(f'hearth: 1\nname: m\nutterances: ["{template}"]\n'
                              "parameters:\n  object: {type: string}\ntree:\n  skill: Act\n")
    entries, problems = load_catalogue([d], _load)
    assert problems == []
    said = " ".join(prefix) + (" the " if article else " ") + obj + "?"
    it = _say(said, entries, demo_world)
    expected = demo_world.find(obj, kinds=["SmallObject"])[0].node.id
    assert (it.outcome, it.params) == ("run", {"object": expected})


@settings(derandomize=True)
@given(st.text(max_size=40))
def test_normalise_keeps_only_lower_case_words(text):
    out = normalise(text)
    assert out == out.strip() and "  " not in out
    assert all(w.isalnum() and w == w.lower() for w in out.split())


def test_approval_expires_at_its_deadline_and_a_raised_level_approves():
    ap = Approvals(granted=1, timeout=30.0)
    seen = []
    ap.subscribe(lambda kind, data: seen.append((kind, data.get("state"))))
    r = ap.request(run="r1", path="/m/turn", skill="TurnKnob", level=2, now=100.0)
    assert ap.poll(r, 129.9) == PENDING
    assert ap.poll(r, 130.0) == EXPIRED and r.reason == "no answer within 30 s"
    r2 = ap.request(run="r1", path="/m/turn", skill="TurnKnob", level=2, now=200.0)
    ap.set_granted(2)
    assert ap.poll(r2, 201.0) == APPROVED and r2.decided_by == "autonomy"
    assert seen == [("approval", "pending"), ("approval", "expired"), ("approval", "pending"),
                    ("autonomy", None), ("approval", "approved")]
