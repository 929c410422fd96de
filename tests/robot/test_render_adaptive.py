"""The adaptive ray cast (hearth/perception/render.py ``Scene.cast``) against a ray per pixel: the
same triangle and miss at every pixel, depth within float rounding, on the demo kitchen's
views, a generated home's, a knob panel seen from afar and random boxes (small, thin,
rotated, overlapping)."""
from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from hearth.perception.camera import Intrinsics
from hearth.perception.render import Scene
from hearth.worldmodel.geometry import LabelledMesh

K = Intrinsics.kinect()


def assert_same_cast(scene: Scene, K: Intrinsics, T) -> np.ndarray:
    """Adaptive and full casts of one view agree; returns the full cast's triangles."""
    full = scene.cast(K, T, adaptive=False)
    fast = scene.cast(K, T, adaptive=True)
    assert full.depth.shape == fast.depth.shape == (K.height, K.width)
    np.testing.assert_array_equal(fast.miss, full.miss)
    np.testing.assert_array_equal(fast.triangle, full.triangle)
    np.testing.assert_array_equal(fast.geometry, full.geometry)
    np.testing.assert_array_equal(fast.primitive, full.primitive)
    assert np.all(fast.depth[full.depth == 0] == 0)
    assert float(np.abs(fast.depth - full.depth).max()) < 1e-5
    return full.triangle


def _kitchen(spec: str):
    from hearth.benchmarks import _worlds
    from hearth.benchmarks.robot import _kitchen_views
    from hearth.robot.sim import world_scene
    world = _worlds.load(spec)
    return world, world_scene(world), _kitchen_views(world)


@pytest.mark.parametrize("scale", [1.0, 0.25])
def test_adaptive_cast_equals_full_cast_on_the_demo_kitchen_views(scale):
    _, scene, views = _kitchen("demo")
    k = K if scale == 1.0 else K.scaled(scale)
    for T in views:
        assert_same_cast(scene, k, T)


def test_adaptive_cast_equals_full_cast_on_a_generated_home(tmp_path):
    from hearth.benchmarks.robot import _kitchen_views
    from hearth.robot.sim import world_scene
    from hearth.worldmodel.homegen import generate_home
    world = generate_home(1, mesh_dir=tmp_path)
    scene = world_scene(world)
    for T in _kitchen_views(world):
        assert_same_cast(scene, K, T)
        assert_same_cast(scene, K.scaled(0.5), T)


def test_knob_markers_a_few_pixels_wide_are_cast():
    from hearth.robot.sim import camera_pose, pan_tilt_to
    from hearth.worldmodel.viewing import knob_view_pose
    world, scene, _ = _kitchen("demo")
    oven = next(o.id for r in world.rooms for o in r.objects if world.knobs(o.id))
    centre = np.mean([world.T_world(k.id)[:3, 3] for k in world.knobs(oven)], axis=0)
    base = knob_view_pose(world, oven)
    assert base is not None
    T = camera_pose(base, *pan_tilt_to(base, centre))
    markers = [i for i, n in enumerate(scene.names) if n == "marker"]
    for k, most in ((K, 60), (K.scaled(0.5), 20), (K.scaled(0.25), 4)):
        tri = assert_same_cast(scene, k, T)
        seen = np.count_nonzero(np.isin(scene._tri_labels[tri], markers))
        # Every marker shows, a few pixels each (one or two at 160x120), and the adaptive
        # cast has exactly those.
        assert len(world.knobs(oven)) <= seen <= most * len(world.knobs(oven))


def _box(size, R, t, name="box"):
    m = o3d.geometry.TriangleMesh.create_box(*size)
    m.translate(-np.asarray(size) / 2)
    m.rotate(R, center=(0, 0, 0))
    m.translate(t)
    return LabelledMesh(name, name, m, (0.5, 0.5, 0.5))


