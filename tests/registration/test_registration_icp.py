"""Each ICP variant recovers a known transform on synthetic clouds; too little overlap fails."""
from __future__ import annotations

import math

import numpy as np
import open3d as o3d
import pytest

from hearth.perception.registration import (
    ICPConfig, JointAxis, RegistrationFailed, planar_params, register_6dof, register_joint,
    register_planar, transform,
)


def _planar(x, y, yaw):
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = (x, y)
    return T


def _furniture(n=6000, seed=0):
    """Surface samples (points, normals) of a corner with a cabinet and a post: enough
    structure to pin down all six degrees of freedom."""
    mesh = o3d.geometry.TriangleMesh()
    for size, at in [((2.0, 0.05, 1.5), (0, 1.0, 0)), ((0.05, 2.0, 1.5), (-1.0, 0, 0)),
                     ((2.0, 2.0, 0.05), (0, 0, -0.05)), ((0.5, 0.6, 0.8), (0.2, 0.3, 0))]:
        b = o3d.geometry.TriangleMesh.create_box(*size)
        b.translate(np.array(at) - np.array([size[0] / 2, size[1] / 2, 0]))
        mesh += b
    cyl = o3d.geometry.TriangleMesh.create_cylinder(0.05, 1.0)
    cyl.translate((0.6, -0.4, 0.5))
    mesh += cyl
    mesh.compute_triangle_normals()
    o3d.utility.random.seed(seed)
    pc = mesh.sample_points_uniformly(n, use_triangle_normal=True)
    return np.asarray(pc.points), np.asarray(pc.normals)


@pytest.fixture(scope="module")
def clouds():
    tgt, tn = _furniture(60000, seed=1)
    src, _ = _furniture(6000, seed=2)
    rng = np.random.default_rng(0)
    return tgt, tn, src + rng.normal(0, 0.001, src.shape)


def test_6dof_icp_recovers_a_known_transform(clouds):
    tgt, tn, src = clouds
    T_true = _planar(0.04, -0.03, math.radians(3))
    T_true[:3, :3] = T_true[:3, :3] @ o3d.geometry.get_rotation_matrix_from_xyz((0.02, -0.015, 0))
    T_true[2, 3] = 0.02
    moved = transform(np.linalg.inv(T_true), src)      # where the sensor saw it
    res = register_6dof(moved, tgt, tn, cfg=ICPConfig(voxel=0.015))
    assert np.linalg.norm(res.T[:3, 3] - T_true[:3, 3]) < 0.003
    assert np.allclose(res.T[:3, :3], T_true[:3, :3], atol=3e-3)
    assert res.fitness > 0.8 and res.residual < 0.004


def test_planar_icp_recovers_x_y_yaw_and_leaves_z_alone(clouds):
    tgt, tn, src = clouds
    T_true = _planar(0.06, -0.05, math.radians(5))
    moved = transform(np.linalg.inv(T_true), src)
    res = register_planar(moved, tgt, tn, cfg=ICPConfig(voxel=0.015))
    x, y, yaw = planar_params(res.T)
    assert abs(x - 0.06) < 0.003 and abs(y + 0.05) < 0.003
    assert abs(math.degrees(yaw) - 5) < 0.15
    assert res.T[2, 3] == 0 and np.allclose(res.T[2, :3], [0, 0, 1])
    assert res.converged


def _door(n=3000, seed=0):
    """A 0.4 x 0.02 x 0.7 door leaf in its part frame (hinge along z at the origin, leaf along
    -y) with a bar handle, as surface samples."""
    leaf = o3d.geometry.TriangleMesh.create_box(0.02, 0.4, 0.7)
    leaf.translate((-0.01, -0.4, 0))
    bar = o3d.geometry.TriangleMesh.create_cylinder(0.008, 0.16)
    bar.translate((0.045, -0.35, 0.4))
    mesh = leaf + bar
    mesh.compute_triangle_normals()
    o3d.utility.random.seed(seed)
    pc = mesh.sample_points_uniformly(n, use_triangle_normal=True)
    return np.asarray(pc.points), np.asarray(pc.normals)


def test_joint_icp_recovers_a_hinge_angle_within_limits():
    T_world_joint = _planar(1.0, 2.0, 0.3)
    joint = JointAxis(T_world_joint, (0, 0, 1), "revolute", 0.0, math.radians(100))
    mp, mn = _door(seed=1)
    obs, _ = _door(seed=2)
    front = obs[:, 0] > 0          # the camera sees the front of the leaf only
    truth = math.radians(35)
    observed = transform(joint.T_world_part(truth), obs[front])
    keep = mn[:, 0] > -0.5
    res = register_joint(mp[keep], mn[keep], observed, joint, truth - math.radians(8),
                         ICPConfig(voxel=0, gates=(0.1, 0.03, 0.01), iterations=(15, 10, 10),
                                   min_fitness=0.2))
    assert abs(math.degrees(res.value) - 35) < 0.2
    assert joint.lower <= res.value <= joint.upper


