"""Rendered knob views for fitting, calibrating and benchmarking the knob reader
(hearth/perception/knobs.py).

Every view is rendered from the knobs as the map describes them (hearth.worldmodel.geometry's knob
meshes in the whole home, so panels, neighbouring knobs and walls are where they are): a
camera 0.5 to 1.5 m from a knob, up to 60 degrees off its axis, where a robot could stand:
in front of the appliance (the side its parking positions are on, whatever its yaw), inside
the room, 0.25-2 m up, with the knob in sight (``KnobScenes.placeable``); every knob of the
object at a random angle (uniform over the full turn) or at one of its states, sometimes the
knob removed (a region with no knob). Only the pixels around the knob are ray cast (a cropped
camera), which keeps a view to a few ms. The image then gets lighting (gain, gamma, offset,
a gradient), optical blur and sensor noise (``noise``: a callable ``(rendering, rng) ->
rendering`` such as the simulated robot's ``robot.noise.add_kinect_noise``, applied first;
colour noise of our own is always added). The map's belief of the knob's pose is perturbed as
registration would (a few mm, a degree or two), so the reader is tried on knobs that are not
quite where the map says.

Pure: the world in, arrays out; the same seed gives the same views.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Optional

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.knob_config import KnobConfig
from hearth.perception.knob_priors import KnobPrior, knob_priors
from hearth.perception.render import Rendering, Scene


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
    when views are drawn at states; ``depth``: the registered depth image (m, 0: no reading,
    with the sensor noise when ``noise`` is given)."""
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
    depth: Optional[np.ndarray] = None


class KnobScenes:
    """Meshes of a home for rendering knob views: per knob-bearing object, one ray-casting
    scene of everything but its knobs (built once, on first use), and the knobs, placed at the
    angles of each view in a small scene of their own. A view casts its rays into both and
    keeps the nearer hit, which is the image one scene of everything would give, without
    rebuilding the whole home's acceleration structure for every new set of knob angles."""

    def __init__(self, world):
        from hearth.worldmodel.geometry import knob_parts, object_meshes, scene_meshes, visual_mesh
        self.world = world
        self.priors = {p.knob_id: p for p in knob_priors(world)}
        if not self.priors:
            from hearth.perception.errors import PerceptionError
            raise PerceptionError("the map has no knobs")
        self.owner = {kid: world.large_object_of(kid).id for kid in self.priors}
        owners = set(self.owner.values())
        self.static = [lm for lm in scene_meshes(world) if lm.owner not in owners]
        self._object_meshes = object_meshes
        self.knobs_of = {o: [k for k in self.priors if self.owner[k] == o] for o in owners}
        # each knob's visuals in its own frame at angle 0 (and whether they turn)
        lib = world.apartment.library
        self._knob_visuals = {kid: [(visual_mesh(v, world.base_dir), v, turns)
                                    for _role, v, turns in knob_parts(world.get(kid), lib)]
                              for kid in self.priors}
        self._bases: dict[str, Scene] = {}
        self._fronts: dict[str, np.ndarray] = {}

    def base(self, owner: str) -> Scene:
        """Everything of the home but ``owner``'s knobs."""
        if owner not in self._bases:
            knobs = set(self.knobs_of[owner])
            own = [lm for lm in self._object_meshes(self.world, self.world.get(owner))
                   if lm.node not in knobs]
            self._bases[owner] = Scene(self.static + own)
        return self._bases[owner]

    def front(self, owner: str) -> np.ndarray:
        """The horizontal unit vector (world) from an appliance towards where a robot stands to
        use it: towards its parking positions, whatever way its own frame is turned."""
        if owner not in self._fronts:
            T = self.world.T_world(owner)
            parking = [p for _pp, p in self.world.parking_positions(owner)]
            c = np.mean([[p.x, p.y] for p in parking], axis=0) - T[:2, 3]
            if np.linalg.norm(c) < 1e-6:
                c = T[:2, 0]
            self._fronts[owner] = np.append(c / np.linalg.norm(c), 0.0)
        return self._fronts[owner]

    def placeable(self, kid: str, eye: np.ndarray, margin: float = 0.1) -> bool:
        """Whether a camera at ``eye`` (world) stands where a robot's camera could: in front of
        the knob's appliance (on its parking side), inside the knob's room, and with nothing of
        the home between it and the knob's face (its own appliance's knobs aside)."""
        prior = self.priors[kid]
        owner = self.owner[kid]
        p = prior.T_world_face()[:3, 3]
        if float((eye - p) @ self.front(owner)) < margin:
            return False
        room = self.world.room_of(owner)
        if room.bounds is not None:
            x0, y0, x1, y1 = room.bounds
            q = np.linalg.inv(room.pose.matrix()) @ np.append(eye, 1.0)
            if not (x0 + margin < q[0] < x1 - margin and y0 + margin < q[1] < y1 - margin):
                return False
        dist = float(np.linalg.norm(p - eye))
        # one ray, eye to knob: a 1-pixel camera looking at it
        r = self.base(owner).render(Intrinsics(500.0, 500.0, 0.0, 0.0, 1, 1), look_at(eye, p))
        z = float(r.depth[0, 0])
        return z <= 0 or z > dist - 0.004

    def knob_meshes(self, owner: str, angles: dict, missing: tuple = ()) -> list:
        """``owner``'s knobs (LabelledMesh, world frame) at ``angles`` (rad, by knob id; a knob
        not in it at the map's angle), without those in ``missing``."""
        from hearth.worldmodel.geometry import LabelledMesh
        out = []
        for kid in self.knobs_of[owner]:
            if kid in missing:
                continue
            a = float(angles.get(kid, self.world.get(kid).angle))
            c, s = math.cos(a), math.sin(a)
            turn = np.eye(4)
            turn[:2, :2] = [[c, -s], [s, c]]
            T0 = self.priors[kid].T_world_knob
            T = T0 @ turn
            for mesh, v, turns in self._knob_visuals[kid]:
                m = type(mesh)(mesh)
                m.transform(T if turns else T0)
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
    return replace(prior, T_world_knob=prior.T_world_knob @ D)


