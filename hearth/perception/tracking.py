"""Small-object tracking with a KLD-adaptive particle filter (RAMCIP D3.1 section 5.3).

State of one particle: position x, y, z and orientation roll, pitch, yaw of the object in the
world frame (roll and pitch stay fixed unless ``TrackerConfig.full_pose``), plus velocities.
Per frame:

1. resample the previous weighted set (systematic resampling on the tracker's own generator);
2. propagate with a *mixed* motion model: a fraction ``velocity_ratio`` of the particles
   moves with its own constant velocity, the rest stays put (constant position); both get
   process noise, so the filter follows starts, stops and turns with few particles;
3. keep drawing (in the resampled order) until the KLD bound of Fox (2003) on the number of
   occupied histogram bins is met (``min_particles`` .. ``max_particles``);
4. weigh each particle by its likelihood: the reference cloud (object frame) is moved to the
   particle's pose and each reference point is paired with its nearest scene point (scipy
   cKDTree over the scene points near the prediction); a pair scores
   exp(-d^2 / 2 sigma_d^2) * exp(-c^2 / 2 sigma_c^2) with ``d`` the Euclidean distance and
   ``c`` the distance in the HSV cone; the particle's score is the mean over the reference
   points (the fraction of the model that is explained) and its weight exp(gain * score).

The reference cloud is taken from the first view (``reference_from_view``), as RAMCIP does:
the tracker needs no model library. Frames: ``T_world_camera`` maps camera points to the
world; depth in metres (0 = no reading); colour uint8 RGB.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.spatial import cKDTree

from hearth.perception.camera import Intrinsics, project
from hearth.perception.errors import PerceptionError

_POSE = slice(0, 6)      # x y z roll pitch yaw
_VEL = slice(6, 12)      # their rates (per second)


@dataclass(frozen=True)
class TrackerConfig:
    """Tracker parameters. Noise sigmas are per frame at 30 Hz (scaled by sqrt(dt * 30))."""
    min_particles: int = 150
    max_particles: int = 600
    init_particles: int = 300
    kld_epsilon: float = 0.08          # bound on the KL divergence (Fox 2003)
    kld_z: float = 2.326               # upper 1 - delta quantile of N(0, 1), delta = 0.01
    bin_size_m: float = 0.02
    bin_size_rad: float = math.radians(15)
    velocity_ratio: float = 0.5        # fraction following the constant-velocity model
    sigma_pos: float = 0.006           # m per frame
    sigma_z: float = 0.001
    sigma_yaw: float = math.radians(3)
    sigma_tilt: float = math.radians(1.5)
    sigma_vel: float = 0.05            # m/s per frame
    sigma_yaw_rate: float = math.radians(10)
    full_pose: bool = False            # also track roll and pitch
    sigma_init_m: float = 0.01
    sigma_init_rad: float = math.radians(5)
    sigma_dist: float = 0.008          # m, nearest-point distance scale of the likelihood
    sigma_color: float = 0.15          # HSV-cone distance scale of the likelihood
    gain: float = 30.0                 # weight = exp(gain * (score - best score))
    roi_margin_m: float = 0.12         # scene points kept around the predicted box
    surface_clearance_m: float = 0.008 # scene points this close above the object's base are
                                       # the supporting surface: left out
    max_scene_points: int = 6000
    min_score: float = 0.15            # below this the estimate is reported lost


@dataclass
class TrackEstimate:
    """The tracker's answer for one frame. ``T_world_object`` 4x4; ``centroid_world`` the
    centre of the object's box at that pose (m); ``score`` the best particle's explained
    fraction of the reference cloud (0..1); ``ok`` False when the object looks lost."""
    T_world_object: np.ndarray
    centroid_world: np.ndarray
    velocity_world: np.ndarray
    n_particles: int
    score: float
    ok: bool


@dataclass
class Reference:
    """The tracked object's appearance: points in the object frame (m) and their HSV-cone
    colours (N, 3)."""
    points_object: np.ndarray
    hsv_cone: np.ndarray
    half_extents: np.ndarray = field(default_factory=lambda: np.full(3, 0.1))

    @property
    def centroid_object(self) -> np.ndarray:
        """The centre of the object's box (object frame): unlike the mean of the seen points it
        does not move with the viewpoint or, for a round object, with an unobservable yaw."""
        return np.array([0.0, 0.0, float(self.half_extents[2])])


# -- helpers ----------------------------------------------------------------------------------

def hsv_cone(rgb: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 RGB -> points in the HSV cone (s v cos h, s v sin h, v), so that hue
    counts only where a colour is saturated and bright (grey and black have no hue)."""
    rgb = np.asarray(rgb, dtype=np.uint8).reshape(-1, 1, 3)
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL).reshape(-1, 3).astype(np.float64) / 255.0
    h = hsv[:, 0] * 2 * np.pi
    sv = hsv[:, 1] * hsv[:, 2]
    return np.stack([sv * np.cos(h), sv * np.sin(h), hsv[:, 2]], axis=1)