def test_joint_icp_recovers_a_slide_and_clamps_at_the_limit():
    T_world_joint = _planar(0.5, 0.5, 0.0)
    joint = JointAxis(T_world_joint, (1, 0, 0), "prismatic", 0.0, 0.3)
    mp, mn = _furniture(4000, seed=3)
    mp, mn = mp * 0.3, mn                      # a small structured part
    obs, _ = _furniture(4000, seed=4)
    cfg = ICPConfig(voxel=0, gates=(0.08, 0.02, 0.008), iterations=(15, 10, 10))
    res = register_joint(mp, mn, transform(joint.T_world_part(0.12), obs * 0.3), joint, 0.08, cfg)
    assert abs(res.value - 0.12) < 0.002
    # The part pulled beyond its travel stops at the limit instead of leaving it.
    res = register_joint(mp, mn, transform(_planar(0.5 + 0.34, 0.5, 0), obs * 0.3), joint, 0.25,
                         ICPConfig(voxel=0, gates=(0.1, 0.05), iterations=(20, 10),
                                   min_fitness=0.0, min_points=1))
    assert 0.29 < res.value <= 0.3


def test_too_little_overlap_fails_explicitly(clouds):
    tgt, tn, src = clouds
    far = src + np.array([5.0, 0, 0])
    with pytest.raises(RegistrationFailed, match="too little overlap"):
        register_planar(far, tgt, tn)
    with pytest.raises(RegistrationFailed, match="too little overlap"):
        register_6dof(far, tgt, tn)
    with pytest.raises(RegistrationFailed, match="only 3 points"):
        register_planar(src[:3], tgt, tn)


# -- the shared ICP pieces ------------------------------------------------------------------------

from hypothesis import given, settings, strategies as st  # noqa: E402

from hearth.perception.registration import (  # noqa: E402
    DepthAgreement, depth_agreement, normal_equations, planar_delta, planar_plane_jacobian,
    planar_point_jacobian, planar_point_step, solve,
)


@settings(max_examples=50, deadline=None)
@given(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-math.pi, math.pi))
def test_the_planar_point_step_recovers_any_planar_motion(dx, dy, yaw):
    rng = np.random.default_rng(3)
    src = rng.uniform(-0.1, 0.1, (40, 3))
    dst = transform(_planar(dx, dy, yaw), src)
    step, c = planar_point_step(src, dst)
    assert np.allclose(transform(planar_delta(step, c), src)[:, :2], dst[:, :2], atol=1e-9)


def test_the_damped_solve_leaves_a_direction_nothing_constrains_where_it_is():
    """Points on one flat wall facing x: the normal equations say nothing about y; the damped
    step moves x only, and a small motion's Gauss-Newton step is the closed-form one."""
    rng = np.random.default_rng(0)
    p = np.c_[np.zeros(200), rng.uniform(-1, 1, 200), rng.uniform(0, 2, 200)]
    n = np.tile([1.0, 0.0, 0.0], (200, 1))
    H, g = normal_equations(planar_plane_jacobian(n, p)[:, :2], np.full(200, 0.03), np.ones(200))
    x = solve(H, g)
    assert x[0] == pytest.approx(-0.03, abs=1e-6) and abs(x[1]) < 1e-9
    assert solve(np.zeros((3, 3)), np.zeros(3)) is None
    src = rng.uniform(-0.1, 0.1, (50, 3))
    dst = transform(_planar(0.001, -0.002, 0.002), src)
    c = src.mean(axis=0)
    e = src - dst
    H, g = normal_equations(planar_point_jacobian(src - c), np.r_[e[:, 0], e[:, 1]], np.ones(100))
    closed, _ = planar_point_step(src, dst)
    assert np.allclose(solve(H, g), closed, atol=1e-5)


def test_one_depth_agreement_scores_candidate_corrections_and_placements():
    """DepthAgreement (candidate corrections of a registration) is depth_agreement (placements
    of model points, as the coarse joint search uses it) after moving the model."""
    from hearth.perception.camera import Intrinsics
    K = Intrinsics.kinect(160, 120)
    depth = np.full((120, 160), 2.0, dtype=np.float32)      # a wall 2 m ahead
    pts = np.c_[np.random.default_rng(1).uniform(-0.5, 0.5, (300, 2)), np.full(300, 2.0)]
    on_wall = depth_agreement(pts[None], depth, K)
    nearer = depth_agreement((pts - [0, 0, 0.5])[None], depth, K)
    behind = depth_agreement((pts + [0, 0, 0.5])[None], depth, K)
    assert on_wall[0] == 300
    assert nearer[0] == -300            # the camera sees the wall through where they would be
    assert behind[0] == 0               # hidden behind the wall: no evidence either way
    half = depth_agreement(pts[None], depth, K, mask=(np.arange(300) < 150)[None])
    assert half[0] == 150
    scorer = DepthAgreement(pts, depth, K, np.eye(4))
    toward = np.eye(4)
    toward[2, 3] = 0.5                  # a correction that puts the model 0.5 m nearer
    assert list(scorer([np.eye(4), toward])) == [300, -300]
