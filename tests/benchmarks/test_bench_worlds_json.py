"""`hearth bench objects|nbv|tracking --quick` on a tiny generated home: the pooled figures at
the top level, the same per world, nothing taken from the demo home."""
from __future__ import annotations

import math

from tests.benchmarks.conftest import bench_json


def _in(value, lo, hi):
    return value is not None and math.isfinite(value) and lo <= value <= hi


def test_objects_bench_reports_pooled_and_per_world_figures_on_a_generated_home(capsys, tiny_home):
    out = bench_json(capsys, "objects", "--quick", "--no-demo", "--world", str(tiny_home),
                     "--scenarios", "3")
    assert out["worlds"] == [str(tiny_home)] and out["skipped"] == {}
    home = out["per_world"][str(tiny_home)]
    assert out["scenes"] == home["scenes"] == 3
    assert out["true_positives"] + out["false_negatives"] > 0     # objects were put in view
    assert _in(out["detection_f1"], 0, 1) and out["detection_f1"] == home["detection_f1"]
    assert set(out["per_kind_f1"]) <= {"top", "shelf", "inside"}
    from hearth.worldmodel import load_world
    world = load_world(tiny_home)
    assert set(home["per_object_f1"]) <= {o.id for o in world.small_objects()}
    assert set(out["per_type_f1"]) <= {o.type for o in world.small_objects()}
    assert _in(out["ms_per_view_median"], 0, 60_000)
    assert out["targets"] == {"detection_f1": 0.95, "ms_per_view_median": 300}
    look = out["lookalike"]                 # apart from the figures above
    assert set(look) == {"scenes", "false_positives", "false_positive_rate", "per_variant",
                         "taken_for"}
    assert set(look["per_variant"]) <= {"taller", "one_colour"}
    assert 0 <= look["false_positives"] <= look["scenes"]
    assert look["false_positive_rate"] is None or _in(look["false_positive_rate"], 0, 1)


def test_lookalikes_are_taller_or_lack_a_colour(demo_world):
    import numpy as np
    from hearth.benchmarks._worlds import extent, extent_of_model
    from hearth.benchmarks.objects import lookalike
    rng = np.random.default_rng(0)
    cup = demo_world.get("red_cup")                 # body and handle of one colour
    assert lookalike(cup, "one_colour", rng) is None
    tall = lookalike(cup, "taller", rng)
    grown = extent_of_model(demo_world, tall)[1] - extent(demo_world, "red_cup")[1]
    assert 0.02 - 1e-9 <= grown <= 0.04 + 1e-9
    assert [v.color for v in tall.model.visuals] == [v.color for v in cup.model.visuals]
    box = demo_world.get("pill_box")                # a white box with a red lid
    plain = lookalike(box, "one_colour", rng)
    assert len({v.color for v in plain.model.visuals}) == 1
    assert [v.size for v in plain.model.visuals] == [v.size for v in box.model.visuals]
    assert len({v.color for v in box.model.visuals}) == 2     # the map's own is untouched


def test_nbv_bench_reports_pooled_and_per_world_figures_on_a_generated_home(capsys, tiny_home):
    out = bench_json(capsys, "nbv", "--quick", "--no-demo", "--world", str(tiny_home),
                     "--scenarios", "2")
    assert out["worlds"] == [str(tiny_home)]
    home = out["per_world"][str(tiny_home)]
    assert out["scenes"] == home["scenes"] == 2
    assert out["scenes_tried"] >= 2
    for key in ("recognised_within_two_views", "occlusion_avoided", "occlusion_below_half",
                "random_view_occlusion_avoided"):
        assert _in(out[key], 0, 1) and out[key] == home[key]
    assert sum(k["scenes"] for k in out["per_kind"].values()) == 2


def test_tracking_bench_reports_pooled_and_per_world_figures_on_a_generated_home(capsys, tiny_home):
    out = bench_json(capsys, "tracking", "--quick", "--no-demo", "--world", str(tiny_home),
                     "--scenarios", "1", "--frames", "12")
    home = out["per_world"][str(tiny_home)]
    assert out["scenarios"] == home["scenarios"] == 1
    assert out["frames"] == 11
    assert _in(out["centroid_err_cm_median"], 0, 100)
    assert out["centroid_err_cm_median"] == home["centroid_err_cm_median"]
    assert out["hz"] > 0 and out["particles_median"] >= 150
    (kind, fig), = out["per_type"].items()
    assert fig["scenarios"] == 1


def test_default_worlds_are_the_demo_and_generated_homes(capsys):
    from argparse import Namespace
    from hearth.benchmarks._worlds import world_specs
    assert world_specs(Namespace(seed=4, quick=False, homes=None, world=None)) == \
        ["demo", "home:4", "home:5"]
    assert world_specs(Namespace(seed=0, quick=True, homes=None, world=None, no_demo=True)) == \
        ["home:0"]
    assert world_specs(Namespace(seed=0, quick=False, homes=3, world=["a.xml"], no_demo=False)) == \
        ["demo", "a.xml"]


def test_a_world_without_any_surface_is_one_clear_line(capsys, tmp_path):
    from hearth.cli.main import main
    from hearth.worldmodel import load_world
    from hearth.worldmodel.io import save_world
    from tests.benchmarks.conftest import make_tiny_home
    path = make_tiny_home(tmp_path)
    world = load_world(path)
    for obj in world.large_objects():
        obj.surfaces = []
    bare = tmp_path / "bare.xml"
    save_world(world, bare)
    capsys.readouterr()
    assert main(["bench", "objects", "--quick", "--no-demo", "--no-progress",
                 "--world", str(bare)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no surface" in err[0] and str(bare) in err[0]


def test_objects_bench_with_learned_models_compares_them_on_the_same_scenes(capsys, tiny_home,
                                                                              tmp_path, monkeypatch):
    """--learned-models detects every scene again with the model set's models; a set made of
    the drawn models' own meshes must detect exactly as the drawn models do (ratio 1, no new
    swap). Learning the set (hearth bench learning's pipeline) is left out: minutes."""
    import numpy as np
    import hearth.benchmarks.learning as learning
    from hearth.worldmodel import load_world
    from hearth.worldmodel.geometry import small_object_meshes
    from hearth.worldmodel.learned import write_model_set
    world = load_world(tiny_home)
    models = {}
    for o in world.small_objects():
        models[o.id] = [(np.asarray(lm.mesh.vertices), np.asarray(lm.mesh.triangles), lm.color,
                         np.eye(4)) for lm in small_object_meshes(world, o, T_world_object=np.eye(4))]
    ids = sorted(models)
    write_model_set(tmp_path / "set", {k: models[k] for k in ids[1:]}, {ids[0]: "not learned here"})
    monkeypatch.setattr(learning, "model_set_for", lambda spec, seed=0, progress=None: tmp_path / "set")
    out = bench_json(capsys, "objects", "--quick", "--no-demo", "--world", str(tiny_home),
                     "--scenarios", "3", "--learned-models")
    got = out["learned_models"]
    assert got["scenes"] == out["scenes"] == 3
    assert got["true_positives"] == out["true_positives"]
    assert got["false_positives"] == out["false_positives"]
    assert got["f1_ratio"] == (1.0 if out["detection_f1"] else None)
    assert got["new_same_type_swaps"] == 0
    sets = out["learned_model_sets"][str(tiny_home)]
    assert sets["learned"] == ids[1:] and sets["not_learned"] == {ids[0]: "not learned here"}