def pose_matrix(p: np.ndarray) -> np.ndarray:
    """(..., 6) x y z roll pitch yaw -> (..., 4, 4) (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    p = np.asarray(p, dtype=np.float64)
    cr, sr = np.cos(p[..., 3]), np.sin(p[..., 3])
    cp, sp = np.cos(p[..., 4]), np.sin(p[..., 4])
    cy, sy = np.cos(p[..., 5]), np.sin(p[..., 5])
    T = np.zeros(p.shape[:-1] + (4, 4))
    T[..., 0, 0] = cy * cp
    T[..., 0, 1] = cy * sp * sr - sy * cr
    T[..., 0, 2] = cy * sp * cr + sy * sr
    T[..., 1, 0] = sy * cp
    T[..., 1, 1] = sy * sp * sr + cy * cr
    T[..., 1, 2] = sy * sp * cr - cy * sr
    T[..., 2, 0] = -sp
    T[..., 2, 1] = cp * sr
    T[..., 2, 2] = cp * cr
    T[..., :3, 3] = p[..., :3]
    T[..., 3, 3] = 1.0
    return T


def pose_vector(T: np.ndarray) -> np.ndarray:
    """4x4 -> x y z roll pitch yaw."""
    R = T[:3, :3]
    pitch = math.asin(-max(-1.0, min(1.0, R[2, 0])))
    roll = math.atan2(R[2, 1], R[2, 2])
    yaw = math.atan2(R[1, 0], R[0, 0])
    return np.array([T[0, 3], T[1, 3], T[2, 3], roll, pitch, yaw])


def kld_bound(k: np.ndarray, epsilon: float, z: float) -> np.ndarray:
    """Fox (2003): particles needed so that, with probability 1 - delta, the KL divergence
    between the sample-based and the true posterior stays below ``epsilon``, given ``k``
    occupied bins (Wilson-Hilferty approximation of the chi-square quantile)."""
    k = np.asarray(k, dtype=np.float64)
    km1 = np.maximum(k - 1, 1)
    a = 2.0 / (9.0 * km1)
    n = km1 / (2 * epsilon) * (1 - a + np.sqrt(a) * z) ** 3
    return np.where(k > 1, n, 1.0)


def scene_cloud(depth: np.ndarray, color: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray,
                box_world: np.ndarray | None = None, max_points: int = 6000):
    """World points (N, 3) and their RGB colours (N, 3) of the pixels whose rays can reach the
    axis-aligned ``box_world`` ((2, 3) min, max; None: the whole image), thinned by a pixel
    stride so that at most about ``max_points`` remain."""
    H, W = depth.shape
    u0, v0, u1, v1 = 0, 0, W, H
    if box_world is not None:
        b = np.asarray(box_world, dtype=np.float64)
        corners = np.array([[x, y, z, 1.0] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]])
        pc = (np.linalg.inv(T_world_camera) @ corners.T).T[:, :3]
        uv, front = project(pc, K)
        if not front.any():
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.uint8)
        if front.all():
            u0 = int(max(0, math.floor(uv[:, 0].min())))
            u1 = int(min(W, math.ceil(uv[:, 0].max()) + 1))
            v0 = int(max(0, math.floor(uv[:, 1].min())))
            v1 = int(min(H, math.ceil(uv[:, 1].max()) + 1))
    if u1 <= u0 or v1 <= v0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.uint8)
    n_px = (u1 - u0) * (v1 - v0)
    stride = max(1, int(math.ceil(math.sqrt(n_px / max(max_points, 1)))))
    d = depth[v0:v1:stride, u0:u1:stride].astype(np.float64)
    c = color[v0:v1:stride, u0:u1:stride]
    v, u = np.mgrid[v0:v1:stride, u0:u1:stride]
    ok = np.isfinite(d) & (d > 0)
    z = d[ok]
    pts = np.stack([(u[ok] - K.cx) * z / K.fx, (v[ok] - K.cy) * z / K.fy, z], axis=1)
    pts = pts @ T_world_camera[:3, :3].T + T_world_camera[:3, 3]
    cols = c[ok]
    if box_world is not None:
        b = np.asarray(box_world, dtype=np.float64)
        keep = np.all((pts >= b[0]) & (pts <= b[1]), axis=1)
        pts, cols = pts[keep], cols[keep]
    return pts, cols


def reference_from_view(points_world: np.ndarray, colors_rgb: np.ndarray,
                        T_world_object: np.ndarray, half_extents, n: int = 80,
                        rng: np.random.Generator | None = None,
                        clearance: float = 0.008) -> Reference:
    """The reference cloud of an object from one view: the scene points inside the object's
    box (``half_extents`` in the object frame, m: x, y around its origin, z up from it to
    2 * half_extents[2]; points within ``clearance`` above the base are dropped so the
    supporting surface stays out), thinned to ``n``."""
    rng = rng or np.random.default_rng(0)
    he = np.asarray(half_extents, dtype=np.float64)
    T_ow = np.linalg.inv(T_world_object)
    p = np.asarray(points_world, dtype=np.float64) @ T_ow[:3, :3].T + T_ow[:3, 3]
    inside = np.all(np.abs(p[:, :2]) <= he[:2], axis=1) & (p[:, 2] > clearance) & (p[:, 2] <= 2 * he[2])
    p, c = p[inside], np.asarray(colors_rgb)[inside]
    if len(p) < 10:
        raise PerceptionError(f"only {len(p)} points of the object in view; cannot track it")
    if len(p) > n:
        idx = rng.choice(len(p), n, replace=False)
        p, c = p[idx], c[idx]
    return Reference(p, hsv_cone(c), he)


# -- the filter -------------------------------------------------------------------------------

def systematic_resample(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` ancestor indices into ``weights`` (any positive scale) by systematic resampling:
    one uniform offset ``u`` from ``rng``, positions ``(u + i) / n``, each mapped to the
    particle whose cumulative weight first exceeds it (index ``k`` is drawn ``n * w_k``
    times, rounded up or down).

    Written here rather than taken from filterpy, whose ``systematic_resample`` draws its
    offset from NumPy's global generator: a tracker must be reproducible from its own seed.
    """
    cumulative = np.cumsum(np.asarray(weights, dtype=np.float64))
    positions = (rng.random() + np.arange(n)) / n * cumulative[-1]
    idx = np.searchsorted(cumulative, positions, side="right")
    return np.minimum(idx, len(cumulative) - 1)     # rounding in the last cumulative sum


