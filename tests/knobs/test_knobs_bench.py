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
    assert out["detector_threshold"] == round(reader.detect_gate.threshold_, 4)
    assert out["detector_calibration"]["positives"] > 0
