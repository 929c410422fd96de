"""The model store keeps one model per home and training configuration: training for another
home leaves this one's models current, a changed knob design makes them stale, and what the
robot changes while it works (knob states, doors, furniture moved) does not."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.perception.knob_training import world_signature
from hearth.skills import knob_models as km
from hearth.skills.knob_models import TrainingConfig, load_or_train
from hearth.worldmodel import model_store
from hearth.worldmodel.io import load_world, save_world
from hearth.worldmodel.pose import Pose


@pytest.fixture
def demo(demo_world_path):
    return load_world(demo_world_path)


def test_model_store_names_what_changed(tmp_path):
    model_store.save("m", {"a": 1}, {"x": 1, "y": {"z": 2}}, directory=tmp_path)
    model_store.forget()
    assert model_store.load("m", {"x": 1, "y": {"z": 2}}, directory=tmp_path).model == {"a": 1}
    stale = model_store.load("m", {"x": 1, "y": {"z": 3}}, directory=tmp_path)
    assert stale.model is None and stale.reason == "stale: trained with other y.z"
    assert model_store.load("n", {}, directory=tmp_path).reason == "missing"
    (tmp_path / "bad.joblib").write_text("not a model")
    assert model_store.load("bad", {}, directory=tmp_path).reason.startswith("unreadable")
    # written through a temporary file that does not stay behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.joblib", "m.joblib"]


def test_models_of_two_homes_are_stored_side_by_side(tmp_path):
    a, b = {"knobs": [{"id": "k", "radius": 0.02}]}, {"knobs": [{"id": "k", "radius": 0.03}]}
    pa = model_store.save("knobs", "model A", {"v": 1}, world=a, directory=tmp_path)
    pb = model_store.save("knobs", "model B", {"v": 1}, world=b, directory=tmp_path)
    assert pa != pb and pa.name.startswith("knobs-") and pb.exists()
    model_store.forget()
    assert model_store.load("knobs", {"v": 1}, world=a, directory=tmp_path).model == "model A"
    assert model_store.load("knobs", {"v": 1}, world=b, directory=tmp_path).model == "model B"


def _other_home(demo_world_path, tmp_path):
    """The demo home with smaller, darker knobs on the oven (another home's design)."""
    demo = load_world(demo_world_path)
    for k in demo.knobs():
        k.radius, k.color, k.marker_color = 0.018, (0.15, 0.15, 0.16), (0.9, 0.9, 0.9)
    path = tmp_path / "other.xml"
    save_world(demo, path)
    return load_world(path)


def test_training_for_another_home_leaves_this_homes_models_current(
        demo, demo_world_path, reader, knob_model_dir, tmp_path, monkeypatch):
    """Home A (the demo, trained by the session's fixture), then home B, then A again: A is
    not retrained, and B's models are stored beside A's."""
    calls = []
    real = km.train
    monkeypatch.setattr(km, "train", lambda world, *a, **k: calls.append(world) or real(world, *a, **k))
    tiny = TrainingConfig().tiny()
    other = _other_home(demo_world_path, tmp_path)
    _, info_b = load_or_train(other, tiny, directory=knob_model_dir)
    assert info_b.source == "trained" and info_b.reason == "missing" and len(calls) == 1
    model_store.forget()
    _, info_a = load_or_train(demo, tiny, directory=knob_model_dir, retrain=False)
    assert info_a.source == "disk" and info_a.path != info_b.path
    _, again_b = load_or_train(other, tiny, directory=knob_model_dir, retrain=False)
    assert again_b.source == "disk" and len(calls) == 1


def test_the_home_key_follows_knob_designs_not_what_the_robot_changes(demo):
    key = world_signature(demo)
    demo.set_knob_state("oven_knob_2", "3")
    demo.set_joint_state("oven_door", 0.7)
    chair = next(o for o in demo.large_objects() if not demo.knobs(o.id))
    p = chair.pose
    demo.set_pose(chair.id, Pose(p.x + 0.4, p.y - 0.2, p.z, p.roll, p.pitch, p.yaw + 0.5))
    assert world_signature(demo) == key
    knob = demo.get("oven_knob_1")
    knob.marker_color = (0.8, 0.1, 0.1)
    assert world_signature(demo) != key
    knob.marker_color = demo.get("oven_knob_3").marker_color
    assert world_signature(demo) == key
    knob.radius *= 0.8
    assert world_signature(demo) != key
    knob.radius /= 0.8
    # states are snapped to at read time from the map: renaming one needs no retraining
    knob.states[1].name = "low"
    knob.states[1].angle -= math.radians(5)
    assert world_signature(demo) == key


def test_the_key_does_not_change_when_the_file_is_saved_again(demo, tmp_path):
    key = world_signature(demo)
    path = tmp_path / "w.xml"
    save_world(demo, path)
    text = path.read_text()
    path.write_text(text.replace("<room ", "<!-- a note -->\n\n<room ", 1))   # lines move
    assert world_signature(load_world(path)) == key


def test_a_knob_view_renders_as_one_scene_of_the_whole_home(demo):
    """Training renders the knobs in a small scene of their own in front of the rest of the
    home; the picture is the one a single scene of everything gives."""
    from hearth.perception.camera import Intrinsics
    from hearth.perception.knob_data import KnobDataConfig, KnobScenes, _camera, _crop
    from hearth.perception.knobs import KnobConfig
    from hearth.perception.render import Scene
    scenes = KnobScenes(demo)
    rng = np.random.default_rng(4)
    K = Intrinsics.kinect()
    same = total = 0
    for i, kid in enumerate(sorted(scenes.priors) * 3):
        owner = scenes.owner[kid]
        angles = {k: float(rng.uniform(-math.pi, math.pi)) for k in scenes.knobs_of[owner]}
        missing = (kid,) if i % 4 == 0 else ()
        T, _, _ = _camera(scenes.priors[kid], rng, KnobDataConfig())
        Kc = _crop(K, T, scenes.priors[kid], KnobConfig())
        if Kc is None:
            continue
        whole = [lm for lm in scenes._object_meshes(demo, demo.get(owner), states=angles)
                 if lm.node not in missing]
        one = Scene(scenes.static + whole).render(Kc, T)
        two = scenes.scene(owner, angles, missing).render(Kc, T)
        def names(r):
            return np.array(list(r.nodes) + [""])[r.labels]     # label -1: nothing
        agree = ((np.abs(one.depth - two.depth) < 1e-5)
                 & (np.abs(one.color.astype(int) - two.color).max(-1) <= 1)
                 & (names(one) == names(two)))
        same, total = same + int(agree.sum()), total + agree.size
    # pixels where a knob's back face and the panel lie in one plane may go either way
    assert same / total > 0.999


def test_hearth_train_all_on_a_home_without_knobs_says_none_are_needed(demo, tmp_path, capsys):
    from hearth.cli.main import main
    for o in demo.large_objects():
        if hasattr(o, "knobs"):
            o.knobs.clear()
            for p in o.parts:
                p.knobs.clear()
    path = tmp_path / "no_knobs.xml"
    save_world(demo, path)
    assert main(["train", "all", "--check", "--world", str(path), "--model-dir", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "demo_home has no knobs: no knob models needed" in out
    assert "segmentation forest: missing" in out
