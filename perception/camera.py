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
    ``T_color_depth`` and projected with ``K_color`` into a ``K_color``-sized image, the
    nearest reading kept where several land on one pixel (what a RealSense driver's
    aligned_depth_to_color does). Pixels no reading lands on are 0."""
    points_depth = depth_to_points(depth_depth, K_depth)
    out = np.zeros((K_color.height, K_color.width), dtype=np.float32)
    if not len(points_depth):
        return out
    T = np.asarray(T_color_depth, dtype=float)
    points_color = points_depth @ T[:3, :3].T + T[:3, 3]
    uv, front = project(points_color, K_color)
    u = np.rint(uv[:, 0]).astype(np.int64)
    v = np.rint(uv[:, 1]).astype(np.int64)
    ok = front & (u >= 0) & (u < K_color.width) & (v >= 0) & (v < K_color.height)
    z = points_color[ok, 2].astype(np.float32)
    idx = v[ok] * K_color.width + u[ok]
    flat = np.full(out.size, np.inf, dtype=np.float32)
    np.minimum.at(flat, idx, z)                    # the nearest surface wins a pixel
    flat[~np.isfinite(flat)] = 0.0
    return flat.reshape(out.shape)
