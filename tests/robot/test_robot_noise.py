"""The Kinect-class noise model and simulated views (robot/noise.py, robot/sim.py)."""
from __future__ import annotations

import math

import numpy as np
import open3d as o3d
import pytest

from hearth.perception.camera import Intrinsics
from hearth.perception.render import Scene
from hearth.robot.noise import KinectNoise, add_kinect_noise
from hearth.robot.sim import camera_pose, pan_tilt_to, render_view
from hearth.worldmodel.geometry import LabelledMesh

K = Intrinsics.kinect()


def plane_rendering(z: float, material: str = "matte", tilt_deg: float = 0.0):
    """A wide plane facing the camera (at the identity pose) at depth z, turned about x."""
    m = o3d.geometry.TriangleMesh.create_box(8.0, 8.0, 0.01)
    m.translate((-4.0, -4.0, 0.0))           # the face the camera sees at z = 0
    R = o3d.geometry.get_rotation_matrix_from_xyz((math.radians(tilt_deg), 0.0, 0.0))
    m.rotate(R, center=(0, 0, 0))
    m.translate((0, 0, z))
    return Scene([LabelledMesh("wall", "wall", m, (0.8, 0.8, 0.8), material)]).render(K, np.eye(4))


def test_plane_at_1_5_m_reads_1_5_m_within_the_noise():
    noisy = add_kinect_noise(plane_rendering(1.5), np.random.default_rng(0))
    d = noisy.depth[noisy.depth > 0]
    assert d.size > 0.95 * K.width * K.height
    assert abs(float(np.mean(d)) - 1.5) < 0.002
    assert np.all(np.abs(d - 1.5) < 6 * KinectNoise().axial_std(1.5) + 0.02)


@pytest.mark.parametrize("z", [1.0, 2.0])
def test_depth_std_is_within_20_percent_of_the_documented_model(z):
    noisy = add_kinect_noise(plane_rendering(z), np.random.default_rng(1))
    d = noisy.depth[noisy.depth > 0]
    model = 0.0012 + 0.0019 * (z - 0.4) ** 2     # Nguyen et al. 2012, docs/robot-adapter.md
    assert abs(float(np.std(d - z)) - model) < 0.2 * model


def test_depth_is_quantised_in_disparity_steps():
    noisy = add_kinect_noise(plane_rendering(2.0), np.random.default_rng(2))
    assert len(np.unique(noisy.depth[noisy.depth > 0])) < 40


def test_dark_and_glass_surfaces_lose_readings_matte_does_not():
    rng = np.random.default_rng(3)
    frac = {mat: float((add_kinect_noise(plane_rendering(1.5, mat), rng).depth == 0).mean())
            for mat in ("matte", "dark", "glass")}
    assert frac["matte"] < 0.01
    assert 0.3 < frac["dark"] < 0.7
    assert frac["glass"] > 0.8


def test_grazing_surfaces_lose_readings():
    clean = plane_rendering(3.0, tilt_deg=84.0)
    noisy = add_kinect_noise(clean, np.random.default_rng(4))
    grazing = (clean.depth > 0) & (clean.incidence < math.cos(math.radians(86)))
    steep = (clean.depth > 0) & (clean.incidence > math.cos(math.radians(70)))
    assert grazing.sum() > 1000 and steep.sum() > 1000
    assert (noisy.depth[grazing] == 0).mean() > 0.95
    assert (noisy.depth[steep] == 0).mean() < 0.05


def test_colour_noise_is_whole_grey_levels_of_the_documented_spread():
    """Per pixel, the same offset on the three channels, a Gaussian of ``color_std`` grey
    levels rounded to whole levels: standard deviation sqrt(std^2 + 1/12), mean 0."""
    clean = plane_rendering(1.5)
    noisy = add_kinect_noise(clean, np.random.default_rng(6))
    diff = noisy.color.astype(int) - clean.color.astype(int)
    assert np.array_equal(diff[..., 0], diff[..., 1]) and np.array_equal(diff[..., 0], diff[..., 2])
    d = diff[..., 0]
    std = KinectNoise().color_std
    assert abs(float(d.mean())) < 0.02
    assert abs(float(d.std()) - math.sqrt(std ** 2 + 1 / 12)) < 0.02
    # The discretised Gaussian's probabilities, level by level, to within sampling error.
    for k in range(-4, 5):
        p = 0.5 * (math.erf((k + 0.5) / (std * math.sqrt(2))) - math.erf((k - 0.5) / (std * math.sqrt(2))))
        assert abs(float((d == k).mean()) - p) < 5 * math.sqrt(p * (1 - p) / d.size) + 1e-4
    assert add_kinect_noise(clean, np.random.default_rng(6), KinectNoise(color_std=0)).color.tolist() \
        == clean.color.tolist()


