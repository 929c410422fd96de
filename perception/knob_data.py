"""Rendered knob views for training and benchmarking the knob models (perception/knobs.py).

Every view is rendered from the knob models in the map (worldmodel.geometry's knob meshes in
the whole home, so panels, neighbouring knobs and walls are where they are): a camera 0.5 to
1.5 m from a knob, up to 60 degrees off its axis, every knob of the object at a random angle
(uniform over the full turn), sometimes the knob removed (a region with no knob). Only the
pixels around the knob are ray cast (a cropped camera), which keeps a view to a few ms.
The image then gets lighting (gain, gamma, offset, a gradient), optical blur and sensor
noise (``noise``: a callable ``(rendering, rng) -> rendering`` such as the simulated robot's
``robot.noise.add_kinect_noise``, applied first; colour noise of our own is always added).
The map's belief of the knob's pose is perturbed as registration would (a few mm, a degree
or two), so the models learn to read knobs that are not quite where the map says.

``training_patches`` cuts detector windows (positives centred on the knob, negatives
elsewhere in the region and from other surfaces of rendered scenes: ``scene_negatives``)
and angle windows from views. Pure: the world in, arrays out; the same seed gives the same
data.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Optional

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from perception.camera import Intrinsics, look_at
from perception.knobs import (
    BORDER, DETECTOR_HOG, PATCH, WINDOW, KnobConfig, KnobPrior, canvas_homography, detect_knob, face_patch,
    knob_priors, rectify, rotate_xy, to_gray,
)
from perception.render import Rendering, Scene


#: A window whose centre is this far (canvas px, a third of a knob radius) from the knob's is
#: a negative for the detector.
NEGATIVE_PX = 5.5


@dataclass(frozen=True)
class KnobDataConfig:
    """How views are drawn. Distances in m, angles in degrees; ``pose_sigma_m`` /
    ``pose_sigma_deg``: the belief's error (clipped at 2.5 sigma); ``missing_rate``: share of
    views whose knob is removed; ``blur_sigma``: max Gaussian blur (px); ``noise_sigma``: max
    colour noise (grey levels)."""
    distance: tuple[float, float] = (0.5, 1.5)
    max_off_axis_deg: float = 60.0
    pose_sigma_m: float = 0.005
    pose_sigma_deg: float = 1.0
    missing_rate: float = 0.15
    blur_sigma: float = 1.5
    noise_sigma: float = 6.0
    gain: tuple[float, float] = (0.55, 1.35)
    gamma: tuple[float, float] = (0.7, 1.5)
    at_states: bool = False
    state_jitter_deg: float = 2.0


@dataclass
class KnobView:
    """One rendered view around one knob: ``image`` (H, W, 3) uint8 of the cropped camera
    ``K``; ``believed``: the map's (perturbed) prior used to search; ``truth``: the true
    prior; ``angle``: the true angle (rad); ``present``: False when the knob was removed; ``state``: the true state
    when views are drawn at states."""
    image: np.ndarray
    K: Intrinsics
    T_world_camera: np.ndarray
    believed: KnobPrior
    truth: KnobPrior
    angle: float
    present: bool
    distance: float
    off_axis_deg: float
    state: str = ""


class KnobScenes:
    """Meshes of a home for rendering knob views: per knob-bearing object, one ray-casting
    scene of everything but its knobs (built once, on first use), and the knobs, placed at the
    angles of each view in a small scene of their own. A view casts its rays into both and
    keeps the nearer hit, which is the image one scene of everything would give, without
    rebuilding the whole home's acceleration structure for every new set of knob angles."""

    def __init__(self, world):
        from worldmodel.geometry import knob_visuals, object_meshes, scene_meshes, visual_mesh
        self.world = world
        self.priors = {p.knob_id: p for p in knob_priors(world)}
        if not self.priors:
            from perception.errors import PerceptionError
            raise PerceptionError("the map has no knobs")
        self.owner = {kid: world.large_object_of(kid).id for kid in self.priors}
        owners = set(self.owner.values())
        self.static = [lm for lm in scene_meshes(world) if lm.owner not in owners]
        self._object_meshes = object_meshes
        self.knobs_of = {o: [k for k in self.priors if self.owner[k] == o] for o in owners}
        # each knob's visuals in its own frame at angle 0, and that frame in the world
        self._knob_visuals = {kid: [(visual_mesh(v, world.base_dir), v)
                                    for v in knob_visuals(world.get(kid))] for kid in self.priors}
        self._bases: dict[str, Scene] = {}

    def base(self, owner: str) -> Scene:
        """Everything of the home but ``owner``'s knobs."""
        if owner not in self._bases:
            knobs = set(self.knobs_of[owner])
            own = [lm for lm in self._object_meshes(self.world, self.world.get(owner))
                   if lm.node not in knobs]
            self._bases[owner] = Scene(self.static + own)
        return self._bases[owner]

    def knob_meshes(self, owner: str, angles: dict, missing: tuple = ()) -> list:
        """``owner``'s knobs (LabelledMesh, world frame) at ``angles`` (rad, by knob id; a knob
        not in it at the map's angle), without those in ``missing``."""
        from worldmodel.geometry import LabelledMesh
        out = []
        for kid in self.knobs_of[owner]:
            if kid in missing:
                continue
            a = float(angles.get(kid, self.world.get(kid).angle))
            c, s = math.cos(a), math.sin(a)
            turn = np.eye(4)
            turn[:2, :2] = [[c, -s], [s, c]]
            T = self.priors[kid].T_world_knob @ turn
            for mesh, v in self._knob_visuals[kid]:
                m = type(mesh)(mesh)
                m.transform(T)
                out.append(LabelledMesh(kid, owner, m, tuple(v.color), v.material, v.name))
        return out

    def scene(self, owner: str, angles: dict, missing: tuple = ()) -> "LayeredScene":
        """The home with ``owner``'s knobs at ``angles`` (and without ``missing``), to render."""
        knobs = self.knob_meshes(owner, angles, missing)
        points = (np.concatenate([np.asarray(lm.mesh.vertices) for lm in knobs])
                  if knobs else np.zeros((0, 3)))
        return LayeredScene(self.base(owner), Scene(knobs), points)


