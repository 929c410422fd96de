"""`hearth bench knobs` prints one JSON object with the figures the issue names (run here on
a few held-out views with the tiny test models)."""
from __future__ import annotations

import json


def test_bench_knobs_prints_the_named_figures(reader, monkeypatch, capsys):
    import skills.knob_models as km
    from executive.cli import main
    from worldmodel import model_store
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
    assert out["detector_threshold"] == round(reader.detect_gate.threshold_, 4)
    assert out["detector_calibration"]["positives"] > 0


def test_bench_knobs_pools_the_worlds_it_is_given_and_says_when_it_has_none(reader, monkeypatch,
                                                                          capsys):
    import skills.knob_models as km
    from executive.cli import main
    from tests.conftest import DEMO_WORLD
    from worldmodel import model_store
    monkeypatch.setattr(km, "load_or_train", lambda world, *a, **k: (reader, km.ModelInfo(
        model_store.path_of(km.MODEL_NAME, {}), "memory")))
    assert main(["bench", "knobs", "--json", "--scenarios", "12", "--quick",
                 "--world", str(DEMO_WORLD)]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["worlds"] == ["demo", str(DEMO_WORLD)]
    assert out["views"] == 24 and set(out["per_world"]) == {"demo", str(DEMO_WORLD)}
    assert sum(w["views"] for w in out["per_world"].values()) == out["views"]
    assert [w["world"] for w in out["per_home"]] == out["worlds"]
    assert main(["bench", "knobs", "--json", "--no-demo"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("knobs: no world to run on (--no-demo needs --world or --homes)")