class ParticleTracker:
    """A KLD-adaptive particle filter following one object.

    ``ParticleTracker(reference, T_world_object, config, rng)``, then per frame
    ``update(depth, color, K, T_world_camera, dt) -> TrackEstimate``.
    """

    def __init__(self, reference: Reference, T_world_object: np.ndarray,
                 config: TrackerConfig | None = None, rng: np.random.Generator | None = None):
        self.config = config or TrackerConfig()
        self.reference = reference
        self.rng = rng or np.random.default_rng(0)
        c = self.config
        p0 = pose_vector(np.asarray(T_world_object, dtype=np.float64))
        n = c.init_particles
        self.particles = np.zeros((n, 12))
        self.particles[:, _POSE] = p0
        self.particles[:, 0:2] += self.rng.normal(0, c.sigma_init_m, (n, 2))
        self.particles[:, 5] += self.rng.normal(0, c.sigma_init_rad, n)
        self.weights = np.full(n, 1.0 / n)
        self.estimate = p0
        self.velocity = np.zeros(6)

    # one step ------------------------------------------------------------------------------
    def _resample_order(self, n_max: int) -> np.ndarray:
        """``n_max`` ancestor indices by systematic resampling, in random order (so that any
        prefix is itself a fair sample: needed by the KLD stopping rule)."""
        idx = systematic_resample(self.weights, n_max, self.rng)
        return self.rng.permutation(idx)

    def _propagate(self, parts: np.ndarray, dt: float) -> np.ndarray:
        c = self.config
        n = len(parts)
        s = math.sqrt(max(dt, 1e-3) * 30.0)
        out = parts.copy()
        moving = self.rng.random(n) < c.velocity_ratio
        out[moving, 0:3] += parts[moving, 6:9] * dt
        out[moving, 5] += parts[moving, 11] * dt
        out[:, 0:2] += self.rng.normal(0, c.sigma_pos * s, (n, 2))
        out[:, 2] += self.rng.normal(0, c.sigma_z * s, n)
        out[:, 5] += self.rng.normal(0, c.sigma_yaw * s, n)
        if c.full_pose:
            out[:, 3:5] += self.rng.normal(0, c.sigma_tilt * s, (n, 2))
        out[:, 6:8] += self.rng.normal(0, c.sigma_vel * s, (n, 2))
        out[:, 11] += self.rng.normal(0, c.sigma_yaw_rate * s, n)
        return out

    def _kld_count(self, parts: np.ndarray) -> int:
        """Smallest prefix length meeting the KLD bound (between min and max particles)."""
        c = self.config
        keys = np.column_stack([np.floor(parts[:, 0:3] / c.bin_size_m),
                                np.floor(np.mod(parts[:, 3:6], 2 * np.pi) / c.bin_size_rad)]).astype(np.int64)
        _, first = np.unique(keys, axis=0, return_index=True)
        first.sort()
        n = np.arange(1, len(parts) + 1)
        k = np.searchsorted(first, n, side="left")   # occupied bins among the first n
        ok = (n >= kld_bound(k, c.kld_epsilon, c.kld_z)) & (n >= c.min_particles)
        hit = np.flatnonzero(ok)
        return int(hit[0] + 1) if len(hit) else len(parts)

    def _scores(self, parts: np.ndarray, tree: cKDTree, scene_hsv: np.ndarray) -> np.ndarray:
        c = self.config
        T = pose_matrix(parts[:, _POSE])                             # (P, 4, 4)
        ref = self.reference.points_object
        pts = np.einsum("pij,mj->pmi", T[:, :3, :3], ref) + T[:, None, :3, 3]
        d, idx = tree.query(pts.reshape(-1, 3), k=1, distance_upper_bound=4 * c.sigma_dist)
        found = np.isfinite(d)
        sim = np.zeros(len(d))
        dc = scene_hsv[idx[found]] - np.tile(self.reference.hsv_cone, (len(parts), 1))[found]
        sim[found] = (np.exp(-0.5 * (d[found] / c.sigma_dist) ** 2)
                      * np.exp(-0.5 * np.sum(dc * dc, axis=1) / c.sigma_color ** 2))
        return sim.reshape(len(parts), -1).mean(axis=1)

    def update(self, depth: np.ndarray, color: np.ndarray, K: Intrinsics,
               T_world_camera: np.ndarray, dt: float = 1 / 30) -> TrackEstimate:
        """Fold one RGB-D frame in and return the new estimate."""
        c = self.config
        anc = self._resample_order(c.max_particles)
        cand = self._propagate(self.particles[anc], dt)
        n = self._kld_count(cand)
        parts = cand[:n]
        # Scene points near where the particles say the object is.
        he = float(np.max(self.reference.half_extents[:2]))
        lo = parts[:, 0:3].min(0) - [he, he, 0.0] - c.roi_margin_m
        hi = parts[:, 0:3].max(0) + [he, he, 2 * self.reference.half_extents[2]] + c.roi_margin_m
        lo[2] = parts[:, 2].min() + c.surface_clearance_m
        pts, cols = scene_cloud(depth, color, K, T_world_camera, np.stack([lo, hi]),
                                c.max_scene_points)
        if len(pts) == 0:
            scores = np.zeros(n)
        else:
            scores = self._scores(parts, cKDTree(pts), hsv_cone(cols))
        w = np.exp(c.gain * (scores - scores.max()))
        w /= w.sum()
        self.particles, self.weights = parts, w
        mean = np.zeros(6)
        mean[:3] = w @ parts[:, 0:3]
        for a in (3, 4, 5):
            mean[a] = math.atan2(w @ np.sin(parts[:, a]), w @ np.cos(parts[:, a]))
        self.velocity = w @ parts[:, _VEL]
        self.estimate = mean
        T = pose_matrix(mean)
        best = float(scores.max()) if len(scores) else 0.0
        centroid = T[:3, :3] @ self.reference.centroid_object + T[:3, 3]
        return TrackEstimate(T, centroid, self.velocity[:3].copy(), n, best, best >= c.min_score)