class LayeredScene:
    """Two ray-casting scenes rendered as one: per pixel the nearer hit. The front one (a few
    small meshes whose vertices are ``front_points``, world frame) is cast only over the
    pixels its vertices' bounding box covers."""

    def __init__(self, back: Scene, front: Scene, front_points: Optional[np.ndarray] = None):
        self.back, self.front, self.front_points = back, front, front_points

    def _front_window(self, K: Intrinsics, T_world_camera: np.ndarray):
        """(u0, v0, u1, v1) of the image the front meshes can cover, None when none."""
        if self.front_points is None:
            return 0, 0, K.width, K.height
        if len(self.front_points) == 0:
            return None
        T = np.linalg.inv(T_world_camera)
        pc = self.front_points @ T[:3, :3].T + T[:3, 3]
        if np.any(pc[:, 2] <= 1e-3):
            return 0, 0, K.width, K.height      # straddles the camera plane: cast everything
        u = K.fx * pc[:, 0] / pc[:, 2] + K.cx
        v = K.fy * pc[:, 1] / pc[:, 2] + K.cy
        u0, v0 = max(int(np.floor(u.min())) - 1, 0), max(int(np.floor(v.min())) - 1, 0)
        u1, v1 = min(int(np.ceil(u.max())) + 2, K.width), min(int(np.ceil(v.max())) + 2, K.height)
        return (u0, v0, u1, v1) if u1 > u0 and v1 > v0 else None

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
        a = self.back.render(K, T_world_camera, max_range)
        win = self._front_window(K, T_world_camera) if self.front.nodes else None
        if win is None:
            return a
        u0, v0, u1, v1 = win
        b = self.front.render(Intrinsics(K.fx, K.fy, K.cx - u0, K.cy - v0, u1 - u0, v1 - v0),
                              T_world_camera, max_range)
        # a's arrays are this render's own: the front's nearer hits go straight into them.
        # Triangle rows: a's, then b's, then the no-hit row of zeros.
        na, nb = len(a.triangle_normals_camera) - 1, len(b.triangle_normals_camera) - 1
        tri_a = np.where(a.triangle == na, na + nb, a.triangle)
        tri_b = np.where(b.triangle == nb, na + nb, b.triangle + na)
        out = Rendering(depth=a.depth, color=a.color, labels=a.labels,
                        nodes=a.nodes + b.nodes, owners=a.owners + b.owners,
                        names=a.names + b.names, materials=a.materials + b.materials,
                        incidence=a.incidence, triangle=tri_a,
                        triangle_normals_camera=np.vstack([a.triangle_normals_camera[:-1],
                                                           b.triangle_normals_camera]))
        w = (slice(v0, v1), slice(u0, u1))
        take = (b.depth > 0) & ((a.depth[w] <= 0) | (b.depth < a.depth[w]))
        out.depth[w][take] = b.depth[take]
        out.color[w][take] = b.color[take]
        out.labels[w][take] = b.labels[take] + len(a.nodes)
        out.triangle[w][take] = tri_b[take]
        out.incidence[w][take] = b.incidence[take]
        return out