def _camera(prior: KnobPrior, rng, cfg: KnobDataConfig, ok: Optional[Callable] = None):
    """A camera pose 0.5-1.5 m from the knob, up to the max off-axis angle (uniform over the
    spherical cap), 0.25-2 m up, where ``ok(eye)`` allows; aimed near (not at) the knob. None
    when 200 draws found no such place."""
    T = prior.T_world_face()
    p = T[:3, 3]
    for _ in range(200):
        cos_a = rng.uniform(math.cos(math.radians(cfg.max_off_axis_deg)), 1.0)
        a = math.acos(cos_a)
        phi = rng.uniform(-math.pi, math.pi)
        d = rng.uniform(*cfg.distance)
        dir_k = np.array([math.sin(a) * math.cos(phi), math.sin(a) * math.sin(phi), cos_a])
        eye = p + d * (T[:3, :3] @ dir_k)
        if 0.25 < eye[2] < 2.0 and (ok is None or ok(eye)):
            # look near the knob, not always straight at it
            side = rng.normal(0, 0.08 * d, 3)
            return look_at(eye, p + side), d, math.degrees(a)
    return None


def search_half_m(prior: KnobPrior, cfg: KnobConfig = KnobConfig()) -> float:
    """Half the side (m, on the face plane) of what the reader looks at around a knob: its
    search region plus the template window."""
    return max(cfg.search_m, cfg.search_radii * prior.radius) + cfg.window_radii * prior.radius


def _crop(K: Intrinsics, T_world_camera, prior: KnobPrior, cfg: KnobConfig, pad: int = 6):
    """The cropped camera that sees the knob's search region (None: not in the image)."""
    h = search_half_m(prior, cfg) * 1.15
    T_cf = np.linalg.inv(T_world_camera) @ prior.T_world_face()
    corners = np.array([[x, y, 0.0, 1.0] for x in (-h, h) for y in (-h, h)]).T
    pc = (T_cf @ corners)[:3]
    if np.any(pc[2] <= 0.05):
        return None
    u = K.fx * pc[0] / pc[2] + K.cx
    v = K.fy * pc[1] / pc[2] + K.cy
    u0, v0 = int(np.floor(u.min())) - pad, int(np.floor(v.min())) - pad
    u1, v1 = int(np.ceil(u.max())) + pad, int(np.ceil(v.max())) + pad
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
        cam = _camera(truth, rng, data, (lambda eye, k=kid: scenes.placeable(k, eye)))
        if cam is None:
            from hearth.perception.errors import PerceptionError
            raise PerceptionError(f"knob {kid}: no place to see it from")
        T_wc, dist, off = cam
        K = _crop(K_full, T_wc, believed, cfg)
        if K is None:
            continue
        r = scenes.scene(owner, angles, () if present else (kid,)).render(K, T_wc)
        if noise is not None:
            # its own generator, so that a noise model drawing more or fewer numbers leaves
            # the views (poses, angles, lighting) of a seed unchanged
            r = noise(r, np.random.default_rng([seed, len(out)])) or r
        out.append(KnobView(photometric(r.color, rng, data), K, T_wc, believed, truth,
                            angles[kid], bool(present), dist, off, states.get(kid, ""),
                            np.asarray(r.depth, dtype=np.float32)))
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
