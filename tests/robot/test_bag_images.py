"""Images as robots record them, read back: depth registered to the colour camera, and
compressed colour and depth decoded (hearth.robot.rosbag, hearth.perception.camera)."""
from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hearth.robot.rosbag import decode_compressed
from hearth.perception.camera import Intrinsics, depth_to_points, register_depth


def _plane(K: Intrinsics, z: float) -> np.ndarray:
    return np.full((K.height, K.width), z, dtype=np.float32)


def test_registering_with_the_same_camera_changes_nothing():
    K = Intrinsics.kinect(64, 48)
    depth = _plane(K, 1.2)
    depth[10:20, 5:30] = 0.8                                 # a box in front
    assert np.allclose(register_depth(depth, K, K, np.eye(4)), depth)


@settings(max_examples=25, deadline=None)
@given(dx=st.floats(-0.03, 0.03), scale=st.floats(0.7, 1.0), z=st.floats(0.6, 3.0))
def test_a_wall_seen_by_a_shifted_coarser_depth_camera_registers_without_holes(dx, scale, z):
    """A fronto-parallel wall: every colour pixel the depth camera covers gets the wall's
    distance (the depth pixels' footprints tile the colour image, as librealsense's align)."""
    Kc = Intrinsics.kinect(64, 48)
    Kd = Intrinsics(Kc.fx * scale, Kc.fy * scale, Kc.cx + 1.0, Kc.cy - 1.0, 64, 48)
    T_color_depth = np.eye(4)
    T_color_depth[0, 3] = dx
    out = register_depth(_plane(Kd, z), Kd, Kc, T_color_depth)
    # The colour pixels inside the depth camera's field of view, with a pixel's margin.
    pts = depth_to_points(_plane(Kd, z), Kd) + [dx, 0, 0]
    u = pts[:, 0] * Kc.fx / z + Kc.cx
    v = pts[:, 1] * Kc.fy / z + Kc.cy
    inside = np.zeros((48, 64), bool)
    inside[max(int(np.ceil(v.min())) + 1, 0):min(int(v.max()) - 1, 48),
           max(int(np.ceil(u.min())) + 1, 0):min(int(u.max()) - 1, 64)] = True
    assert np.allclose(out[inside], z, atol=1e-5)


def test_the_nearest_surface_wins_a_pixel():
    K = Intrinsics.kinect(64, 48)
    depth = _plane(K, 2.0)
    depth[20:28, 20:28] = 1.0
    T = np.eye(4)
    T[0, 3] = 0.05                                          # the box shifts over the wall
    out = register_depth(depth, K, K, T)
    # Column 26: the box (shifted 2.6 px) and the wall behind it (1.3 px) both land there.
    assert out[24, 26] == np.float32(1.0) and out[24, 50] == np.float32(2.0)


def _msg(fmt: str, data: bytes):
    return SimpleNamespace(format=fmt, data=np.frombuffer(data, dtype=np.uint8))


def test_compressed_colour_and_depth_decode_as_published():
    rgb = np.zeros((6, 8, 3), np.uint8)
    rgb[..., 0] = 200                                        # red
    ok, png = cv2.imencode(".png", rgb[..., ::-1])
    assert np.array_equal(decode_compressed(_msg("rgb8; png compressed bgr8", png.tobytes()),
                                            "colour"), rgb)
    mm = np.arange(48, dtype=np.uint16).reshape(6, 8) * 100
    ok, depth_png = cv2.imencode(".png", mm)
    header = np.array([0], "<i4").tobytes() + np.array([0.0, 0.0], "<f4").tobytes()
    z = decode_compressed(_msg("16UC1; compressedDepth png", header + depth_png.tobytes()),
                          "depth")
    assert np.allclose(z, mm / 1000.0)
    # 32FC1: quantised inverse depth, depth = A / (v - B), v = 0 no reading.
    a, b = 100.0, -10.0
    metres = np.array([[0.0, 1.0, 2.5]], np.float32)
    v = np.where(metres > 0, a / np.where(metres > 0, metres, 1) + b, 0).astype(np.uint16)
    ok, inv_png = cv2.imencode(".png", v)
    header = np.array([0], "<i4").tobytes() + np.array([a, b], "<f4").tobytes()
    z = decode_compressed(_msg("32FC1; compressedDepth png", header + inv_png.tobytes()), "depth")
    assert np.allclose(z, metres, atol=1e-6)