def _perturb(prior: KnobPrior, rng, cfg: KnobDataConfig) -> KnobPrior:
    t = np.clip(rng.normal(0, cfg.pose_sigma_m, 3), -2.5 * cfg.pose_sigma_m, 2.5 * cfg.pose_sigma_m)
    t[2] *= 0.4
    r = np.clip(rng.normal(0, math.radians(cfg.pose_sigma_deg), 3), -2.5 * math.radians(cfg.pose_sigma_deg),
                2.5 * math.radians(cfg.pose_sigma_deg))
    D = np.eye(4)
    D[:3, :3] = Rotation.from_rotvec(r).as_matrix()
    D[:3, 3] = t
    return KnobPrior(prior.knob_id, prior.T_world_knob @ D, prior.radius, prior.depth,
                     prior.state_names, prior.state_angles)


def _camera(prior: KnobPrior, rng, cfg: KnobDataConfig):
    """A camera pose 0.5-1.5 m from the knob, up to the max off-axis angle, head height-ish."""
    T = prior.T_world_face()
    p = T[:3, 3]
    for _ in range(50):
        cos_a = rng.uniform(math.cos(math.radians(cfg.max_off_axis_deg)), 1.0)
        a = math.acos(cos_a)
        phi = rng.uniform(-math.pi, math.pi)
        d = rng.uniform(*cfg.distance)
        dir_k = np.array([math.sin(a) * math.cos(phi), math.sin(a) * math.sin(phi), cos_a])
        eye = p + d * (T[:3, :3] @ dir_k)
        if 0.25 < eye[2] < 2.0:
            # look near the knob, not always straight at it
            side = rng.normal(0, 0.08 * d, 3)
            return look_at(eye, p + side), d, math.degrees(a)
    return look_at(p + 1.0 * T[:3, 2], p), 1.0, 0.0


