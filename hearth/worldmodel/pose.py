"""Immutable poses and homogeneous transforms.

A ``Pose`` is x, y, z in metres and roll, pitch, yaw in radians, relative to a parent frame;
the rotation is ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (scipy's extrinsic "xyz" Euler angles).
``pose.matrix()`` is the 4x4 ``T_parent_child`` that maps points from the child frame into
the parent frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def _rotation():
    # scipy.spatial takes about 0.4 s to import and loading or validating a world needs no
    # rotation, so scipy is imported the first time one is computed (keeps `hearth validate`
    # and the CLI quick).
    from scipy.spatial.transform import Rotation
    return Rotation


@dataclass(frozen=True)
class Pose:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = _rotation().from_euler("xyz", [self.roll, self.pitch, self.yaw]).as_matrix()
        T[:3, 3] = (self.x, self.y, self.z)
        return T

    @staticmethod
    def from_matrix(T: np.ndarray) -> "Pose":
        r, p, y = _rotation().from_matrix(np.asarray(T)[:3, :3]).as_euler("xyz")
        t = np.asarray(T)[:3, 3]
        return Pose(float(t[0]), float(t[1]), float(t[2]), float(r), float(p), float(y))

    @staticmethod
    def planar(x: float, y: float, yaw: float) -> "Pose":
        return Pose(x, y, 0.0, 0.0, 0.0, yaw)

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def as_tuple(self) -> tuple[float, float, float, float, float, float]:
        return (self.x, self.y, self.z, self.roll, self.pitch, self.yaw)

    def as_dict(self) -> dict[str, float]:
        return dict(zip(("x", "y", "z", "roll", "pitch", "yaw"), self.as_tuple()))

    def compose(self, other: "Pose") -> "Pose":
        """``self * other``: ``other`` is given in this pose's frame."""
        return Pose.from_matrix(self.matrix() @ other.matrix())

    def inverse(self) -> "Pose":
        return Pose.from_matrix(np.linalg.inv(self.matrix()))

    def planar_distance(self, other: "Pose") -> float:
        return math.hypot(self.x - other.x, self.y - other.y)

    def yaw_difference(self, other: "Pose") -> float:
        """Smallest signed yaw difference ``self.yaw - other.yaw`` in radians."""
        return wrap_angle(self.yaw - other.yaw)


def wrap_angle(a: float) -> float:
    """An angle in radians wrapped to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 transform to an (N, 3) array."""
    points = np.asarray(points, dtype=float)
    return points @ T[:3, :3].T + T[:3, 3]


def rotation_about_axis(axis, angle: float) -> np.ndarray:
    """4x4 rotation about a unit axis through the origin."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    T = np.eye(4)
    T[:3, :3] = _rotation().from_rotvec(axis * angle).as_matrix()
    return T


def translation_along_axis(axis, distance: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    T = np.eye(4)
    T[:3, 3] = axis * distance
    return T
