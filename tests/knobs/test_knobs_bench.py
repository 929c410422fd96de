"""`hearth bench knobs` prints one JSON object with the figures the issue names (run here on
a few held-out views with the tiny test models)."""
from __future__ import annotations

import json


def test_bench_knobs_prints_the_named_figures(reader, monkeypatch, capsys):
    import hearth.skills.knob_models as km
    from hearth.cli.main import main
    from hearth.worldmodel import model_store
    monkeypatch.setattr(km, "load_or_train", lambda world, *a, **k: (reader, km.ModelInfo(
        model_store.path_of(km.MODEL_NAME, {}), "memory")))
    assert main(["bench", "knobs", "--json", "--scenarios", "40", "--seed", "3"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("detection_precision", "detection_recall", "state_accuracy"):
        assert 0.0 <= out[key] <= 1.0
    assert out["views"] == 40 and out["knobs_present"] + out["knobs_missing"] == 40
    assert out["angle_err_deg_median"] < 30 and out["ms_per_knob"] > 0
    assert out["on_read_as_off"] == 0
    assert out["per_design"]["plain"]["views"] == 40
    # by how hard the view is: every view in one of the levels, none left out
    assert set(out["per_level"]) <= {"near", "hard", "very_hard"}
    assert sum(f["views"] for f in out["per_level"].values()) == 40
    assert sum(f["knobs_present"] for f in out["per_level"].values()) == out["knobs_present"]
    assert sum(f["n"] for f in out["per_level"].values()) == out["knobs_present"]
    assert out["renderer"] == "hearth" and "held_out_families" not in out
    # read from more views as a mission does; from one view, the per-view figure
    views = out["state_over_views"]
    assert views["1"]["state_accuracy"] == out["state_accuracy"]
    assert views["1"]["sequences"] == out["knobs_present"]
    assert set(views) == {"1", "2", "3"}
    assert out["detector_threshold"] == round(reader.detect_gate.threshold_, 4)
    assert out["detector_calibration"]["positives"] > 0


def test_bench_knobs_pools_the_worlds_it_is_given_and_says_when_it_has_none(reader, monkeypatch,
                                                                          capsys):
    import hearth.skills.knob_models as km
    from hearth.cli.main import main
    from tests.conftest import DEMO_WORLD
    from hearth.worldmodel import model_store
    monkeypatch.setattr(km, "load_or_train", lambda world, *a, **k: (reader, km.ModelInfo(
        model_store.path_of(km.MODEL_NAME, {}), "memory")))
    assert main(["bench", "knobs", "--json", "--scenarios", "12", "--quick",
                 "--world", str(DEMO_WORLD)]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["worlds"] == ["demo", str(DEMO_WORLD)]
    assert out["views"] == 24 and set(out["per_world"]) == {"demo", str(DEMO_WORLD)}
    assert sum(w["views"] for w in out["per_world"].values()) == out["views"]
    assert [w["world"] for w in out["per_home"]] == out["worlds"]
    # one family only: no other family's readings to choose its gates on, said so
    assert main(["bench", "knobs", "--json", "--scenarios", "8", "--quick", "--held-out-families"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["held_out_families"] == {"plain": {"skipped": "no other family to choose gates on",
                                                  "n": 0, "near_state_accuracy": None}}
    assert main(["bench", "knobs", "--json", "--no-demo"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("knobs: no world to run on (--no-demo needs --world or --homes)")


def test_a_knob_read_from_more_views_keeps_the_first_state_a_view_gives():
    """``state_over_views``: each view leads a sequence of k views of the same knob at the
    same state; the first view that gives a state decides, right or wrong, as a mission
    reading from one place and then another does."""
    from hearth.benchmarks.knobs import over_views

    def view(knob, truth, state, present=True, world="w"):
        return dict(world=world, knob=knob, truth=truth, off="off", state=state, present=present)
    recs = [view("a", "2", "unknown"), view("a", "2", "2"), view("a", "2", "unknown"),
            view("b", "3", "1"), view("b", "3", "3"),
            view("c", "1", "off"), view("c", "1", "unknown", present=False),
            view("a", "2", "2", world="other")]
    out = over_views(recs)
    # one view: every present view alone (a 1/3 right, b 1/2, c wrong: read off, and a of
    # the other world right)
    assert out["1"] == dict(sequences=7, state_accuracy=round(3 / 7, 4),
                            state_wrong_rate=round(2 / 7, 4), on_read_as_off=1)
    # two views: a's three sequences (u,2) (2,u) (u,u) give 2, 2, unknown; b's (1,3) (3,1)
    # give 1 (wrong) and 3; c and the other world's a have one view: no sequence
    assert out["2"] == dict(sequences=5, state_accuracy=0.6, state_wrong_rate=0.2,
                            on_read_as_off=0)
    # three views: only a, right from every start
    assert out["3"] == dict(sequences=3, state_accuracy=1.0, state_wrong_rate=0.0,
                            on_read_as_off=0)


def test_gates_chosen_again_on_a_readers_own_readings_are_its_gates(reader):
    """The held-out protocol chooses gates on other families' readings with the function
    training used (``gates_from``): on the reader's own validation readings it gives the
    reader's gates to the digit, and on readings with every wrong one left out, state gates
    no higher."""
    from hearth.perception.knob_training import TrainingConfig, gates_from
    val = reader.validation_
    assert {"depth", "colour"} <= set(val) and all("knob" in r for r in val["depth"])
    again = gates_from(reader, val, TrainingConfig().tiny())
    assert again.detect_gate.threshold_ == reader.detect_gate.threshold_
    assert [again.margin_threshold_for(lv) for lv in range(3)] == \
           [reader.margin_threshold_for(lv) for lv in range(3)]
    assert again.half_turn_gates == reader.half_turn_gates
    right = {k: [r for r in rs if r["right"] or not r["present"]] for k, rs in val.items()}
    easier = gates_from(reader, right, TrainingConfig().tiny())
    assert all(easier.margin_threshold_for(lv) <= reader.margin_threshold_for(lv) for lv in range(3))