def _crop(K: Intrinsics, T_world_camera, prior: KnobPrior, cfg: KnobConfig, pad: int = 6):
    """The cropped camera that sees the knob's search region at every pyramid scale."""
    size = WINDOW + 2 * cfg.search_px
    rho = cfg.px_per_radius * min(cfg.scales) / prior.radius
    H, _ = canvas_homography(K, T_world_camera, prior, rho, size, cfg=cfg)
    c = np.array([[0, 0, 1], [size, 0, 1], [0, size, 1], [size, size, 1]], dtype=float).T
    uv = H @ c
    uv = uv[:2] / uv[2]
    u0, v0 = np.floor(uv.min(1)).astype(int) - pad
    u1, v1 = np.ceil(uv.max(1)).astype(int) + pad
    u0, v0 = max(u0, 0), max(v0, 0)
    u1, v1 = min(u1, K.width), min(v1, K.height)
    if u1 - u0 < 8 or v1 - v0 < 8:
        return None
    return Intrinsics(K.fx, K.fy, K.cx - u0, K.cy - v0, int(u1 - u0), int(v1 - v0))


def photometric(image: np.ndarray, rng, cfg: KnobDataConfig) -> np.ndarray:
    """Lighting, blur and colour noise on a uint8 RGB image."""
    x = image.astype(np.float32) / 255.0
    h, w = x.shape[:2]
    g = rng.uniform(*cfg.gain)
    yy, xx = np.mgrid[0:h, 0:w]
    grad = 1.0 + rng.uniform(-0.15, 0.15) * (xx / max(w, 1) - 0.5) + rng.uniform(-0.15, 0.15) * (yy / max(h, 1) - 0.5)
    x = np.clip(x * g * grad[..., None], 0, 1) ** rng.uniform(*cfg.gamma)
    x = x * 255.0 + rng.uniform(-20, 20)
    sigma = rng.uniform(0, cfg.blur_sigma)
    if sigma > 0.3:
        x = cv2.GaussianBlur(x, (0, 0), sigma)
    x = x + rng.normal(0, rng.uniform(1.0, cfg.noise_sigma), x.shape)
    return np.clip(x, 0, 255).astype(np.uint8)


def render_views(world, n: int, seed: int, data: KnobDataConfig = KnobDataConfig(),
                 cfg: KnobConfig = KnobConfig(), noise: Optional[Callable] = None,
                 scenes: Optional[KnobScenes] = None, progress: Optional[Callable] = None) -> list[KnobView]:
    """``n`` views drawn with ``seed``; ``progress(done, n)`` is called now and then."""
    rng = np.random.default_rng(seed)
    scenes = scenes or KnobScenes(world)
    K_full = Intrinsics.kinect()
    ids = sorted(scenes.priors)
    out: list[KnobView] = []
    while len(out) < n:
        kid = ids[int(rng.integers(len(ids)))]
        owner = scenes.owner[kid]
        states = {}
        if data.at_states:
            angles = {}
            for k in scenes.knobs_of[owner]:
                i = int(rng.integers(len(scenes.priors[k].state_angles)))
                states[k] = scenes.priors[k].state_names[i]
                angles[k] = float(scenes.priors[k].state_angles[i]
                                  + math.radians(rng.uniform(-1, 1) * data.state_jitter_deg))
        else:
            angles = {k: float(rng.uniform(-math.pi, math.pi)) for k in scenes.knobs_of[owner]}
        present = rng.random() >= data.missing_rate
        truth = scenes.priors[kid]
        believed = _perturb(truth, rng, data)
        T_wc, dist, off = _camera(truth, rng, data)
        K = _crop(K_full, T_wc, believed, cfg)
        if K is None:
            continue
        r = scenes.scene(owner, angles, () if present else (kid,)).render(K, T_wc)
        if noise is not None:
            # its own generator, so that a noise model drawing more or fewer numbers leaves
            # the views (poses, angles, lighting) of a seed unchanged
            r = noise(r, np.random.default_rng([seed, len(out)])) or r
        out.append(KnobView(photometric(r.color, rng, data), K, T_wc, believed, truth,
                            angles[kid], bool(present), dist, off, states.get(kid, "")))
        if progress and len(out) % 50 == 0:
            progress(len(out), n)
    return out


