"""The MuJoCo renderer (hearth/robot/mujoco_render.py) against Hearth's ray caster: the same
world, camera and pose give the same depth where both see the same surface (to float
rounding noise-free, to within the noise model's spread with Kinect noise), the same node
labels, and a knob turned or hidden between frames shows in the image.

Skipped, with the reason, where MuJoCo is not installed or cannot open an OpenGL context."""
from __future__ import annotations

import numpy as np
import pytest

from hearth.perception.camera import Intrinsics, look_at

mujoco_render = pytest.importorskip("hearth.robot.mujoco_render")
_ok, _why = mujoco_render.available()
pytestmark = pytest.mark.skipif(not _ok, reason=f"MuJoCo cannot render here: {_why}")


@pytest.fixture(scope="module")
def oven_view():
    """The demo home's room with the oven (alone, to keep the scenes small), a 320x240 camera
    1 m in front of and 0.4 m above its first knob."""
    import dataclasses
    from hearth.worldmodel import load_world
    from hearth.worldmodel.io import parse_world, to_xml
    from tests.conftest import DEMO_WORLD
    home = load_world(DEMO_WORLD)
    room = home.room_of(home.knobs()[0].id)
    one = dataclasses.replace(home.apartment, rooms=[room], history=[], search_stats=[])
    world = parse_world(to_xml(one), "oven-room", base_dir=DEMO_WORLD.parent)
    knob = world.knobs()[0]
    T_k = world.T_world(knob.id)
    eye = T_k[:3, 3] + T_k[:3, 2] * 1.0 + np.array([0.0, 0.0, 0.4])
    return world, knob, Intrinsics.kinect(320, 240), look_at(eye, T_k[:3, 3])


@pytest.fixture(scope="module")
def both(oven_view):
    from hearth.robot.sim import world_scene
    world, _knob, K, T = oven_view
    mj = mujoco_render.MujocoScene(world)
    return mj, world_scene(world), K, T


def _same_surface(a, b) -> np.ndarray:
    na, nb = np.array(a.nodes + ["-"]), np.array(b.nodes + ["-"])
    return (a.depth > 0) & (b.depth > 0) & (na[a.labels] == nb[b.labels])


def test_noise_free_depth_and_labels_agree_with_hearths_renderer(both):
    mj, hearth, K, T = both
    a, b = mj.render(K, T), hearth.render(K, T)
    same = _same_surface(a, b)
    assert same.mean() > 0.97                    # the same node seen at nearly every pixel
    diff = np.abs(a.depth[same] - b.depth[same])
    assert np.median(diff) < 1e-4 and np.percentile(diff, 99) < 2e-3
    # incidence (from MuJoCo's depth) drives the noise model: close to the ray caster's
    assert np.median(np.abs(a.incidence[same] - b.incidence[same])) < 0.01


def test_kinect_noise_on_both_renderers_agrees_within_the_noise(both):
    from hearth.robot.noise import KinectNoise, add_kinect_noise
    mj, hearth, K, T = both
    model = KinectNoise()
    a = add_kinect_noise(mj.render(K, T), np.random.default_rng(1), model)
    b = add_kinect_noise(hearth.render(K, T), np.random.default_rng(2), model)
    ok = (a.depth > 0) & (b.depth > 0)
    z = b.depth[ok]
    sigma = np.hypot(model.axial_std(z), model.quantisation_step(z))
    inside = np.abs(a.depth[ok] - z) <= 4 * np.sqrt(2) * sigma
    assert ok.mean() > 0.8 and inside.mean() > 0.97


def test_a_knob_turned_or_hidden_changes_only_that_knob(both, oven_view):
    mj, _hearth, K, T = both
    _world, knob, _K, _T = oven_view
    before = mj.render(K, T)
    mine = before.mask([knob.id])
    assert mine.sum() > 50
    mj.set_states({knob.id: knob.angle + np.pi / 2})
    turned = mj.render(K, T)
    mj.hide([knob.id])
    hidden = mj.render(K, T)
    mj.hide()
    mj.set_states({knob.id: knob.angle})
    changed = np.any(turned.color != before.color, axis=-1)
    assert changed[mine].mean() > 0.02 and not changed[~_grown(mine)].any()
    assert hidden.mask([knob.id]).sum() == 0 and (hidden.depth[mine] > before.depth[mine]).all()


def _grown(mask: np.ndarray, px: int = 2) -> np.ndarray:
    import cv2
    return cv2.dilate(mask.astype(np.uint8), np.ones((2 * px + 1, 2 * px + 1), np.uint8)) > 0


def test_render_view_gives_a_frame_like_the_simulated_robots(oven_view):
    from hearth.robot.noise import KinectNoise
    world, _knob, K, T = oven_view
    frame = mujoco_render.render_view(world, K, T, np.random.default_rng(0), KinectNoise())
    assert frame.depth.shape == (K.height, K.width) and frame.color.dtype == np.uint8
    assert (frame.depth > 0).mean() > 0.8 and frame.labels.max() >= 0


def test_the_simulated_robot_draws_with_mujoco_when_asked(oven_view):
    from hearth.robot.simulated import SimulatedRobot
    world, _knob, _K, _T = oven_view
    frames = {}
    for renderer in ("hearth", "mujoco"):
        robot = SimulatedRobot(world.copy(), seed=3, renderer=renderer)
        robot.look_at(world.T_world("oven")[:3, 3])
        frames[renderer] = robot.capture()
    a, b = frames["mujoco"], frames["hearth"]
    assert isinstance(a.rendering.labels, np.ndarray) and a.depth.shape == b.depth.shape
    ok = (a.depth > 0) & (b.depth > 0)
    # the same seed draws the same noise: the frames differ by rendering alone
    assert ok.mean() > 0.8 and np.median(np.abs(a.depth[ok] - b.depth[ok])) < 1e-3


def test_the_knob_benchs_mujoco_views_are_the_same_views_drawn_by_mujoco():
    """``--renderer mujoco`` of `hearth bench knobs`: the same poses, states and missing
    knobs as Hearth's views of a seed, on a world converted from LIBERO's stove."""
    from pathlib import Path
    from hearth.perception.knob_data import KnobDataConfig, render_views
    from hearth.worldmodel import load_world
    world = load_world(Path(__file__).resolve().parents[1] / "assets" / "libero_flat_stove" / "world.xml")
    data = KnobDataConfig(at_states=True, missing_rate=0.3)
    hearth = render_views(world, 5, 7, data, scenes=mujoco_render.knob_scenes(world, "hearth"))
    mj = render_views(world, 5, 7, data, scenes=mujoco_render.knob_scenes(world, "mujoco"))
    for a, b in zip(hearth, mj):
        assert (a.state, a.present, a.K) == (b.state, b.present, b.K)
        ok = (a.depth > 0) & (b.depth > 0)
        assert ok.mean() > 0.9 and np.median(np.abs(a.depth[ok] - b.depth[ok])) < 1e-4