def test_same_seed_same_noise_and_none_is_noise_free():
    clean = plane_rendering(1.2)
    a = add_kinect_noise(clean, np.random.default_rng(5))
    b = add_kinect_noise(clean, np.random.default_rng(5))
    assert np.array_equal(a.depth, b.depth) and np.array_equal(a.color, b.color)
    assert add_kinect_noise(clean, np.random.default_rng(5), None) is clean
    assert a.labels is clean.labels          # ground truth stays


def test_render_view_gives_the_frame_of_render_then_noise(demo_world):
    """render_view draws the noise while it shades: the same frame, for a seed, as the noise
    added to the rendering afterwards, and the generator left in the same state."""
    from hearth.robot.sim import world_scene
    w = demo_world
    base = w.parking_positions("oven")[0][1]
    T = camera_pose(base, *pan_tilt_to(base, w.T_world("oven")[:3, 3]))
    scene = world_scene(w)
    for k in (K, K.scaled(0.25)):
        r1, r2 = np.random.default_rng(3), np.random.default_rng(3)
        frame = render_view(w, k, T, r1, scene=scene)
        noisy = add_kinect_noise(scene.render(k, T), r2)
        assert np.array_equal(frame.depth, noisy.depth)
        assert np.array_equal(frame.color, noisy.color)
        assert np.array_equal(frame.labels, noisy.labels)
        assert r1.random() == r2.random()


def test_the_same_frame_whatever_the_number_of_bands(demo_world, monkeypatch):
    """Rendering and noise run in row bands, one per core: a seed gives the same frame on
    any machine."""
    from hearth.perception import bands
    from hearth.robot.sim import world_scene
    w = demo_world
    base = w.parking_positions("oven")[0][1]
    T = camera_pose(base, *pan_tilt_to(base, w.T_world("oven")[:3, 3]))
    scene = world_scene(w)
    frames = []
    for n in (1, 2, 3, 7):
        monkeypatch.setattr(bands, "BANDS", n)
        frames.append(render_view(w, K, T, np.random.default_rng(4), scene=scene))
    for f in frames[1:]:
        assert np.array_equal(f.depth, frames[0].depth)
        assert np.array_equal(f.color, frames[0].color)
        assert np.array_equal(f.labels, frames[0].labels)


def test_a_one_row_frame_gets_noise_too():
    m = o3d.geometry.TriangleMesh.create_box(8.0, 8.0, 0.01)
    m.translate((-4.0, -4.0, 1.0))
    row = Intrinsics(500.0, 500.0, 1.0, 0.0, 3, 1)
    clean = Scene([LabelledMesh("wall", "wall", m, (0.8, 0.8, 0.8))]).render(row, np.eye(4))
    noisy = add_kinect_noise(clean, np.random.default_rng(0))
    assert noisy.depth.shape == (1, 3) and noisy.color.shape == (1, 3, 3)
    assert np.all(np.abs(noisy.depth[noisy.depth > 0] - 1.0) < 0.05)


def test_head_looks_exactly_at_the_point_and_camera_is_1_3_m_high():
    base = (1.0, 2.0, 0.5)
    T0 = camera_pose(base, 0.0, 0.0)
    assert T0[2, 3] == pytest.approx(1.30)
    target = np.array([3.0, 2.5, 0.7])
    pan, tilt = pan_tilt_to(base, target)
    T = camera_pose(base, pan, tilt)
    ray = (target - T[:3, 3]) / np.linalg.norm(target - T[:3, 3])
    assert ray @ T[:3, 2] == pytest.approx(1.0, abs=1e-9)
    assert tilt > 0                           # looking down at a table


def test_render_view_of_the_demo_oven_shows_its_knobs(demo_world):
    w = demo_world
    base = w.parking_positions("oven")[0][1]
    knob = w.T_world("oven_knob_2")[:3, 3]
    T = camera_pose(base, *pan_tilt_to(base, knob))
    frame = render_view(w, K, T, np.random.default_rng(0))
    assert frame.color.shape == (480, 640, 3) and frame.color.dtype == np.uint8
    assert frame.depth.dtype == np.float32
    assert frame.mask(["oven_knob_2"]).sum() > 100
    assert np.array_equal(frame.T_world_camera, T)


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-5, 5), y=st.floats(-5, 5), yaw=st.floats(-3.1, 3.1),
       dist=st.floats(0.5, 4.0), bearing=st.floats(-2.9, 2.9), z=st.floats(0.0, 1.6))
def test_pan_tilt_to_puts_any_reachable_point_on_the_optical_axis(x, y, yaw, dist, bearing, z):
    base = (x, y, yaw)
    target = np.array([x + dist * math.cos(yaw + bearing), y + dist * math.sin(yaw + bearing), z])
    pan, tilt = pan_tilt_to(base, target)
    T = camera_pose(base, pan, tilt)
    ray = target - T[:3, 3]
    if np.linalg.norm(ray) < 1e-6:
        return
    # Within the head's limits the aim is exact (the limits clip only extreme targets).
    if math.radians(-45) < tilt < math.radians(75) and abs(pan) < math.radians(170):
        assert ray @ T[:3, 2] / np.linalg.norm(ray) == pytest.approx(1.0, abs=1e-9)