def true_center_m(view: KnobView) -> tuple[float, float]:
    """Where the true knob face centre appears on the believed face plane (m): the camera ray
    through it, cut with the believed plane."""
    T_bf = view.believed.T_world_face()
    T_fw = np.linalg.inv(T_bf)
    c = (T_fw @ np.append(view.T_world_camera[:3, 3], 1.0))[:3]
    q = (T_fw @ view.truth.T_world_face()[:, 3])[:3]
    t = -c[2] / (q[2] - c[2]) if abs(q[2] - c[2]) > 1e-9 else 1.0
    p = c + t * (q - c)
    return float(p[0]), float(p[1])


def training_patches(views: list[KnobView], seed: int, cfg: KnobConfig = KnobConfig(),
                     positives: int = 3, negatives: int = 6, angle_patches: int = 2):
    """Detector patches and labels, angle patches and angles (rad) from views.

    Positives: windows centred within 2 px on the knob at scales within half a pyramid
    step; negatives: windows of the searched canvas whose centre is at least ``NEGATIVE_PX``
    (a third of a knob radius) from the knob, or anywhere when it is missing. Angle windows:
    centred within 4 px (what the detector gets wrong in hard views), same scale range."""
    rng = np.random.default_rng(seed)
    det_p, det_y, ang_p, ang_y = [], [], [], []
    st = DETECTOR_HOG["stride"][0]
    size = WINDOW + 2 * cfg.search_px
    for v in views:
        gray = to_gray(v.image)
        pr = v.believed
        cx, cy = true_center_m(v)
        psi = pr.canvas_frame(v.T_world_camera, cfg.view_aligned)[1]
        ccx, ccy = rotate_xy((cx, cy), -psi)   # the knob centre in the canvas frame
        if v.present:
            for k in range(positives + angle_patches):
                s = rng.uniform(0.93, 1.08)
                rho = cfg.px_per_radius * s / pr.radius
                j = (2.0 if k < positives else 4.0) / rho
                patch = face_patch(gray, v.K, v.T_world_camera, pr,
                                   (cx + rng.uniform(-j, j), cy + rng.uniform(-j, j)), s, cfg)
                if k < positives:
                    det_p.append(patch)
                    det_y.append(1)
                else:
                    ang_p.append(patch)
                    ang_y.append(v.angle - psi)   # the angle the canvas shows
        s = float(rng.choice(cfg.scales))
        rho = cfg.px_per_radius * s / pr.radius
        full = size + 2 * BORDER
        canvas = rectify(gray, canvas_homography(v.K, v.T_world_camera, pr, rho, full, cfg=cfg)[0], full)
        c0 = (full - 1) / 2
        tx, ty = c0 + ccx * rho, c0 - ccy * rho
        cand = []
        for y0 in range(0, size - WINDOW + 1, st):
            for x0 in range(0, size - WINDOW + 1, st):
                wx, wy = x0 + BORDER + (WINDOW - 1) / 2, y0 + BORDER + (WINDOW - 1) / 2
                if not v.present or math.hypot(wx - tx, wy - ty) > NEGATIVE_PX:
                    cand.append((x0, y0))
        for idx in rng.permutation(len(cand))[:negatives]:
            x0, y0 = cand[idx]
            det_p.append(canvas[y0:y0 + PATCH, x0:x0 + PATCH])
            det_y.append(0)
    return (np.array(det_p, dtype=np.uint8).reshape(-1, PATCH, PATCH), np.array(det_y, dtype=int),
            np.array(ang_p, dtype=np.uint8).reshape(-1, PATCH, PATCH), np.array(ang_y, dtype=float))


