"""Registration on rendered views of the demo home with Kinect-class noise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.benchmarks.registration import T_BASE_CAMERA, planar, simulate_depth
from hearth.perception.articulated import register_articulated, register_base, register_handles
from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.errors import PerceptionError
from hearth.perception.handles import rotation_error_deg
from hearth.perception.localisation import refine_localisation

K = Intrinsics.kinect()


def _truth(world, states):
    truth = world.copy()
    for pid, v in states.items():
        truth.set_joint_state(pid, v)
    return truth


def _front_camera(world, oid, lateral=0.1, distance=1.5):
    To = world.T_world(oid)
    eye = (To @ np.array([distance, lateral, 0, 1]))[:3]
    eye[2] = 1.4
    target = (To @ np.array([0.15, 0, 0, 1]))[:3]
    target[2] = 0.5
    return look_at(eye, target)


def _registered(world, oid, states, seed, lateral=0.1):
    """``world``'s object ``oid`` registered in a depth image of it with its parts at
    ``states``, seen from the front: ``(truth, T_world_camera, registration)``."""
    truth = _truth(world, states)
    Tc = _front_camera(world, oid, lateral)
    depth = simulate_depth(truth, K, Tc, np.random.default_rng(seed))
    return truth, Tc, register_articulated(world, oid, depth, K, Tc)


@pytest.mark.parametrize("left,right", [(0, 35), (35, 90), (90, 0)])
def test_cupboard_doors_read_at_0_35_and_90_degrees(demo_world, left, right):
    states = {"cupboard_door_left": math.radians(left), "cupboard_door_right": math.radians(right)}
    truth, _, reg = _registered(demo_world, "cupboard", states, left + right)
    for pid, want in (("cupboard_door_left", left), ("cupboard_door_right", right)):
        st = reg.parts[pid]
        assert st.known, st.reason
        assert st.unit == "deg"
        assert abs(st.state - want) < 1.0
        # the part's world pose follows its state
        assert np.allclose(st.T_world_part[:3, 3], truth.T_world(pid)[:3, 3], atol=0.01)
    # the map is not touched by perception
    assert demo_world.get("cupboard_door_left").joint.state == 0.0


def test_a_door_seen_edge_on_is_unknown_not_a_wrong_angle(demo_world):
    # The left door open at 90 degrees stands in the plane y = hinge; a camera in that plane
    # sees only its edge.
    states = {"cupboard_door_left": math.radians(90), "cupboard_door_right": 0.0}
    truth = _truth(demo_world, states)
    To = demo_world.T_world("cupboard")
    hinge = demo_world.get("cupboard_door_left").joint.origin
    eye = (To @ np.array([1.6, hinge.y, 0, 1]))[:3]
    eye[2] = 0.55
    target = (To @ np.array([0.0, hinge.y, 0, 1]))[:3]
    target[2] = 0.55
    Tc = look_at(eye, target)
    depth = simulate_depth(truth, K, Tc, np.random.default_rng(3))
    reg = register_articulated(demo_world, "cupboard", depth, K, Tc)
    st = reg.parts["cupboard_door_left"]
    assert not st.known and st.state is None
    assert "edge-on" in st.reason or "too little" in st.reason


def test_a_drawer_hidden_below_an_open_one_is_unknown(demo_world):
    states = {"drawer_0": 0.0, "drawer_1": 0.22, "drawer_2": 0.1}
    _, _, reg = _registered(demo_world, "drawer_unit", states, 5)
    assert not reg.parts["drawer_0"].known and "hidden" in reg.parts["drawer_0"].reason
    assert abs(reg.parts["drawer_1"].state - 0.22) < 0.005


def test_drawers_read_to_the_millimetre(demo_world):
    states = {"drawer_0": 0.3, "drawer_1": 0.15, "drawer_2": 0.0}
    _, _, reg = _registered(demo_world, "drawer_unit", states, 5)
    for pid, want in states.items():
        assert reg.parts[pid].unit == "m"
        assert abs(reg.parts[pid].state - want) < 0.005


def test_handles_found_within_5_mm_and_1_degree(demo_world):
    states = {"cupboard_door_left": math.radians(20), "cupboard_door_right": math.radians(50)}
    truth, Tc, reg = _registered(demo_world, "cupboard", states, 7, lateral=-0.2)
    hs = register_handles(demo_world, reg, Tc)
    for hid in ("cupboard_handle_left", "cupboard_handle_right"):
        est = hs[hid]
        assert not isinstance(est, Exception), est
        T = truth.T_world(hid)
        assert np.linalg.norm(est.T_world_handle[:3, 3] - T[:3, 3]) < 0.005
        assert rotation_error_deg(est.T_world_handle, T) < 1.0


def test_moved_object_is_registered_back(demo_world):
    from hearth.worldmodel.pose import Pose
    truth = demo_world.copy()
    p = demo_world.get("drawer_unit").pose
    truth.set_pose("drawer_unit", Pose(p.x + 0.03, p.y - 0.02, 0, 0, 0, p.yaw + math.radians(2)))
    Tc = _front_camera(demo_world, "drawer_unit")
    depth = simulate_depth(truth, K, Tc, np.random.default_rng(9))
    reg = register_base(demo_world, "drawer_unit", depth, K, Tc, include_parts=True)
    E = np.linalg.inv(truth.T_world("drawer_unit")) @ reg.T_world_object
    assert np.linalg.norm(E[:3, 3]) < 0.003
    assert reg.base.fitness > 0.3 and reg.base.residual < 0.005


def test_object_out_of_view_fails_with_a_clear_message(demo_world):
    Tc = _front_camera(demo_world, "fridge")
    depth = simulate_depth(demo_world, K, Tc, np.random.default_rng(1))
    with pytest.raises(PerceptionError, match="cupboard"):
        register_base(demo_world, "cupboard", depth, K, Tc)


def test_localisation_corrected_from_12_cm_and_6_degrees(demo_world):
    from hearth.perception.localisation import LocalisationConfig
    To = demo_world.T_world("cupboard")
    p = To @ np.array([1.8, 0.4, 0, 1])
    yaw = math.atan2(To[1, 3] - p[1], To[0, 3] - p[0])
    T_true = planar(p[0], p[1], yaw)
    depth = simulate_depth(demo_world, K, T_true @ T_BASE_CAMERA, np.random.default_rng(11))
    T_bel = planar(p[0] + 0.08, p[1] - 0.09, yaw + math.radians(6))
    fix = refine_localisation(demo_world, depth, K, T_bel @ T_BASE_CAMERA, T_bel)
    E = np.linalg.inv(T_true) @ fix.T_world_base
    assert math.hypot(E[0, 3], E[1, 3]) < 0.01
    assert abs(math.degrees(math.atan2(E[1, 0], E[0, 0]))) < 0.5
    assert fix.ok and "cupboard" in fix.landmarks
    assert fix.quality["residual_mm"] < 5
    # the cupboard's doors and edges pin the pose down in every direction
    # (ring_m: how far the worst probe of the ring and of the weakest direction stood)
    assert not fix.loose and fix.quality["ring_drop"] > 0.05
    assert 0.01 <= fix.quality["ring_m"] <= max(LocalisationConfig().ring_radii)


def test_a_fix_that_slides_along_a_front_is_loose():
    """``_ring_drop``: the depth agreement 3 cm from the fix in 8 directions. Where it hardly
    drops along one of them (a long flat front slides along itself), the fix is loose."""
    from hearth.perception.localisation import LocalisationConfig, _ring_drop
    centre = np.array([2.0, 1.0, 0.5])

    class agreement:
        """A DepthAgreement stand-in: the landmarks' centre moved by each candidate scores
        less with distance, along x by ``along_x_cost`` a metre, along y by 20 a metre; the
        fix and each probe are scored alike (as on the points both see)."""
        def __init__(self, along_x_cost):
            self.cost = along_x_cost

        def __call__(self, Ts):
            d = np.array([T[:3, :3] @ centre + T[:3, 3] - centre for T in Ts])
            return 1000.0 * (1.0 - self.cost * np.abs(d[:, 0]) - 20.0 * np.abs(d[:, 1]))

        def against(self, C, Cs):
            return np.full(len(Cs), self([C])[0]), self(Cs)
    cfg = LocalisationConfig()
    pinned, _ = _ring_drop(np.eye(4), agreement(20.0), centre, cfg)
    sliding, where = _ring_drop(np.eye(4), agreement(0.5), centre, cfg)
    assert pinned > cfg.min_ring_drop > sliding
    assert sliding == pytest.approx(0.5 * 0.03, abs=1e-9)   # 3 cm along x costs 1.5 %
    assert where == 0.03                                     # ... the nearest probe
