"""hearth.worldmodel.frames: one room-membership test, planar transforms, joints and pose coercion,
honouring turned and offset rooms."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from hearth.worldmodel import frames
from hearth.worldmodel.nodes import Joint, Room
from hearth.worldmodel.pose import Pose

angles = st.floats(-math.pi, math.pi, allow_nan=False)
coords = st.floats(-20, 20, allow_nan=False)


def _room(x=0.0, y=0.0, yaw=0.0, bounds=(0.0, 0.0, 4.0, 3.0), rid="r"):
    return Room(rid, rid, pose=Pose(x, y, 0, 0, 0, yaw), bounds=bounds)


def test_a_point_inside_a_turned_room_is_in_it_and_its_mirror_is_not():
    room = _room(10.0, 5.0, math.pi / 2)   # bounds x 0..4 along world +y, y 0..3 along world -x
    assert frames.room_contains(room, 10.0 - 1.5, 5.0 + 2.0)
    assert not frames.room_contains(room, 10.0 + 1.5, 5.0 + 2.0)
    assert frames.room_at([room], 8.5, 7.0) is room
    assert frames.room_at([room], 11.5, 7.0) is None


def test_room_corners_are_the_bounds_in_the_world():
    room = _room(1.0, 2.0, math.pi / 2)
    c = frames.room_corners(room)
    np.testing.assert_allclose(c, [[1, 2], [1, 6], [-2, 6], [-2, 2]], atol=1e-9)


def test_a_room_without_bounds_holds_nothing():
    assert not frames.room_contains(Room("x", "x"), 0.0, 0.0)


@given(coords, coords, angles, st.floats(0.01, 0.99), st.floats(0.01, 0.99))
def test_room_membership_is_invariant_under_the_rooms_pose(x, y, yaw, fu, fv):
    room = _room(x, y, yaw)
    x0, y0, x1, y1 = room.bounds
    local = np.array([x0 + fu * (x1 - x0), y0 + fv * (y1 - y0)])
    world = frames.transform_xy(room.pose.matrix(), local)[0]
    assert frames.room_contains(room, *world)
    np.testing.assert_allclose(frames.to_room(room, world), local, atol=1e-7)
    outside = frames.transform_xy(room.pose.matrix(), local + [x1 - x0 + 0.5, 0.0])[0]
    assert not frames.room_contains(room, *outside)


@given(coords, coords, angles)
def test_planar_T_and_planar_of_round_trip(x, y, yaw):
    px, py, pyaw = frames.planar_of(frames.planar_T(x, y, yaw))
    assert px == pytest.approx(x) and py == pytest.approx(y)
    assert math.isclose(math.cos(pyaw - yaw), 1.0, abs_tol=1e-9)


@given(coords, coords, angles)
def test_planar_about_keeps_its_centre_when_it_only_turns(cx, cy, yaw):
    T = frames.planar_about(0.0, 0.0, yaw, (cx, cy))
    np.testing.assert_allclose(frames.transform_xy(T, [(cx, cy)])[0], (cx, cy), atol=1e-6)


def test_pose_coercion_takes_every_documented_form():
    p = Pose(1, 2, 0.5, 0.1, 0.2, 0.3)
    assert frames.as_pose(p) is p
    assert frames.as_pose(p.as_dict()) == p
    assert frames.as_pose(list(p.as_tuple())) == p
    assert frames.as_pose((1, 2, 0.3)) == Pose.planar(1, 2, 0.3)
    q = frames.as_pose(p.matrix())
    np.testing.assert_allclose(q.as_tuple(), p.as_tuple(), atol=1e-9)
    np.testing.assert_allclose(frames.as_matrix(p), p.matrix())
    base = frames.as_base_pose(p.matrix())
    assert (base.z, base.roll, base.pitch) == (0.0, 0.0, 0.0)
    assert base.x == pytest.approx(1) and base.y == pytest.approx(2)
    for bad in ("north", {"x": 1}, (1, 2), [[1, 2], [3, 4]]):
        with pytest.raises(ValueError, match="not a pose"):
            frames.as_pose(bad)


def test_joint_transforms_turn_and_slide_along_their_axis():
    door = Joint("revolute", Pose(1, 0, 0), axis=(0, 0, 1), lower=0, upper=2, state=math.pi / 2)
    T = frames.joint_T(door)
    np.testing.assert_allclose(T[:3, 3], (1, 0, 0), atol=1e-12)
    np.testing.assert_allclose(T[:3, 0], (0, 1, 0), atol=1e-12)
    drawer = Joint("prismatic", Pose(0, 0, 1), axis=(2, 0, 0), lower=0, upper=1, state=0.0)
    np.testing.assert_allclose(frames.joint_T(drawer, 0.25)[:3, 3], (0.25, 0, 1), atol=1e-12)