def hard_negatives(views: list[KnobView], detector, cfg: KnobConfig = KnobConfig(),
                   margin: float = -0.5, limit: int = 20000) -> np.ndarray:
    """Windows the detector scores above ``margin`` although no knob is centred in them
    (the centre is more than ``NEGATIVE_PX`` from the knob, or the knob is missing): one
    round of hard-negative mining over the training views (Felzenszwalb et al.)."""
    st = DETECTOR_HOG["stride"][0]
    size = WINDOW + 2 * cfg.search_px
    full = size + 2 * BORDER
    out = []
    for v in views:
        gray = to_gray(v.image)
        pr = v.believed
        cx, cy = rotate_xy(true_center_m(v), -pr.canvas_frame(v.T_world_camera, cfg.view_aligned)[1])
        for s in cfg.scales:
            rho = cfg.px_per_radius * s / pr.radius
            canvas = rectify(gray, canvas_homography(v.K, v.T_world_camera, pr, rho, full, cfg=cfg)[0], full)
            score = detector.scan(canvas[BORDER:BORDER + size, BORDER:BORDER + size])
            c0 = (full - 1) / 2
            tx, ty = c0 + cx * rho, c0 - cy * rho
            for i, j in zip(*np.nonzero(score > margin)):
                x0, y0 = j * st, i * st
                wx, wy = x0 + BORDER + (WINDOW - 1) / 2, y0 + BORDER + (WINDOW - 1) / 2
                if not v.present or math.hypot(wx - tx, wy - ty) > NEGATIVE_PX:
                    out.append(canvas[y0:y0 + PATCH, x0:x0 + PATCH])
        if len(out) >= limit:
            break
    return np.array(out[:limit], dtype=np.uint8).reshape(-1, PATCH, PATCH)


def scene_negatives(world, n_views: int, seed: int, cfg: KnobConfig = KnobConfig(),
                    data: KnobDataConfig = KnobDataConfig(), per_view: int = 4,
                    scenes: Optional[KnobScenes] = None) -> np.ndarray:
    """Negative windows from other surfaces of the rendered home: a camera looks at a random
    object from 0.5-2.5 m; a random surface point (away from every knob) and its normal define
    a plane, rectified as a knob's face would be."""
    rng = np.random.default_rng(seed)
    scenes = scenes or KnobScenes(world)
    objs = [o for o in world.large_objects()]
    K_full = Intrinsics.kinect()
    radius = float(np.median([p.radius for p in scenes.priors.values()]))
    knob_pts = np.array([p.T_world_face()[:3, 3] for p in scenes.priors.values()])
    owners = sorted(scenes.knobs_of)
    bounds = {}
    out = []
    tries = 0
    while len(out) < n_views * per_view and tries < n_views * 20:
        tries += 1
        o = objs[int(rng.integers(len(objs)))]
        if o.id not in bounds:
            bounds[o.id] = world.bounds_world(o.id)
        b = bounds[o.id]
        target = rng.uniform(b[0], b[1])
        d = rng.uniform(0.5, 2.5)
        a = rng.uniform(-math.pi, math.pi)
        eye = target + np.array([d * math.cos(a), d * math.sin(a), rng.uniform(-0.3, 0.8)])
        if not 0.3 < eye[2] < 2.0:
            continue
        T_wc = look_at(eye, target)
        u0, v0 = int(rng.integers(0, K_full.width - 128)), int(rng.integers(0, K_full.height - 128))
        K = Intrinsics(K_full.fx, K_full.fy, K_full.cx - u0, K_full.cy - v0, 128, 128)
        owner = owners[int(rng.integers(len(owners)))]
        angles = {k: float(rng.uniform(-math.pi, math.pi)) for k in scenes.knobs_of[owner]}
        r = scenes.scene(owner, angles).render(K, T_wc)
        gray = to_gray(photometric(r.color, rng, data))
        for _ in range(per_view):
            i, j = int(rng.integers(20, 108)), int(rng.integers(20, 108))
            z = float(r.depth[i, j])
            if z <= 0:
                continue
            pc = np.array([(j - K.cx) * z / K.fx, (i - K.cy) * z / K.fy, z])
            pw = T_wc[:3, :3] @ pc + T_wc[:3, 3]
            if np.min(np.linalg.norm(knob_pts - pw, axis=1)) < 4 * radius:
                continue
            nz = T_wc[:3, :3] @ r.normals_camera[i, j]
            if np.linalg.norm(nz) < 0.5:
                continue
            nz = nz / np.linalg.norm(nz)
            x = np.cross(nz, rng.normal(size=3))
            x /= np.linalg.norm(x)
            T_plane = np.eye(4)
            T_plane[:3, 0], T_plane[:3, 1], T_plane[:3, 2], T_plane[:3, 3] = x, np.cross(nz, x), nz, pw
            prior = KnobPrior("none", T_plane, radius, 0.0, ("x",), (0.0,))
            s = float(rng.uniform(0.85, 1.15))
            out.append(face_patch(gray, K, T_wc, prior, (0.0, 0.0), s, cfg))
    return np.array(out, dtype=np.uint8).reshape(-1, PATCH, PATCH)


