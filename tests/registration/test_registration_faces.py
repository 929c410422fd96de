"""Faces from the part's geometry (a box however it is turned, a mesh) and handles found on
them in rendered views of the demo cupboard."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.benchmarks.registration import simulate_depth
from hearth.perception.articulated import part_face, register_articulated, register_handles
from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.handles import rotation_error_deg
from hearth.worldmodel.homegen_geometry import box_mesh, merge, ply_bytes
from hearth.worldmodel.nodes import Model, Visual
from hearth.worldmodel.pose import Pose

K = Intrinsics.kinect()
DOOR, HANDLE = "cupboard_door_left", "cupboard_handle_left"


def _camera(world, lateral=0.2):
    To = world.T_world("cupboard")
    eye = (To @ np.array([1.5, lateral, 0, 1]))[:3]
    eye[2] = 1.4
    target = (To @ np.array([0.15, 0, 0, 1]))[:3]
    target[2] = 0.5
    return look_at(eye, target)


def _handle_in_view(world, angle_deg=30, seed=7):
    truth = world.copy()
    truth.set_joint_state(DOOR, math.radians(angle_deg))
    Tc = _camera(world)
    depth = simulate_depth(truth, K, Tc, np.random.default_rng(seed))
    reg = register_articulated(world, "cupboard", depth, K, Tc)
    est = register_handles(world, reg, Tc)[HANDLE]
    assert not isinstance(est, Exception), est
    return est, truth


def _mesh_door(world, tmp_path):
    """The left door as a PLY mesh: a panel with a raised frame (as generated homes draw
    them), its vertices turned a quarter about z and the visual's pose turning them back, so
    nothing about the mesh's own axes says where its face is."""
    part = world.get(DOOR)
    box = part.model.visuals[0]
    sx, sy, sz = box.size
    c = np.array([box.pose.x, box.pose.y, box.pose.z])
    r, b = 0.008, 0.05
    pieces = [box_mesh(c, (sx, sy, sz)),
              box_mesh(c + (sx / 2 + r / 2, 0, sz / 2 - b / 2), (r, sy, b)),
              box_mesh(c + (sx / 2 + r / 2, 0, -sz / 2 + b / 2), (r, sy, b)),
              box_mesh(c + (sx / 2 + r / 2, sy / 2 - b / 2, 0), (r, b, sz - 2 * b)),
              box_mesh(c + (sx / 2 + r / 2, -sy / 2 + b / 2, 0), (r, b, sz - 2 * b))]
    mesh = merge(*pieces)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])   # +90 deg about z
    turned = (mesh[0] @ R.T, mesh[1])
    (tmp_path / "door.ply").write_bytes(ply_bytes(turned))
    part.model = Model([Visual("mesh", Pose(0, 0, 0, 0, 0, -math.pi / 2), file="door.ply",
                               color=box.color, name="face")])
    world.base_dir = tmp_path
    return world


def test_the_face_of_a_turned_box_door_faces_out_of_the_cupboard(demo_world):
    part = demo_world.get(DOOR)
    box = part.model.visuals[0]
    sx, sy, sz = box.size
    # the same box described turned a quarter about z: its thin axis is now its own y
    part.model = Model([Visual("box", Pose(box.pose.x, box.pose.y, box.pose.z, 0, 0, math.pi / 2),
                               size=(sy, sx, sz), color=box.color, name="face")])
    face = part_face(demo_world, part)
    assert np.allclose(face.T_part_face[:3, 0], (1, 0, 0), atol=1e-9)
    assert face.T_part_face[0, 3] == pytest.approx(box.pose.x + sx / 2)
    assert sorted(face.half_size) == pytest.approx(sorted((sy / 2, sz / 2)))
    est, truth = _handle_in_view(demo_world)
    T = truth.T_world(HANDLE)
    # within the bar for a right reading (10 mm, 2 deg): along the bar the position
    # comes from its ends, a few millimetres at this range
    assert np.linalg.norm(est.T_world_handle[:3, 3] - T[:3, 3]) < 0.010
    assert rotation_error_deg(est.T_world_handle, T) < 1.0


def test_a_handle_on_a_mesh_door_is_found_with_the_normal_from_the_mesh(demo_world, tmp_path):
    world = _mesh_door(demo_world, tmp_path)
    face = part_face(world, world.get(DOOR))
    assert np.allclose(face.T_part_face[:3, 0], (1, 0, 0), atol=1e-6)
    # the outer surface is the raised frame's
    box_x = 0.01
    assert face.T_part_face[0, 3] == pytest.approx(box_x + 0.008, abs=1e-6)
    est, truth = _handle_in_view(world)
    T = truth.T_world(HANDLE)
    assert np.linalg.norm(est.T_world_handle[:3, 3] - T[:3, 3]) < 0.005
    assert rotation_error_deg(est.T_world_handle, T) < 1.0
    n_true = truth.T_world(DOOR)[:3, :3] @ face.T_part_face[:3, 0]
    assert math.degrees(math.acos(min(1.0, float(est.plane_normal @ n_true)))) < 0.5


def test_a_mesh_panel_without_a_handle_faces_away_from_its_parent(demo_world, tmp_path):
    # a side panel: its broad faces look along the part's +-y; outward is away from the
    # cupboard's centre
    part = demo_world.get(DOOR)
    (tmp_path / "panel.ply").write_bytes(ply_bytes(box_mesh((0.0, 0.1, 0.4), (0.3, 0.02, 0.8))))
    part.model = Model([Visual("mesh", file="panel.ply")])
    part.handles = []
    demo_world.base_dir = tmp_path
    face = part_face(demo_world, part)
    centre = np.array([0.0, 0.1, 0.4])
    parent_centre_in_part = np.linalg.inv(part.joint.origin.matrix())[:3, 3]  # roughly
    n = face.T_part_face[:3, 0]
    assert abs(abs(n[1]) - 1) < 1e-9
    assert (centre - parent_centre_in_part) @ n > 0


def test_both_ends_of_a_bar_seen_steeply_from_above_are_seen_to_be_ends(demo_world):
    # 70 cm in front of the cupboard, the camera 1.4 m up: just past the bar's lower end the
    # view meets the bar's own front, past its upper end its end cap; both are passed over
    # and the face behind is found
    To, Th = demo_world.T_world("cupboard"), demo_world.T_world(HANDLE)
    eye = (To @ np.array([0.7, 0.1, 0, 1]))[:3]
    eye[2] = 1.4
    Tc = look_at(eye, Th[:3, 3])
    truth = demo_world.copy()
    truth.set_joint_state(DOOR, math.radians(20))
    for seed in range(4):
        depth = simulate_depth(truth, K, Tc, np.random.default_rng(seed))
        reg = register_articulated(demo_world, "cupboard", depth, K, Tc)
        est = register_handles(demo_world, reg, Tc)[HANDLE]
        assert not isinstance(est, Exception), est
        assert est.ends_seen == 2
        assert not est.prior_used
        T = truth.T_world(HANDLE)
        assert np.linalg.norm(est.T_world_handle[:3, 3] - T[:3, 3]) < 0.010
