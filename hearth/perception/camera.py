"""Pinhole camera model (OpenCV convention: x right, y down, z forward, pixels).

``T_world_camera`` maps camera-frame points into the world frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for a ``width`` x ``height`` image."""
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @staticmethod
    def kinect(width: int = 640, height: int = 480) -> "Intrinsics":
        """A Kinect-class RGB-D camera (about 58 x 45 degrees field of view at 640 x 480)."""
        s = width / 640.0
        return Intrinsics(525.0 * s, 525.0 * s, (width - 1) / 2.0, (height - 1) / 2.0, width, height)

    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])

    def scaled(self, factor: float) -> "Intrinsics":
        """The same camera at ``factor`` times the resolution (0.5: half width and height)."""
        w, h = int(round(self.width * factor)), int(round(self.height * factor))
        return Intrinsics(self.fx * factor, self.fy * factor, (self.cx + 0.5) * factor - 0.5,
                          (self.cy + 0.5) * factor - 0.5, w, h)

    def as_dict(self) -> dict:
        return dict(fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, width=self.width,
                    height=self.height)

    @staticmethod
    def from_dict(d: dict) -> "Intrinsics":
        return Intrinsics(float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]),
                          int(d["width"]), int(d["height"]))


def pixel_rays(K: Intrinsics) -> np.ndarray:
    """(H, W, 3) ray directions in the camera frame with z = 1 for every pixel centre."""
    u, v = np.meshgrid(np.arange(K.width, dtype=np.float64), np.arange(K.height, dtype=np.float64))
    return np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u)], axis=-1)


def depth_to_points(depth: np.ndarray, K: Intrinsics, mask: np.ndarray | None = None,
                    stride: int = 1) -> np.ndarray:
    """(N, 3) camera-frame points from a depth image in metres (0 or NaN = no reading).

    ``mask`` selects pixels; ``stride`` keeps every stride-th row and column.
    """
    d = depth[::stride, ::stride]
    v, u = np.mgrid[0:depth.shape[0]:stride, 0:depth.shape[1]:stride]
    ok = np.isfinite(d) & (d > 0)
    if mask is not None:
        ok &= mask[::stride, ::stride]
    z = d[ok]
    x = (u[ok] - K.cx) * z / K.fx
    y = (v[ok] - K.cy) * z / K.fy
    return np.stack([x, y, z], axis=1)


def project(points_camera: np.ndarray, K: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (N, 2) of camera-frame points and a mask of those in front."""
    p = np.asarray(points_camera, dtype=float)
    front = p[:, 2] > 1e-6
    z = np.where(front, p[:, 2], 1.0)
    uv = np.stack([K.fx * p[:, 0] / z + K.cx, K.fy * p[:, 1] / z + K.cy], axis=1)
    return uv, front


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``T_world_camera`` for a camera at ``eye`` looking at ``target`` (OpenCV axes)."""
    eye, target, up = (np.asarray(a, dtype=float) for a in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, (0.0, 1.0, 0.0))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


def register_depth(depth_depth: np.ndarray, K_depth: Intrinsics, K_color: Intrinsics,
                   T_color_depth: np.ndarray) -> np.ndarray:
    """A depth image (metres, 0 = no reading) of the depth camera, as the colour camera sees
    it: each reading back-projected with ``K_depth``, moved into the colour frame by
    ``T_color_depth`` and projected with ``K_color`` into a ``K_color``-sized image. As a
    RealSense driver's aligned_depth_to_color does (librealsense's align), a depth pixel
    covers the colour pixels whose centres lie between the projections of its two corners,
    so a depth camera of coarser pixels leaves no holes; the nearest reading wins a pixel. Pixels no reading
    reaches are 0."""
    d = np.asarray(depth_depth, dtype=np.float64)
    v, u = np.nonzero(np.isfinite(d) & (d > 0))
    out = np.full(K_color.height * K_color.width, np.inf, dtype=np.float32)
    if not len(u):
        return np.zeros((K_color.height, K_color.width), dtype=np.float32)
    z = d[v, u]
    T = np.asarray(T_color_depth, dtype=float)
    corners = []
    for off in (-0.5, 0.5):
        p = np.stack([(u + off - K_depth.cx) * z / K_depth.fx,
                      (v + off - K_depth.cy) * z / K_depth.fy, z], axis=1)
        pc = p @ T[:3, :3].T + T[:3, 3]
        uv, front = project(pc, K_color)
        corners.append((uv, front, pc[:, 2]))
    (a, fa, za), (b, fb, zb) = corners
    # The colour pixels whose centres lie in the footprint [low, high): footprints of
    # neighbouring depth pixels share their corners, so they tile without gaps or overlaps.
    x0 = np.ceil(np.minimum(a[:, 0], b[:, 0])).astype(np.int64)
    x1 = np.ceil(np.maximum(a[:, 0], b[:, 0])).astype(np.int64) - 1
    y0 = np.ceil(np.minimum(a[:, 1], b[:, 1])).astype(np.int64)
    y1 = np.ceil(np.maximum(a[:, 1], b[:, 1])).astype(np.int64) - 1
    zc = (0.5 * (za + zb)).astype(np.float32)
    ok = fa & fb & (x1 >= 0) & (x0 < K_color.width) & (y1 >= 0) & (y0 < K_color.height)
    # A footprint is a few colour pixels wide at most: wider ones (a reading seen edge-on, or
    # a far smaller colour pixel) are clipped to 4 so that one reading cannot paint a wall.
    span = 4
    x0, y0, zc = x0[ok], y0[ok], zc[ok]
    x1 = np.minimum(x1[ok], x0 + span - 1)
    y1 = np.minimum(y1[ok], y0 + span - 1)
    for dy in range(span):
        for dx in range(span):
            x, y = x0 + dx, y0 + dy
            m = (x <= x1) & (y <= y1) & (x >= 0) & (x < K_color.width) & (y >= 0) & \
                (y < K_color.height)
            np.minimum.at(out, y[m] * K_color.width + x[m], zc[m])
    out[~np.isfinite(out)] = 0.0
    return out.reshape(K_color.height, K_color.width)