@dataclass
class ThresholdCalibration:
    """``threshold``: the chosen detector threshold; ``errors``: validation errors there
    (missed knobs plus false detections); ``positives`` / ``empty``: validation views with a
    knob and without; ``recall`` / ``false_positive_rate`` at the threshold."""
    threshold: float
    errors: int
    positives: int
    empty: int
    recall: float
    false_positive_rate: float


def calibrate_threshold(views: list[KnobView], detector, cfg: KnobConfig = KnobConfig(),
                        floor: float = -5.0) -> ThresholdCalibration:
    """The detector threshold with the fewest errors on validation ``views`` (drawn with
    other seeds than the training views): for each view the best window of the knob's region
    is found with no threshold (above ``floor``); a present knob is missed when that window is
    under the threshold or, over it, more than half a radius from the knob (then it is also a
    false detection); an empty region errs when its best window is over the threshold. The
    error count is a step function of the threshold; we take the middle of its lowest step,
    as far from both kinds of error as the validation set allows. A hinge-loss SVM's own
    boundary (0) sits where its training windows are, not where the best of ~50 windows per
    region falls, which is why calibrating the threshold matters."""
    scan = replace(cfg, threshold=floor)
    near, far, empty = [], [], []
    for v in views:
        det = detect_knob(to_gray(v.image), v.K, v.T_world_camera, v.believed, detector, scan)
        s = det.score if det is not None else floor
        if not v.present:
            empty.append(s)
            continue
        cx, cy = true_center_m(v)
        ok = det is not None and math.hypot(det.center_m[0] - cx, det.center_m[1] - cy) <= 0.5 * v.truth.radius
        (near if ok else far).append(s)
    near_a, far_a, empty_a = (np.sort(np.asarray(x, dtype=float)) for x in (near, far, empty))
    cuts = np.unique(np.concatenate([near_a, far_a, empty_a, [floor]]))
    cand = np.concatenate([[floor - 1.0], (cuts[:-1] + cuts[1:]) / 2, [cuts[-1] + 1.0]])

    def errors(t):
        # near windows under t are misses; far windows are misses, and false detections
        # too when over t; empty regions over t are false detections
        return (np.searchsorted(near_a, t) + len(far_a) + (len(far_a) - np.searchsorted(far_a, t))
                + (len(empty_a) - np.searchsorted(empty_a, t)))

    err = np.array([errors(t) for t in cand])
    best = np.flatnonzero(err == err.min())
    # the middle of the lowest step (the lowest steps are contiguous in practice; if not,
    # the middle of the first run)
    run = best[:np.argmax(np.diff(np.append(best, best[-1] + 2)) > 1) + 1]
    lo, hi = cand[run[0]], cand[run[-1]]
    t = float((lo + hi) / 2) if np.isfinite(lo + hi) else float(lo)
    n_pos = len(near_a) + len(far_a)
    rec = float((near_a > t).sum() / max(n_pos, 1))
    fpr = float((empty_a > t).sum() / max(len(empty_a), 1))
    return ThresholdCalibration(t, int(errors(t)), n_pos, len(empty_a), rec, fpr)
