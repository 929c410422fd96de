"""Simulated views of a world: the camera head on the robot base, and noisy RGB-D frames.

Frames (see docs/robot-adapter.md):

- world: x, y on the floor, z up.
- base: the robot's base on the floor, x forward, y left, z up; a base pose is (x, y, yaw).
- camera: OpenCV axes (x right, y down, z forward), as in hearth/perception/camera.py.

The head (``HeadMount``): a pan joint (about the base's z axis) at ``pan_xy`` in the base,
a tilt joint (about the panned y axis; positive tilt looks down) at ``tilt_height`` above the
floor, and the camera's optical centre ``camera_forward`` ahead of the tilt axis on its
optical axis, so the optical axis always passes through the pan and tilt axes and looking at
a point is exact. With the defaults the camera is 1.30 m above the floor, 0.15 m ahead of the
base centre at pan = tilt = 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.robot.noise import KinectNoise, NoiseBands, draw_kinect_noise, start_kinect_noise
from hearth.worldmodel.frames import as_matrix
from hearth.worldmodel.pose import Pose

#: Camera axes (OpenCV: x right, y down, z forward) expressed in a body frame with x forward,
#: y left, z up.
R_BODY_CAMERA = np.array([[0.0, 0.0, 1.0],
                          [-1.0, 0.0, 0.0],
                          [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class HeadMount:
    """Where the pan/tilt head and its camera sit on the base (metres, radians)."""
    pan_xy: tuple[float, float] = (0.10, 0.0)
    tilt_height: float = 1.30
    camera_forward: float = 0.05
    pan_limits: tuple[float, float] = (-math.radians(170), math.radians(170))
    tilt_limits: tuple[float, float] = (-math.radians(45), math.radians(75))

    def clip(self, pan: float, tilt: float) -> tuple[float, float]:
        return (float(np.clip(pan, *self.pan_limits)), float(np.clip(tilt, *self.tilt_limits)))


HEAD = HeadMount()


def _as_T(pose) -> np.ndarray:
    return as_matrix(pose)


def T_base_camera(pan: float = 0.0, tilt: float = 0.0, mount: HeadMount = HEAD) -> np.ndarray:
    """4x4 camera pose in the base frame for head angles ``pan``, ``tilt`` (rad)."""
    cp, sp = math.cos(pan), math.sin(pan)
    ct, st = math.cos(tilt), math.sin(tilt)
    R_pan = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    R_tilt = np.array([[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]])   # +tilt: look down
    R_head = R_pan @ R_tilt
    T = np.eye(4)
    T[:3, :3] = R_head @ R_BODY_CAMERA
    T[:3, 3] = (np.array([mount.pan_xy[0], mount.pan_xy[1], mount.tilt_height])
                + R_head @ np.array([mount.camera_forward, 0.0, 0.0]))
    return T


def camera_pose(base_pose, pan: float = 0.0, tilt: float = 0.0,
                mount: HeadMount = HEAD) -> np.ndarray:
    """``T_world_camera`` for a base pose (a Pose, (x, y, yaw) or a 4x4 T_world_base) and
    head angles (rad)."""
    return _as_T(base_pose) @ T_base_camera(pan, tilt, mount)


def pan_tilt_to(base_pose, point_world, mount: HeadMount = HEAD) -> tuple[float, float]:
    """Head angles (pan, tilt; rad, within the mount's limits) that put ``point_world`` on
    the optical axis for the given base pose."""
    T_wb = _as_T(base_pose)
    p = np.linalg.inv(T_wb) @ np.append(np.asarray(point_world, dtype=float), 1.0)
    dx, dy = p[0] - mount.pan_xy[0], p[1] - mount.pan_xy[1]
    pan = math.atan2(dy, dx)
    tilt = math.atan2(mount.tilt_height - p[2], math.hypot(dx, dy))
    return mount.clip(pan, tilt)


class PanTiltHead:
    """The head of the simulated and the replayed robot: ``head``, ``set_head`` (clipped to
    ``self.mount``; done at once) and ``look_at`` (aimed from the *believed* base pose, so a
    localisation error shows in the image). The class using it sets ``mount``, ``_pan`` and
    ``_tilt`` and has ``base_pose()``."""

    def head(self) -> tuple[float, float]:
        return self._pan, self._tilt

    def set_head(self, pan: float, tilt: float):
        from hearth.robot.adapter import DoneAction
        self._pan, self._tilt = self.mount.clip(float(pan), float(tilt))
        return DoneAction("set_head", result=(self._pan, self._tilt))

    def look_at(self, point_world):
        return self.set_head(*pan_tilt_to(self.base_pose(), point_world, self.mount))


class SpokenAndLogged:
    """Speech and the action log of the simulated and the replayed robot: ``say`` is done at
    once and kept in ``said``; ``_log`` appends one dict per action to ``log`` (``time`` on
    ``self.clock``, ``action`` and its details). The class using it sets ``said``, ``log``
    and ``clock``."""

    def say(self, text: str):
        from hearth.robot.adapter import DoneAction
        self.said.append(str(text))
        self._log("say", text=str(text))
        return DoneAction("say", result=str(text))

    def _log(self, action: str, **info) -> None:
        self.log.append(dict(time=self.clock.now(), action=action, **info))


@dataclass
class Frame:
    """One RGB-D capture. ``color`` uint8 RGB (H, W, 3); ``depth`` float32 metres (0 = no
    reading); ``T_world_camera`` the *believed* camera pose (4x4); ``timestamp`` seconds on the
    robot's clock; ``pan``/``tilt`` the head angles (rad). Ground truth where known:
    ``T_world_camera_true``, ``base_pose_true``, ``labels`` (node index per pixel, -1 none)
    with ``nodes``/``owners`` naming them, ``rendering`` (the noise-free rendering)."""
    color: np.ndarray
    depth: np.ndarray
    intrinsics: Intrinsics
    T_world_camera: np.ndarray
    timestamp: float = 0.0
    pan: float = 0.0
    tilt: float = 0.0
    base_pose: Optional[Pose] = None
    T_world_camera_true: Optional[np.ndarray] = None
    base_pose_true: Optional[Pose] = None
    labels: Optional[np.ndarray] = None
    nodes: list = field(default_factory=list)
    owners: list = field(default_factory=list)
    rendering: Optional[object] = None
    parking: Optional[str] = None

    @property
    def K(self) -> Intrinsics:
        return self.intrinsics

    def mask(self, node_ids) -> np.ndarray:
        """Ground-truth pixels of the given nodes (needs ``labels``)."""
        idx = [i for i, n in enumerate(self.nodes) if n in set(node_ids)]
        return np.isin(self.labels, idx)

    def owner_mask(self, owner_ids) -> np.ndarray:
        idx = [i for i, n in enumerate(self.owners) if n in set(owner_ids)]
        return np.isin(self.labels, idx)


def world_scene(world, states: Optional[dict] = None):
    """A hearth.perception.render.Scene of every mesh of ``world`` (in the given states)."""
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import scene_meshes
    return Scene(scene_meshes(world, states=states))


def render_view(world, K: Intrinsics, T_world_camera, rng: Optional[np.random.Generator] = None,
                noise: Optional[KinectNoise] = KinectNoise(), states: Optional[dict] = None,
                scene=None, T_world_camera_believed=None, timestamp: float = 0.0) -> Frame:
    """Render ``world`` from ``T_world_camera`` (the true camera pose) with Kinect-class
    noise (``noise=None``: noise-free). ``states`` overrides joint states / knob angles;
    ``scene`` reuses a prebuilt Scene (``world_scene``) of the same world and states.
    The frame's ``T_world_camera`` is ``T_world_camera_believed`` when given, else the truth."""
    T_true = np.asarray(T_world_camera, dtype=float)
    scene = scene if scene is not None else world_scene(world, states)
    rng = rng if rng is not None else np.random.default_rng(0)
    # The frame-sized random draws of the noise need only the image size: drawn on a pool
    # thread while the rays are cast, started once the cast has cast its first rays (before
    # that it keeps both cores busy, after it leaves one idle while it works out which
    # blocks to fill: 0.94-0.99x a frame in turns in one process; the same frames).
    started_draws: list = []

    def start_draws() -> None:
        if noise is not None and not started_draws:
            started_draws.append(draw_kinect_noise((K.height, K.width), rng, noise))
    try:
        hits = scene.cast(K, T_true, when_coarse=start_draws)
    except BaseException:
        if started_draws:
            started_draws[0].exception()   # the generator is the pool thread's until it is done
        raise
    start_draws()                   # (a cast that never called it)
    draws = started_draws[0] if started_draws else None
    if noise is None:
        clean = noisy = scene.shade(hits)
    else:
        # The lateral jitter needs the depth (and the generator, once the draws above are
        # done): on a pool thread while this one (and the other) shades; the same frame as
        # add_kinect_noise(scene.render(...)).
        started = start_kinect_noise(hits.depth, rng, noise, draws)
        bands = NoiseBands(started, scene.materials, hits.depth.shape)
        clean = scene.shade(hits, after=bands.band)       # the noise applied band by band
        noisy = bands.result(clean)
    T_bel = T_true if T_world_camera_believed is None else np.asarray(T_world_camera_believed)
    return Frame(color=noisy.color, depth=noisy.depth, intrinsics=K, T_world_camera=T_bel.copy(),
                 timestamp=timestamp, T_world_camera_true=T_true.copy(), labels=clean.labels,
                 nodes=clean.nodes, owners=clean.owners, rendering=clean)
