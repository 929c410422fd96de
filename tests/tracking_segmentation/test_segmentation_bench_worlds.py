"""`hearth bench segmentation` on any world: views of a generated home it never trained on,
figures per world and pooled, the demo home's keys only when the demo home is run."""
from __future__ import annotations

import math

from tests.benchmarks.conftest import bench_json, make_tiny_home


def _in(value, lo, hi):
    return value is not None and math.isfinite(value) and lo <= value <= hi


def test_segmentation_bench_reports_pooled_and_per_world_figures_on_a_generated_home(
        capsys, monkeypatch, tmp_path, small_forest):
    from hearth.skills import segmentation_model as sm
    monkeypatch.setattr(sm, "load_or_train", lambda *a, **k: small_forest)
    home = str(make_tiny_home(tmp_path))
    out = bench_json(capsys, "segmentation", "--quick", "--no-demo", "--world", home,
                     "--scenarios", "1", "--views", "3")
    assert out["frames"] == 1                          # held-out random rooms, as before
    assert out["worlds"] == [home]
    fig = out["per_world"][home]
    assert out["homes_frames"] == fig["frames"] == 3
    assert _in(out["homes_class_average_accuracy"], 0.3, 1)   # a small forest, an unseen home
    assert out["homes_class_average_accuracy"] == fig["class_average_accuracy"]
    assert {"floor", "wall"} <= set(out["homes_per_class"])
    assert set(out["homes_per_class"]) <= {"floor", "wall", "ceiling", "table", "chair",
                                           "cabinet", "object"}
    assert "demo_home_class_average_accuracy" not in out     # the demo home was not run
    assert out["targets"]["homes_class_average_accuracy"] == 0.85
