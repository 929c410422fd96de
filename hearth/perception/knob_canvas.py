"""Rectification: the homography of a knob's face plane into a canvas that shows it head-on,
heights above that plane from the depth image, and the angle of a view to a knob's axis. The
method is described in hearth/perception/knobs.py."""

from __future__ import annotations

import math

import cv2
import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.perception.knob_priors import KnobPrior


def plane_homography(K: Intrinsics, T_world_camera: np.ndarray, T_world_plane: np.ndarray,
                     px_per_m: float, size: int, center=(0.0, 0.0)) -> np.ndarray:
    """3x3 homography from canvas pixels to image pixels: the canvas is ``size`` px square,
    shows the plane z = 0 of ``T_world_plane`` head-on at ``px_per_m``, its centre pixel at
    plane point ``center`` (m), canvas right = plane +x, canvas up = plane +y."""
    return image_of_plane(K, T_world_camera, T_world_plane) @ _canvas_to_plane(px_per_m, size, center)


def image_of_plane(K: Intrinsics, T_world_camera: np.ndarray, T_world_plane: np.ndarray) -> np.ndarray:
    """3x3 homography from the plane z = 0 of ``T_world_plane`` (m) to image pixels."""
    T_cp = np.linalg.inv(T_world_camera) @ T_world_plane
    return K.matrix() @ np.column_stack([T_cp[:3, 0], T_cp[:3, 1], T_cp[:3, 3]])


def _canvas_to_plane(px_per_m: float, size: int, center) -> np.ndarray:
    """``plane_homography``'s canvas pixels -> plane (m)."""
    c = (size - 1) / 2.0
    return np.array([[1.0 / px_per_m, 0.0, center[0] - c / px_per_m],
                     [0.0, -1.0 / px_per_m, center[1] + c / px_per_m],
                     [0.0, 0.0, 1.0]])


def rectify(image: np.ndarray, H_img_canvas: np.ndarray, size: int) -> np.ndarray:
    """The ``size`` x ``size`` canvas seen through ``H_img_canvas`` (the image's dtype and
    channels)."""
    return cv2.warpPerspective(image, H_img_canvas, (size, size),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REPLICATE)


def canvas_heights(depth: np.ndarray, H_img_canvas: np.ndarray, size: int, camera_height: float,
                   face: float, slack: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    """The depth image seen through a canvas (``rectify``'s ``H_img_canvas``) as heights (m)
    above the canvas plane (the knob's face), and where they are valid: a measured depth,
    between ``slack`` behind the panel (``face`` below the plane) and ``slack`` in front of
    the plane. A canvas pixel is a point q of the plane at camera depth z_q (the homography's
    third row); the surface seen through it lies on the same ray at the measured depth Z,
    at height ``camera_height`` * (1 - Z / z_q)."""
    h, seen = plane_heights(depth, H_img_canvas, size, size, camera_height)
    valid = seen & (h > -face - slack) & (h < slack)
    return np.where(valid, h, 0.0), valid


def plane_heights(depth: np.ndarray, H_img_canvas: np.ndarray, width: int, height: int,
                  camera_height: float) -> tuple[np.ndarray, np.ndarray]:
    """The depth image seen through a ``width`` x ``height`` canvas of a plane as heights (m)
    above it (``canvas_heights``' geometry), and where there is a reading in front of the
    camera (the heights elsewhere are meaningless)."""
    Z = cv2.warpPerspective(np.asarray(depth, np.float32), H_img_canvas, (width, height),
                            flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    jj, ii = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    zq = H_img_canvas[2, 0] * jj + H_img_canvas[2, 1] * ii + H_img_canvas[2, 2]
    h = camera_height * (1.0 - Z / np.where(zq > 1e-6, zq, 1e-6))
    return h, (Z > 0) & (zq > 1e-6)


def to_gray(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return image if image.dtype == np.uint8 else np.clip(image, 0, 255).astype(np.uint8)
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)


def to_rgb(image: np.ndarray) -> np.ndarray:
    """An RGB uint8 image (a grey one repeated on three channels)."""
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    return image if image.dtype == np.uint8 else np.clip(image, 0, 255).astype(np.uint8)


def rotate_xy(xy, psi: float) -> tuple[float, float]:
    """A plane point turned by ``psi`` (rad, counter-clockwise)."""
    c, s = math.cos(psi), math.sin(psi)
    return (c * xy[0] - s * xy[1], s * xy[0] + c * xy[1])


def off_axis_deg(T_world_camera: np.ndarray, prior: KnobPrior) -> float:
    """Angle between the knob's axis and the direction from the knob to the camera."""
    v = T_world_camera[:3, 3] - prior.T_world_face()[:3, 3]
    c = float(np.dot(v, prior.T_world_knob[:3, 2]) / max(np.linalg.norm(v), 1e-9))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))