@pytest.mark.parametrize("seed", range(6))
def test_adaptive_cast_equals_full_cast_on_random_boxes(seed):
    """Boxes of 3 mm to 1 m, turned any way, overlapping each other and a wall, some with
    faces in one plane (sharp corners, thin boards edge-on, specks between the samples)."""
    rng = np.random.default_rng(seed)
    meshes = [_box((6.0, 6.0, 0.1), np.eye(3), (0.0, 0.0, 4.0), "wall")]
    for i in range(60):
        size = np.exp(rng.uniform(np.log(0.003), np.log(1.0), 3))
        R = o3d.geometry.get_rotation_matrix_from_xyz(rng.uniform(-np.pi, np.pi, 3))
        if i % 4 == 0:
            R = np.eye(3)                     # axis-aligned: faces in one plane with others
        meshes.append(_box(size, R, (rng.uniform(-1.5, 1.5), rng.uniform(-1.2, 1.2),
                                     rng.uniform(0.8, 3.9)), f"b{i}"))
    scene = Scene(meshes)
    for k in (K, K.scaled(0.5), K.scaled(0.25)):
        for yaw in (0.0, 0.3):
            T = np.eye(4)
            T[:3, :3] = o3d.geometry.get_rotation_matrix_from_xyz((0.1, yaw, 0.05))
            assert_same_cast(scene, k, T)


def test_a_speck_between_the_samples_is_cast():
    """A 1 cm cube 2.5 m away (2 pixels) in front of a wall, moved across a block."""
    for dx in np.linspace(0.0, 0.02, 5):
        scene = Scene([_box((6.0, 6.0, 0.1), np.eye(3), (0, 0, 4.0), "wall"),
                       _box((0.01, 0.01, 0.01), np.eye(3), (0.013 + dx, 0.007, 2.5), "speck")])
        tri = assert_same_cast(scene, K, np.eye(4))
        assert np.count_nonzero(scene._tri_labels[tri] == 1) > 0


def test_faces_in_one_plane_on_a_turned_cooker_cast_only_where_they_overlap():
    """A cooker turned 45 degrees whose hob's top lies in the plane of the body's top: which
    of the two a ray there hits is rounding, so the overlap is cast at every pixel, but only
    the overlap (its box in world axes covered the body's front below it: home 1's cooker
    cast two thirds of the view)."""
    from hearth.perception.render import _AdaptiveCast
    turn = o3d.geometry.get_rotation_matrix_from_xyz((0.0, 0.0, np.pi / 4))
    scene = Scene([_box((6.0, 6.0, 0.1), np.eye(3), (0.0, 0.0, -0.05), "floor"),
                   _box((0.6, 0.6, 0.9), turn, (0.0, 0.0, 0.45), "body"),
                   _box((0.5, 0.5, 0.02), turn, (0.0, 0.0, 0.89), "hob")])
    # From 0.9 m in front of the cooker's corner, 1.3 m up, looking down at it (camera z
    # forward, y down).
    c = np.array([-0.9, 0.0, 1.3])
    z = np.array([0.0, 0.0, 0.75]) - c
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = c
    tri = assert_same_cast(scene, K, T).reshape(K.height, K.width)
    run = _AdaptiveCast(scene, K, T[:3, :3], c, 8.0)
    run.run()
    cast = run.known.reshape(K.height, K.width)
    normal_z = scene._tri_normals[tri, 2]
    front = (scene._tri_labels[tri] == 1) & (np.abs(normal_z) < 0.5)     # the body's sides
    assert front.mean() > 0.2
    # Rays through the body's sides: the grid and the outline's corners, not a cast of all.
    assert cast[front].mean() < 0.2


@pytest.mark.parametrize("view", [0, 4])
def test_render_without_the_adaptive_cast_is_the_reference(view):
    _, scene, views = _kitchen("demo")
    a = scene.render(K, views[view])
    scene.adaptive = False
    try:
        b = scene.render(K, views[view])
    finally:
        scene.adaptive = True
    np.testing.assert_array_equal(a.labels, b.labels)
    assert float(np.abs(a.depth - b.depth).max()) < 1e-5
    assert float(np.abs(a.incidence - b.incidence).max()) < 1e-5
    # The colour's view-dependent term comes from the depth: a depth one float32 step off
    # can turn a channel's rounding (measured: 0 to 7 pixels of 307,200 a view, by 1).
    off = np.abs(a.color.astype(int) - b.color.astype(int))
    assert off.max() <= 1 and np.count_nonzero(off) < 1e-4 * off.size
