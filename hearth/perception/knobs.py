"""Knob reading by analysis by synthesis: each knob is rendered as the map describes it, at each
angle it could stand at, from where the camera is, and compared with the image.

RAMCIP D3.1 (5.2.1.2 to 5.2.1.4) detects knobs with HOG + SVM and reads their angle with
models trained on pictures of one knob design; such models read the design they were
trained on and little else. Here nothing is learned about a knob's look: the map gives its
shape (``hearth.worldmodel.nodes.Knob``: base, grip, marker, symmetry; ``knob_shape``), and the
reader asks which angle of that shape explains the pixels around the knob best.

**Rectification.** The region around a knob is warped by a homography of its front-face
plane (the plane z = ``KnobShape.face`` of its frame, from the map's registered or believed
pose) into a *canvas* that shows the plane head-on at a fixed scale (pixels per knob radius),
turned about the knob's axis so that the camera always lies towards canvas-up
(``KnobPrior.canvas_frame``). Seen from a camera centre C, a canvas is the central
projection of the knob onto that plane from C; turning the knob by ``a`` is turning C by
``-a`` about the axis, so in the turned canvas the knob at angle ``a`` looks like the knob at
``a - psi`` seen from the canvas's up side, whatever the azimuth of the view. What it looks
like then depends on that relative angle and on how far off-axis the camera is (theta) only.

**Templates** (``KnobTemplates``, fitted per home from the map's knob shapes: rendering, no
learning): for every shape, off-axis angle (``theta_step_deg`` bins) and relative angle
(``alpha_step_deg`` steps over 360/symmetry degrees), a *label map* of the canvas: which
visual of the knob, and which way its surface faces (front, or a side facing up, left, down
or right in the canvas), each pixel shows, or the background. Rays are parallel (the knob is
small against its distance); the final check renders the exact perspective.

**Scoring.** A label map says which pixels should look alike: the pixels of one label are
one surface under one light. How well an image fits a label map is the share of its colour
variance that the labels explain, R^2 = between-label variance / total variance over the
window, in RGB (so a red tip on a black grip, equal in grey, still tells the angle). It is
blind to gain, offset and the actual colours, so it holds under other lighting, cameras and
renderers, and needs no rendering of colour at all; the colours of the map are not trusted.

**Depth.** Given the registered depth image, the reader also compares the knob's height
above its face plane, as the templates (``ShapeTemplates.heights``) and the exact renderings
give it, with the measured depth (``canvas_heights``; squared correlation, so blind to the
believed plane's height and the depth scale), and adds that fit to the colour's: the knob's
body stands out of its panel whatever its colours, so depth says where a knob without colour
contrast is (its marker alone fits as well flipped by half a turn a radius away), and which
way a protruding grip lies. The centre is then taken from the depth, each candidate angle at
the centre the depth gives the shape at that angle.

**Round bodies** (``round_body_levels``: every visual but the marker a cylinder or disc on
the axis, such as a skirt with a cap, and a marker off the axis no wider than
``dot_max_size`` of its distance from it, ``marker_dot``): the body says nothing of the
angle and, in its panel's colour, only depth says where it is, while a centre a millimetre
off turns a dot 6-11 mm from the axis by 5-9 degrees. So the centre comes from the depth of
the top's rim at the image's own pixels (``body_center``: the measured and the rendered
masks of the top, centroid against centroid) and the angle from the dot's
colour about that centre (``dot_profile``, ``KnobReader._dot_reading``), with a margin in
units of the angle's expected error and state gates of its own (``dot_gates``).

**Reading a knob** (``KnobReader.read``): (1) the canvas at the coarse scale; (2) where the
knob is: the labels averaged over every angle (what the knob looks like whatever its angle)
are fitted at every offset within ``search_m`` of where the map puts it (a soft-label
regression, by correlation), with a Gaussian prior on the offset (the registration error);
(3) the coarse angle: every template of the off-axis bin at that offset and its neighbours;
(4) the best angle and the best angle of the best *other* state are rendered exactly (the
real camera centre, perspective, fixed parts in place) at three angles each, at the fine
scale, scored over small offsets; a parabola through the three gives the angle; (5) the
state: the nearest state to the angle (modulo the symmetry), given only when the fit is
good enough (``detect_gate``: a knob is there), the margin over the best other state is
wide enough (``state_gate`` / ``state_gate_hard`` / ``state_gate_very_hard`` by
``view_level``, calibrated on rendered validation views so that no wrong reading passed
it; an "off" reading needs more; a reading without depth has gates of its own,
``colour_gates``), and the angle lies well inside the state's
half step. Otherwise "unknown", with the reason.

**Half turns.** A knob without symmetry looks much like itself turned by half a turn (the
grip of a pointer or tip mostly coincides), so over the whole window the two fit nearly
alike. The reading is also compared with the exact check nearest its half turn only where
the two renderings differ (``KnobReader._half_turn``), and needs that comparison above a
gate calibrated like the state gate (``half_turn_gates``).

Everything here is pure: images and poses in, readings out. Estimators have the scikit-learn
shape (the constructor stores parameters, ``fit`` returns self, learned attributes end in
``_``, every other method starts with ``check_is_fitted``). Training is
hearth/perception/knob_training.py; storing the models is hearth/worldmodel/model_store.py, asked by
hearth/skills/knob_models.py.

Frames: ``T_world_camera`` maps camera points (OpenCV axes) to the world; a knob's
``T_world_knob`` is its frame at angle 0 (+z out of the panel, angles counter-clockwise about
+z); angles are radians in (-pi, pi].
"""
from __future__ import annotations

import copy
import hashlib
import math
import time
from dataclasses import dataclass, field
from typing import Optional, Sequence

import cv2
import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from hearth.perception import knob_kernels
from hearth.perception.camera import Intrinsics
from hearth.perception.registration import single_threaded_blas
from hearth.perception.trained import read_time, trained_fields

#: Face classes of a label: front (normal along the knob's axis), or a side facing canvas
#: up, left, down, right.
N_FACE = 5
#: Face classes of the exact check's labels: front, then the sides in ``FINE_AZIMUTHS``
#: directions (canvas frame) and two bands of steepness: about one flat face of a primitive,
#: under one light, per label.
FINE_AZIMUTHS = 36
N_FACE_FINE = 1 + 2 * FINE_AZIMUTHS
#: Ray origins of the parallel (template) rays stand this far out along the view (m).
_FAR = 0.5


@dataclass(frozen=True)
class KnobConfig:
    """Trained (part of the stored templates): ``px_per_radius`` (coarse canvas pixels per
    knob radius), ``window_radii`` (the template window's half width, in knob radii),
    ``alpha_step_deg`` / ``theta_step_deg`` / ``max_theta_deg`` (template angle steps and the
    most off-axis bin). Read time: ``fine_px_per_radius`` (the exact check's scale),
    ``search_m`` / ``search_radii`` (how far from where the map puts it the knob is looked
    for: the larger of the two), ``offset_sigma_m`` (the registration error the offset prior
    assumes), ``fine_shift_px`` (offsets tried in the exact check), ``min_radius_px`` (a
    knob smaller in the image is not read), ``max_off_axis_deg``, ``max_snap`` (the angle
    must lie within this share of half a state step of its state), ``off_margin_factor``
    (an "off" reading needs this many times the calibrated margin; one over the margin but
    under this passes every other check gets evidence ``off_one_view``: two of them from
    places apart make the knob off, ``OffViews``), ``off_rival_min`` (an "off" reading must
    explain the pixels where off and the best "on" candidate differ better than that by this
    much: evidence ``off_rival``, not calibrated), ``min_confidence`` (a
    reading less confident than this is "unknown"), ``threshold`` /
    ``margin_threshold`` (override the calibrated gates; None: the fitted ones).
    A knob whose body is round about its axis (``round_body_levels``) with a marker off the
    axis no larger than ``dot_max_size`` of its distance from it: ``round_body_center``
    (its centre from the depth of its rims, ``body_center``), ``dot_angle`` (its angle from
    the marker's colour, ``KnobReader._dot_reading``, with ``dot_noise_floor`` (grey
    levels), ``dot_center_px`` and ``dot_blob_px`` (the expected errors of the centre and of
    the marker, image pixels, the marker's over its contrast to noise) and
    ``dot_dominance_power`` for its margin); such a reading seen more than
    ``dot_max_off_axis_deg`` off the knob's axis gives no state. ``min_relief``: with depth,
    a knob is found only where the depth shows at least this share of its rendered relief
    (evidence ``stands``, ``depth_slope``) within ``relief_sigmas`` standard errors of the
    slope (``stands_se``: what the depth can show of the described relief; a flat knob's is
    wide), and ``max_offset_searches``: only within this
    many search radii of where the map puts it (evidence ``offset``), whatever its fit
    (``not_there``)."""
    px_per_radius: float = 8.0
    window_radii: float = 1.25
    alpha_step_deg: float = 5.0
    theta_step_deg: float = 5.0
    max_theta_deg: float = 70.0
    fine_px_per_radius: float = read_time(12.0)
    search_m: float = read_time(0.014)
    search_radii: float = read_time(0.6)
    offset_sigma_m: float = read_time(0.008)
    offset_weight: float = read_time(0.05)
    align_iterations: int = read_time(5)
    angle_stages: int = read_time(2)
    candidates: int = read_time(3)
    decimate_above_px: float = read_time(16.0)
    min_radius_px: float = read_time(4.0)
    max_off_axis_deg: float = read_time(70.0)
    max_snap: float = read_time(0.7)
    off_margin_factor: float = read_time(1.5)
    min_confidence: float = read_time(0.0)
    angle_span_steps: int = read_time(2)
    fine_ridge_px: float = read_time(0.0)
    depth_weight: float = read_time(1.0)
    depth_settle_radii: float = read_time(0.03)
    round_body_center: bool = read_time(True)
    min_relief: float = read_time(0.45)
    relief_sigmas: float = read_time(2.0)
    off_rival_min: float = read_time(0.1)
    max_offset_searches: float = read_time(1.5)
    dot_angle: bool = read_time(True)
    dot_noise_floor: float = read_time(2.0)
    dot_max_size: float = read_time(0.6)
    dot_center_px: float = read_time(0.25)
    dot_blob_px: float = read_time(1.0)
    dot_dominance_power: float = read_time(3.0)
    dot_max_off_axis_deg: float = read_time(60.0)
    threshold: Optional[float] = read_time(None)
    margin_threshold: Optional[float] = read_time(None)

    def trained_fields(self) -> dict:
        """The fields the templates are made with (the others, declared ``read_time``,
        change how a reader reads and need no refitting)."""
        return trained_fields(self)


# -- knob shapes ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class KnobShape:
    """What the reader knows of a knob's look: its visuals as triangle meshes in the knob
    frame at angle 0 (``vertices`` / ``triangles`` per visual, ``roles`` base/grip/marker,
    ``turns``: False for a fixed base), its outline ``radius`` (m, the farthest point from the
    axis), ``face`` (m, the frontmost z: the canvas plane), its ``symmetry``. ``key``: a
    fingerprint of all of it (knobs of one design share it and their templates)."""
    key: str
    vertices: tuple
    triangles: tuple
    roles: tuple[str, ...]
    turns: tuple[bool, ...]
    radius: float
    face: float
    symmetry: int = 1

    @property
    def period(self) -> float:
        """The angle (rad) after which the shape looks the same again."""
        return 2 * math.pi / self.symmetry


def knob_shape(knob, library: Optional[dict] = None, base_dir=None) -> KnobShape:
    """The ``KnobShape`` of a map ``Knob`` (hearth.worldmodel.geometry ``knob_parts``: the described
    shape, or the plain knob of format 1)."""
    from hearth.worldmodel.geometry import knob_parts, visual_mesh
    verts, tris, roles, turns = [], [], [], []
    for role, v, t in knob_parts(knob, library):
        m = visual_mesh(v, base_dir)
        if len(m.triangles) == 0:
            continue
        verts.append(np.asarray(m.vertices, dtype=np.float64).round(7))
        tris.append(np.asarray(m.triangles, dtype=np.int32))
        roles.append(role)
        turns.append(bool(t))
    if not verts:
        from hearth.perception.errors import PerceptionError
        raise PerceptionError(f"knob {knob.id} has no shape to read")
    allv = np.concatenate(verts)
    radius = float(np.max(np.hypot(allv[:, 0], allv[:, 1])))
    face = float(np.max(allv[:, 2]))
    h = hashlib.sha256()
    for v, t, r, tu in zip(verts, tris, roles, turns):
        h.update(v.tobytes())
        h.update(t.tobytes())
        h.update(f"{r}:{tu}".encode())
    h.update(str(int(knob.symmetry)).encode())
    return KnobShape(h.hexdigest()[:16], tuple(verts), tuple(tris), tuple(roles), tuple(turns),
                     radius, face, int(knob.symmetry))


class _Caster:
    """Ray casting against one shape: a scene of its turning visuals and one of its fixed
    ones (open3d's Embree scenes; built on first use, not pickled), with each triangle's
    visual, normal azimuth (about the knob's axis) and steepness."""

    def __init__(self, shape: KnobShape):
        import open3d as o3d
        self.o3d = o3d
        self.scenes, self.first, self.az, self.nz, self.part = [], [], [], [], []
        self.bounds = []
        for turning in (True, False):
            scene = o3d.t.geometry.RaycastingScene()
            first, az, nz, part, corners = [], [], [], [], []
            count = 0
            for i, (v, t, tu) in enumerate(zip(shape.vertices, shape.triangles, shape.turns)):
                if tu != turning:
                    continue
                v32 = v.astype(np.float32).astype(np.float64)
                corners += [v32.min(0), v32.max(0)]
                mesh = o3d.t.geometry.TriangleMesh()
                mesh.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
                mesh.triangle.indices = o3d.core.Tensor(t)
                scene.add_triangles(mesh)
                n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
                n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
                first.append(count)
                az.append(np.arctan2(-n[:, 0], n[:, 1]))      # 0: facing +y, +pi/2: facing -x
                nz.append(np.abs(n[:, 2]))
                part.append(np.full(len(t), i, dtype=np.int64))
                count += len(t)
            self.scenes.append(scene if count else None)
            # the scene's bounding box (the vertices as the scene holds them), padded by 0.1 mm
            # so that no rounding drops a ray that grazes it (``knob_kernels.turn_rays_near_box``)
            pad = 1e-4
            self.bounds.append((np.min(corners, 0) - pad, np.max(corners, 0) + pad) if count else None)
            self.first.append(np.array(first + [count], dtype=np.int64))
            self.az.append(np.concatenate(az + [np.zeros(1)]))
            self.nz.append(np.concatenate(nz + [np.zeros(1)]))
            self.part.append(np.concatenate(part + [np.zeros(1, np.int64)]))

    def _cast(self, k: int, origins: np.ndarray, dirs: np.ndarray, turns: np.ndarray) -> tuple:
        """Scene ``k``'s hits of the rays ``origins``, ``dirs`` (``labels``' broadcast forms)
        turned back by each of ``turns`` into the visuals' frame: of the rays that can reach
        the scene's bounding box (``knob_kernels.turn_rays_near_box``; the others hit
        nothing, and each ray is cast alone, so the hits are those of casting all), their
        indices (b * N + n), t (inf: nothing), geometry and primitive ids."""
        M = len(turns) * dirs.shape[1]
        rays = np.empty((M, 6), np.float32)
        keep = np.empty(M, np.int64)
        m = knob_kernels.turn_rays_near_box(origins, dirs, np.cos(turns), np.sin(turns),
                                            *self.bounds[k], rays, keep)
        keep = keep[:m]
        if not m:
            return keep, np.empty(0, np.float32), np.empty(0, np.uint32), np.empty(0, np.uint32)
        # one thread: a few thousand rays a call, and Embree's threads cost more CPU than
        # they save (a pointer reading 9.6 -> 9.1 ms CPU, its wall time the same to the noise)
        ans = self.scenes[k].cast_rays(self.o3d.core.Tensor.from_numpy(rays[:m]), nthreads=1)
        return (keep, np.array(ans["t_hit"].numpy()), np.array(ans["geometry_ids"].numpy()),
                np.array(ans["primitive_ids"].numpy()))

    def labels(self, origins: np.ndarray, dirs: np.ndarray, turns: np.ndarray, fixed_turn: float,
               fine: bool = False, with_t: bool = False, cache: Optional[dict] = None):
        """Labels (uint16, 0 = nothing) of rays given in the canvas frame with the knob's
        origin at the canvas origin, for each of ``turns`` (B,): the turning visuals turned
        by it (rad, counter-clockwise about +z), the fixed ones by ``fixed_turn``.
        ``origins`` (3,) or (B, N, 3), ``dirs`` (N, 3) or (B, N, 3). The label is
        1 + visual * classes + face class, the face class from the normal turned into the
        canvas: front (along the axis), else which way it faces (4 sides, or with ``fine``
        ``FINE_AZIMUTHS`` directions in two bands of steepness). With ``with_t``: also the
        ray parameter of each hit (B, N) (inf where nothing is hit). ``cache``: a dict kept
        by a caller that casts the same rays (one window's) at the same ``fixed_turn`` again
        and again: the fixed visuals' hits are cast once into it and reused (the same hits,
        so the same labels)."""
        turns = np.atleast_1d(np.asarray(turns, dtype=float))
        B = len(turns)
        # rays the same for every turn: the fixed visuals' hits are the same for all of them
        # (cast once)
        same_rays = np.ndim(dirs) == 2 and np.ndim(origins) <= 2
        d3 = np.asarray(dirs, dtype=np.float64)
        d3 = d3.reshape((1,) + d3.shape) if d3.ndim == 2 else d3
        N = d3.shape[1]
        # one origin for every ray (the camera centre): (1, 1, 3), else (B, N, 3)
        o3 = np.asarray(origins, dtype=np.float64)
        o3 = o3.reshape(1, 1, 3) if o3.ndim == 1 else o3.reshape((-1,) + o3.shape[-2:])
        best_t = np.full((B, N), np.inf)
        label = np.zeros((B, N), dtype=np.uint16)
        classes = N_FACE_FINE if fine else N_FACE
        for k, scene in enumerate(self.scenes):
            if scene is None:
                continue
            a = turns if k == 0 else np.full(B, float(fixed_turn))
            once = k == 1 and same_rays
            Bc = 1 if once else B
            # into the visuals' frame: turn the rays back by a (compiled, numpy's operations:
            # hearth/perception/knob_kernels.py)
            hits = cache.get("fixed") if (once and cache is not None) else None
            if hits is None:
                hits = self._cast(k, o3, d3, a[:Bc])
                if once and cache is not None:
                    cache["fixed"] = hits
            # the nearer hits' labels: each triangle's face class for each turn, per hit
            knob_kernels.nearest_labels(
                *hits, Bc, self.first[k], self.az[k],
                self.nz[k], self.part[k], a, fine, classes, FINE_AZIMUTHS,
                2 * math.pi / FINE_AZIMUTHS, math.pi / 2, label, best_t)
        return (label, best_t) if with_t else label


def _canvas_points(n: int, px_per_m: float, center=(0.0, 0.0)) -> np.ndarray:
    """(n*n, 2) canvas-plane points (m) of an n x n canvas's pixel centres, row-major; canvas
    right = +x, canvas up = +y, its centre pixel at ``center``."""
    c = (n - 1) / 2.0
    jj, ii = np.meshgrid(np.arange(n), np.arange(n))
    return np.stack([(jj.ravel() - c) / px_per_m + center[0],
                     -(ii.ravel() - c) / px_per_m + center[1]], -1)


# -- templates -------------------------------------------------------------------------------------

@dataclass
class ShapeTemplates:
    """One shape's templates: ``labels`` (T, A, n, n) uint8 label maps per off-axis bin and
    relative angle (``alphas``, rad, over one period), ``counts`` (T, A, L) pixels per label,
    ``soft`` (T, L, n, n) the label maps averaged over the angles and ``gram_inv`` (T, L, L)
    the pseudo-inverse of their Gram matrix (the offset search's regression)."""
    labels: np.ndarray
    counts: np.ndarray
    soft: np.ndarray
    gram_inv: np.ndarray
    alphas: np.ndarray
    thetas: np.ndarray
    n_labels: int
    #: (T, A, n, n) float32: the height (m) of what each canvas pixel shows above the face
    #: plane (<= 0: the knob's front at 0, the panel at -face), what a depth image shows
    heights: Optional[np.ndarray] = None


class KnobTemplates(BaseEstimator):
    """Label-map templates of knob shapes (module docstring). ``fit(shapes)`` renders them
    (parallel rays at each bin's off-axis angle); nothing is learned. ``templates_``: shape
    key -> ShapeTemplates; ``shapes_``: shape key -> KnobShape."""

    def __init__(self, px_per_radius: float = 8.0, window_radii: float = 1.25,
                 alpha_step_deg: float = 5.0, theta_step_deg: float = 5.0,
                 max_theta_deg: float = 70.0):
        self.px_per_radius = px_per_radius
        self.window_radii = window_radii
        self.alpha_step_deg = alpha_step_deg
        self.theta_step_deg = theta_step_deg
        self.max_theta_deg = max_theta_deg

    @property
    def window_px(self) -> int:
        """Side of a template (pixels)."""
        return 2 * int(math.ceil(self.window_radii * self.px_per_radius)) + 1

    def fit(self, shapes: Sequence[KnobShape], y=None):
        self.shapes_ = {}
        self.templates_ = {}
        for s in shapes:
            if s.key not in self.templates_:
                self.shapes_[s.key] = s
                self.templates_[s.key] = self._render(s)
        return self

    def _render(self, shape: KnobShape) -> ShapeTemplates:
        caster = _Caster(shape)
        n = self.window_px
        rho = self.px_per_radius / shape.radius
        q = _canvas_points(n, rho)
        n_alpha = max(1, int(round(360.0 / shape.symmetry / self.alpha_step_deg)))
        alphas = np.arange(n_alpha) * (shape.period / n_alpha)
        thetas = np.radians(np.arange(0.0, self.max_theta_deg + 1e-9, self.theta_step_deg))
        L = 1 + len(shape.roles) * N_FACE
        labels = np.zeros((len(thetas), n_alpha, n, n), np.uint8)
        heights = np.zeros((len(thetas), n_alpha, n, n), np.float32)
        for ti, th in enumerate(thetas):
            v = np.array([0.0, math.sin(th), math.cos(th)])     # towards the camera
            origins = np.empty((len(q), 3))
            origins[:, :2] = q + _FAR * v[:2]
            origins[:, 2] = shape.face + _FAR * v[2]            # knob origin at z = -face
            dirs = np.broadcast_to(-v, origins.shape)
            lab, t = caster.labels(origins, dirs, alphas, 0.0, with_t=True)
            labels[ti] = lab.reshape(n_alpha, n, n)
            # the hit's height above the face plane; no hit: the panel (z = 0 of the knob)
            z = origins[None, :, 2] - t * v[2]
            heights[ti] = np.where(np.isfinite(t), z - shape.face, -shape.face).reshape(n_alpha, n, n)
        counts = np.stack([np.stack([np.bincount(labels[t, a].ravel(), minlength=L)
                                     for a in range(n_alpha)]) for t in range(len(thetas))])
        onehot = (labels[..., None] == np.arange(L)).mean(1)          # (T, n, n, L)
        soft = np.moveaxis(onehot, -1, 1).astype(np.float32)          # (T, L, n, n)
        flat = soft.reshape(len(thetas), L, -1).astype(np.float64)
        gram_inv = np.stack([np.linalg.pinv(f @ f.T, rcond=1e-6, hermitian=True) for f in flat])
        return ShapeTemplates(labels, counts.astype(np.float32), soft, gram_inv.astype(np.float32),
                              alphas, thetas, L, heights)

    def bin_of(self, theta: float) -> int:
        check_is_fitted(self)
        return int(min(round(math.degrees(theta) / self.theta_step_deg),
                       round(self.max_theta_deg / self.theta_step_deg)))


class CalibratedThreshold(BaseEstimator, ClassifierMixin):
    """A one-feature classifier: ``predict(X)`` is X[:, 0] > ``threshold_``. ``fit(X, y)``
    chooses the threshold on validation readings: ``objective="fewest_errors"`` the middle of
    the lowest step of (positives at or under it) + (negatives over it), as far from both
    kinds of error as the validation set allows (down to ``floor`` where no negative lies
    under the positives); ``"no_false_accepts"`` just above the
    highest negative (times ``safety``, and at least ``floor``), so that no negative of the
    validation set passes."""

    def __init__(self, objective: str = "fewest_errors", safety: float = 1.0, floor: float = 0.0):
        self.objective = objective
        self.safety = safety
        self.floor = floor

    def fit(self, X, y):
        x = np.asarray(X, dtype=float).reshape(len(X), -1)[:, 0]
        y = np.asarray(y).astype(bool)
        pos, neg = np.sort(x[y]), np.sort(x[~y])
        if self.objective == "no_false_accepts":
            top = float(neg[-1]) if len(neg) else self.floor
            t = max(self.floor, top * self.safety if top > 0 else top)
        elif self.objective == "fewest_errors":
            cuts = np.unique(np.concatenate([pos, neg]))
            if len(cuts) == 0:
                t = self.floor
            else:
                # the lowest cut at the floor: with no negative under the positives (the
                # relief check took them all) the step runs from the floor to the lowest
                # positive, not to just under it
                low = [self.floor] if self.floor < cuts[0] - 1e-3 else []
                cand = np.concatenate([low, [cuts[0] - 1e-3], (cuts[:-1] + cuts[1:]) / 2,
                                       [cuts[-1] + 1e-3]])
                err = np.searchsorted(pos, cand, side="right") + (len(neg) - np.searchsorted(neg, cand, side="right"))
                best = np.flatnonzero(err == err.min())
                run = best[:np.argmax(np.diff(np.append(best, best[-1] + 2)) > 1) + 1]
                t = float((cand[run[0]] + cand[run[-1]]) / 2)
        else:
            raise ValueError(f"objective must be fewest_errors or no_false_accepts, not {self.objective!r}")
        self.threshold_ = float(t)
        self.classes_ = np.array([0, 1])
        self.n_features_in_ = 1
        self.validation_ = dict(positives=int(len(pos)), negatives=int(len(neg)),
                                positives_passed=int((pos > t).sum()),
                                negatives_passed=int((neg > t).sum()))
        return self

    def decision_function(self, X) -> np.ndarray:
        check_is_fitted(self)
        return np.asarray(X, dtype=float).reshape(len(X), -1)[:, 0] - self.threshold_

    def predict(self, X) -> np.ndarray:
        return (self.decision_function(X) > 0).astype(int)


# -- the knobs the map knows --------------------------------------------------------------------

@dataclass(frozen=True)
class KnobPrior:
    """What the map says of one knob: its frame at angle 0 in the world (registered or
    believed), its outline radius and face height (m, from its shape), its discrete states
    (names, angles in rad), its shape's key and symmetry, and its travel (``(lo, hi)`` rad:
    the angles it can stand at, from its off state through its settings the way it turns;
    None: any)."""
    knob_id: str
    T_world_knob: np.ndarray
    radius: float
    depth: float
    state_names: tuple[str, ...]
    state_angles: tuple[float, ...]
    shape: str = ""
    symmetry: int = 1
    travel: Optional[tuple[float, float]] = None
    off_state: str = ""
    #: what of the knob stands at every angle (``standing_profile``): ((radius, top height)
    #: m, ...) per visual but the markers; () unknown (a cylinder of the outline assumed)
    profile: tuple = ()
    #: the knob's body is ridged and otherwise round about its axis (``near_round``: a
    #: knurl): only its marker says its angle, and its ridges fit well at other angles
    round_grip: bool = False

    def T_world_face(self) -> np.ndarray:
        """The knob's front face (z = depth) at angle 0."""
        T = self.T_world_knob.copy()
        T[:3, 3] = T[:3, 3] + T[:3, 2] * self.depth
        return T

    def canvas_frame(self, T_world_camera: np.ndarray, aligned: bool = True) -> tuple[np.ndarray, float]:
        """The face frame turned by ``psi`` about the knob's axis so that its +y points towards
        the camera (projected on the face plane), and ``psi`` (rad); (face frame, 0) when not
        ``aligned``. A marker at knob angle a is at a - psi in this frame."""
        T = self.T_world_face()
        if not aligned:
            return T, 0.0
        v = T_world_camera[:3, 3] - T[:3, 3]
        ux, uy = float(T[:3, 0] @ v), float(T[:3, 1] @ v)
        if math.hypot(ux, uy) < 1e-9:
            return T, 0.0
        psi = math.atan2(-ux, uy)
        R = np.eye(4)
        c, s = math.cos(psi), math.sin(psi)
        R[:2, :2] = [[c, -s], [s, c]]
        return T @ R, psi


def knob_travel(knob) -> Optional[tuple[float, float]]:
    """The angles (rad, ``lo <= hi``) a knob that turns one way (``Knob.turns``) can stand
    at: from its off state through every setting that way; None for one that turns either
    way (or a symmetric one whose travel covers its period)."""
    if knob.turns == "either":
        return None
    sign = -1.0 if knob.turns == "clockwise" else 1.0
    off = knob.state_angle(knob.off)
    reach = max(((sign * (s.angle - off)) % (2 * math.pi)) for s in knob.states)
    if reach >= 2 * math.pi / knob.symmetry - 1e-9:
        return None
    lo, hi = sorted((off, off + sign * reach))
    return lo, hi


def knob_priors(world, object_id: Optional[str] = None,
                T_world_object: Optional[np.ndarray] = None) -> list[KnobPrior]:
    """Priors of every knob in the map (or of one object's knobs). ``T_world_object``: the
    object's registered pose, when it differs from the map's."""
    out = []
    lib = world.apartment.library
    for k in world.knobs(object_id):
        T_wp = world.T_world(world.parent(k.id).id)
        if T_world_object is not None and object_id is not None:
            T_wp = T_world_object @ np.linalg.inv(world.T_world(object_id)) @ T_wp
        s = _shape_of(k, lib, world.base_dir)
        out.append(KnobPrior(k.id, T_wp @ k.pose.matrix(), s.radius, s.face,
                             tuple(x.name for x in k.states), tuple(float(x.angle) for x in k.states),
                             s.key, s.symmetry, knob_travel(k), k.off, standing_profile(s),
                             near_round(s)))
    return out


def near_round(shape: KnobShape, tol: float = 0.1) -> bool:
    """Whether a knob's body (every visual but the markers) is ridged and otherwise round
    about its axis: within ``tol`` of its outline radius at every height, and more than 2 %
    off a circle somewhere (a knurled ring, its ridges a few per cent deep). Its angle rests
    on its marker alone, a small part of the knob, while its ridges fit well every 12-22
    degrees, away from the marker's angle. A plain cylinder or a taper (round within 2 %)
    is not such a knob (its body fits alike at every angle: the marker decides), nor is a
    symmetric shape or one without a marker."""
    if shape.symmetry != 1 or "marker" not in shape.roles:
        return False
    ridged = False
    for v, role in zip(shape.vertices, shape.roles):
        if role == "marker":
            continue
        for z in np.unique(np.round(v[:, 2], 4)):
            ring = v[np.abs(v[:, 2] - z) < 5e-5]
            rad = np.hypot(ring[:, 0], ring[:, 1])
            rim = rad > 0.5 * rad.max()
            if not rim.any():
                continue
            if (np.ptp(rad[rim]) > tol * shape.radius or abs(ring[rim, 0].mean()) > tol * shape.radius
                    or abs(ring[rim, 1].mean()) > tol * shape.radius):
                return False
            ridged |= bool(np.ptp(rad[rim]) > 0.02 * shape.radius)
    return ridged


def standing_profile(shape: KnobShape) -> tuple:
    """What of a knob stands out of its panel whatever its angle: for each visual but the
    markers, the radius of the largest disc about the axis inside its outline on the face
    plane (a round cap's rim, a bar's half width, 0 where the visual does not cover the axis)
    and its top's height (m). A bar grip 8 mm wide on a 2 mm bezel stands 4 mm about the axis
    at its full height and over the whole bezel 2 mm: the knob panel's match looks for that,
    not for a cylinder of the outline (knob_panel)."""
    from scipy.spatial import ConvexHull, QhullError
    out = []
    for v, role in zip(shape.vertices, shape.roles):
        if role == "marker" or len(v) < 3:
            continue
        xy = np.asarray(v[:, :2], dtype=float)
        try:
            P = xy[ConvexHull(xy).vertices]
        except (QhullError, ValueError):
            continue
        E = np.roll(P, -1, axis=0) - P
        cross = E[:, 0] * (-P[:, 1]) - E[:, 1] * (-P[:, 0])      # origin left of every edge: inside
        L = np.hypot(E[:, 0], E[:, 1])
        ok = L > 1e-9
        inside = bool(np.all(cross[ok] >= -1e-9))
        r_in = float(np.min(np.abs(cross[ok]) / L[ok])) if inside and ok.any() else 0.0
        out.append((round(r_in, 5), round(float(v[:, 2].max()), 5)))
    return tuple(out)


_SHAPES: dict = {}


def canon(value, drop: frozenset = frozenset()):
    """A JSON-able, rounded copy of map nodes (dataclasses) without ``line`` fields, and
    without the fields of ``value`` itself named in ``drop``."""
    from dataclasses import fields, is_dataclass
    if is_dataclass(value):
        return {f.name: canon(getattr(value, f.name)) for f in fields(value)
                if f.name != "line" and f.name not in drop}
    if isinstance(value, (list, tuple)):
        return [canon(v) for v in value]
    if isinstance(value, float):
        return round(value, 6)
    return value


def _shape_of(knob, library, base_dir) -> KnobShape:
    """``knob_shape``, cached by what it is made of (a map's knobs are read again and again)."""
    key = repr((canon([knob.radius, knob.depth, knob.base, knob.grip, knob.marker,
                        knob.base_fixed, knob.symmetry, knob.described]),
                canon([library.get(m.ref) for m in (knob.base, knob.grip, knob.marker)
                        if m is not None and m.ref]), str(base_dir)))
    if key not in _SHAPES:
        if len(_SHAPES) > 256:
            _SHAPES.clear()
        _SHAPES[key] = knob_shape(knob, library, base_dir)
    return _SHAPES[key]


# -- rectification ---------------------------------------------------------------------------------

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


# -- scoring ---------------------------------------------------------------------------------------

def _box_sum(img: np.ndarray, n: int) -> np.ndarray:
    """Sums over every n x n window (valid positions) of a 2-D float image."""
    ii = cv2.integral(img.astype(np.float64))
    return ii[n:, n:] - ii[:-n, n:] - ii[n:, :-n] + ii[:-n, :-n]


def _windows(img: np.ndarray, n: int) -> np.ndarray:
    """Every n x n window (valid positions, row-major) of a 2-D image, or of each channel of
    a 3-D one, as the rows of a matrix: (h * w, n * n) or (h * w * channels, n * n), so that
    one BLAS product correlates many templates with the image at every position (what one
    ``cv2.matchTemplate`` call per template and channel did, a call costing more than its
    sums on a canvas this small)."""
    from numpy.lib.stride_tricks import sliding_window_view
    win = sliding_window_view(img, (n, n), axis=(0, 1))           # (h, w[, c], n, n)
    return np.ascontiguousarray(win).reshape(-1, n * n)


def offset_scores(canvas: np.ndarray, soft: np.ndarray, gram_inv: np.ndarray) -> np.ndarray:
    """R^2 of the soft-label regression of the RGB ``canvas`` (H, W, 3) float32 on ``soft``
    (L, n, n) label maps at every valid window position: (H - n + 1, W - n + 1)."""
    L, n, _ = soft.shape
    N = n * n
    keep = np.flatnonzero(np.diag(gram_inv) > 0)
    chans = [np.ascontiguousarray(canvas[..., ch]) for ch in range(3)]
    h, w = canvas.shape[0] - n + 1, canvas.shape[1] - n + 1
    # each label's map correlated with each channel at every offset, one product
    b = (_windows(canvas, n) @ soft[keep].reshape(len(keep), N).T).reshape(h, w, 3, len(keep))
    b = b.transpose(3, 2, 0, 1)                                        # (L', 3, h, w)
    G = gram_inv[np.ix_(keep, keep)]
    explained = np.einsum("lchw,lm,mchw->hw", b, G, b)
    sums = np.stack([_box_sum(c, n) for c in chans])
    sq = sum(_box_sum(c * c, n) for c in chans)
    mean_part = (sums ** 2).sum(0) / N
    tv = sq - mean_part
    return np.where(tv > 1e-6 * N, (explained - mean_part) / np.maximum(tv, 1e-9), 0.0)


def measured_sums(height: np.ndarray, valid: np.ndarray, n: int) -> tuple:
    """What ``depth_offset_scores`` needs of a measured height map whatever the template
    (n x n): the windows (``_windows``) of the weights and of the heights (mm about their
    median, 0 where not valid), and their box sums. Made once per canvas: a reading
    correlates several templates with it."""
    w = valid.astype(np.float32)
    ref = float(np.median(height[valid])) if valid.any() else 0.0
    hw = np.where(valid, (height - ref) * 1000.0, 0.0).astype(np.float32)      # mm
    return _windows(w, n), _windows(hw, n), _box_sum(w, n), _box_sum(hw, n), _box_sum(hw * hw, n)


def depth_offset_scores(height: np.ndarray, valid: np.ndarray, template: np.ndarray,
                        min_valid: float = 0.5, sums: Optional[tuple] = None) -> np.ndarray:
    """Squared correlation (with a positive slope; 0 otherwise) between a measured height map
    (H, W) (m above the face plane, only where ``valid``) and a template height map (n, n) at
    every valid window position: (H - n + 1, W - n + 1). Correlation, so that an error of the
    believed plane's height (registration) or of the depth scale does not matter; windows with
    fewer than ``min_valid`` of their pixels measured score 0. Masked correlation is not one
    of OpenCV's matchTemplate modes: the masked sums are written out, as products of the
    map's windows (``_windows``) with the template. ``sums``: ``measured_sums`` of the same
    map, when made already."""
    n = template.shape[0]
    N = n * n
    Pw, Ph, Sw, Sh, Shh = sums if sums is not None else measured_sums(height, valid, n)
    t = ((template - template.mean()) * 1000.0).astype(np.float32).ravel()
    shape = Sw.shape
    St = (Pw @ t).reshape(shape).astype(np.float64)
    Stt = (Pw @ (t * t)).reshape(shape).astype(np.float64)
    Sht = (Ph @ t).reshape(shape).astype(np.float64)
    Swc = np.maximum(Sw, 1.0)
    cov = Sht - Sh * St / Swc
    vh = Shh - Sh * Sh / Swc
    vt = Stt - St * St / Swc
    ok = (Sw >= min_valid * N) & (cov > 0) & (vh > 1e-9) & (vt > 1e-9)
    return np.where(ok, cov * cov / np.maximum(vh * vt, 1e-12), 0.0)


def measured_heights(heights: np.ndarray, valid: np.ndarray) -> tuple:
    """What ``depth_scores`` needs of measured heights (P, N) whatever the templates: the
    weights, the heights (mm, 0 where not valid) weighted, the count of valid pixels (at
    least 1), the sums of the heights and of their squares, and the count itself. An exact
    check's window makes them once for all its renderings (``knob_kernels.depth_fits``)."""
    W = valid.astype(np.float64)
    m = np.where(valid, heights, 0.0).astype(np.float64) * 1000.0
    Wm = W * m
    return (W, Wm, np.maximum(W.sum(1), 1.0)[:, None], Wm.sum(1)[:, None],
            (W * m * m).sum(1)[:, None], W.sum(1)[:, None])


#: the share of a window's pixels with a measured depth that ``depth_scores`` needs
DEPTH_MIN_VALID = 0.5


def depth_scores(heights: np.ndarray, valid: np.ndarray, templates: np.ndarray,
                 min_valid: float = DEPTH_MIN_VALID) -> np.ndarray:
    """Squared correlation (positive slope, else 0) of measured heights ``heights`` (P, N)
    (valid where ``valid``) with template heights ``templates`` (A, N): (P, A)."""
    W, Wm, Sw, Sm, Smm, count = measured_heights(heights, valid)
    T = templates.astype(np.float64) * 1000.0
    T = T - T.mean(1, keepdims=True)
    St = W @ T.T
    Stt = W @ (T * T).T
    Smt = Wm @ T.T
    cov = Smt - Sm * St / Sw
    vm = Smm - Sm * Sm / Sw
    vt = Stt - St * St / Sw
    ok = (count >= min_valid * W.shape[1]) & (cov > 0) & (vm > 1e-9) & (vt > 1e-9)
    return np.where(ok, cov * cov / np.maximum(vm * vt, 1e-12), 0.0)


def not_there(evidence: dict, config: "KnobConfig") -> Optional[str]:
    """Why a reading is no knob in its region whatever its fit (None: it may be one): its
    depth shows less than ``KnobConfig.min_relief`` of the knob's relief (evidence
    ``stands``; a reading without depth has none and is not judged by it), or it stands more than
    ``max_offset_searches`` search radii from where the map puts the knob (``offset``, in
    search radii: a round body's centre follows the depth's tops, and with the knob gone
    it walked to a packed neighbour's)."""
    stands, se = evidence.get("stands"), evidence.get("stands_se") or 0.0
    if stands is not None and stands + config.relief_sigmas * se < config.min_relief:
        return (f"its depth shows {100 * stands:.0f} % (+- {100 * se:.0f}) of a knob's relief, "
                f"needs {100 * config.min_relief:.0f} %")
    if evidence.get("offset") is not None and evidence["offset"] > config.max_offset_searches:
        return (f"the best fit stands {evidence['offset']:.1f} search radii from where the map "
                f"puts it, at most {config.max_offset_searches:.1f}")
    return None


def depth_slope(heights: np.ndarray, valid: np.ndarray, template: np.ndarray,
                min_valid: float = DEPTH_MIN_VALID) -> Optional[float]:
    """The least-squares slope of measured heights ``heights`` (N,) (valid where ``valid``)
    on a rendering's heights ``template`` (N,): how much of the rendered knob's relief the
    depth shows (near 1 where the knob stands, near 0 over a bare panel; the correlation
    ``depth_scores`` fits is blind to the scale). None with too few valid pixels or a flat
    rendering."""
    v = valid.ravel()
    if v.mean() < min_valid:
        return None
    m = heights.ravel()[v].astype(np.float64)
    t = template.ravel()[v].astype(np.float64)
    t = t - t.mean()
    vt = float(t @ t)
    return None if vt < 1e-12 else float(t @ (m - m.mean())) / vt


def depth_slope_se(heights: np.ndarray, valid: np.ndarray, template: np.ndarray,
                   min_valid: float = DEPTH_MIN_VALID) -> Optional[tuple[float, float]]:
    """``depth_slope`` and its standard error (from the fit's residuals: the depth's noise
    over how much relief the rendering has where it is measured). A knob whose described
    relief is low (a flat disc 1 mm proud, a thin fin a pixel or two wide) has a slope the
    depth cannot pin, and the error says by how much; None as ``depth_slope``."""
    v = valid.ravel()
    if v.mean() < min_valid or v.sum() < 4:
        return None
    m = heights.ravel()[v].astype(np.float64)
    t = template.ravel()[v].astype(np.float64)
    t = t - t.mean()
    vt = float(t @ t)
    if vt < 1e-12:
        return None
    mc = m - m.mean()
    slope = float(t @ mc) / vt
    resid = mc - slope * t
    se = math.sqrt(float(resid @ resid) / max(len(m) - 2, 1) / vt)
    return slope, se


def _onehot(labels: np.ndarray, n_labels: int):
    """The (A * L, N) sparse one-hot matrix of label maps ``labels`` (A, N) (``label_scores``)."""
    from scipy.sparse import csr_matrix
    A, N = labels.shape
    rows = (np.arange(A)[:, None] * n_labels + labels.astype(np.int64)).ravel()
    cols = np.tile(np.arange(N), A)
    return csr_matrix((np.ones(len(rows), np.float32), (rows, cols)), shape=(A * n_labels, N))


_ONEHOT: dict = {}


def template_onehot(tpl: "ShapeTemplates", ti: int):
    """``_onehot`` of a shape's templates in off-axis bin ``ti``, made once (the same matrix
    every time a knob of that shape is read; the cache holds the templates it was made of)."""
    key = (id(tpl.labels), ti)
    got = _ONEHOT.get(key)
    if got is None or got[0] is not tpl.labels:
        if len(_ONEHOT) > 512:
            _ONEHOT.clear()
        got = _ONEHOT[key] = (tpl.labels, _onehot(tpl.labels[ti].reshape(len(tpl.alphas), -1),
                                                  tpl.n_labels))
    return got[1]


def label_scores(patches: np.ndarray, labels: np.ndarray, counts: np.ndarray, n_labels: int,
                 onehot=None) -> np.ndarray:
    """R^2 of piecewise-constant fits: ``patches`` (P, N, 3) pixel colours, ``labels`` (A, N)
    label maps, ``counts`` (A, L) pixels per label. Returns (P, A). ``onehot``: the labels'
    ``_onehot`` when made already (``template_onehot``)."""
    P, N, _ = patches.shape
    A = labels.shape[0]
    if onehot is None:
        onehot = _onehot(labels, n_labels)
    X = np.ascontiguousarray(np.moveaxis(patches, 0, 1).reshape(N, P * 3), dtype=np.float32)
    sums = np.asarray(onehot @ X).reshape(A, n_labels, P, 3)
    inv_n = np.where(counts > 0, 1.0 / np.maximum(counts, 1), 0.0)            # (A, L)
    bcv = np.einsum("alpc,al->pa", sums.astype(np.float64) ** 2, inv_n)
    total = patches.sum(1)                                                    # (P, 3)
    mean_part = (total ** 2).sum(1) / N
    tv = (patches.astype(np.float64) ** 2).sum((1, 2)) - mean_part
    bcv -= mean_part[:, None]
    return np.where(tv[:, None] > 1e-6 * N, bcv / np.maximum(tv, 1e-9)[:, None], 0.0)


def _depth_center(hc, hv, template, cell, inside, off, rho, reach: int = 2, min_fit: float = 0.3,
                  sums: Optional[tuple] = None):
    """The canvas offset (m, canvas frame) where ``template`` (heights, n x n) fits the
    measured heights best, within ``reach`` canvas pixels of ``cell`` (row, column of the
    offset grid ``off``) and inside the search region, refined by a parabola through its
    neighbours in each direction; None when the best fit is under ``min_fit``. ``sums``:
    ``measured_sums`` of the heights."""
    d = depth_offset_scores(hc, hv, template, sums=sums)
    ci, cj = cell
    d = np.where(inside, d, -np.inf)
    i0, i1 = max(ci - reach, 0), min(ci + reach + 1, d.shape[0])
    j0, j1 = max(cj - reach, 0), min(cj + reach + 1, d.shape[1])
    sub = d[i0:i1, j0:j1]
    k = int(np.argmax(sub))
    i, j = i0 + k // sub.shape[1], j0 + k % sub.shape[1]
    if not np.isfinite(d[i, j]) or d[i, j] < min_fit:
        return None

    def vertex(a, b, c):
        den = a - 2 * b + c
        if not (np.isfinite(a) and np.isfinite(c)) or den >= 0:
            return 0.0
        return float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))

    di = vertex(d[i - 1, j], d[i, j], d[i + 1, j]) if 0 < i < d.shape[0] - 1 else 0.0
    dj = vertex(d[i, j - 1], d[i, j], d[i, j + 1]) if 0 < j < d.shape[1] - 1 else 0.0
    return (float(off[j] + dj / rho), float(-(off[i] + di / rho)))


def _candidates(curve: np.ndarray, allowed: np.ndarray, state_of: np.ndarray, k: int) -> list[int]:
    """Indices of the ``k`` best local maxima of a circular score curve among the allowed
    angles, best first, and the best allowed angle of another state than the first when
    none of them is of one (the runner-up the margin is measured against)."""
    c = np.where(allowed, curve, -np.inf)
    peaks = np.flatnonzero(np.isfinite(c) & (c >= np.roll(c, 1)) & (c >= np.roll(c, -1)))
    peaks = peaks[np.argsort(-c[peaks], kind="stable")]             # best first, ties in order
    picks = [int(i) for i in peaks[:k]] or [int(np.argmax(c))]
    if all(state_of[i] == state_of[picks[0]] for i in picks):
        others = np.flatnonzero(allowed & (state_of != state_of[picks[0]]))
        if len(others):
            picks.append(int(others[np.argmax(curve[others])]))
    return picks


def _states_of(prior: "KnobPrior", angles: np.ndarray) -> np.ndarray:
    """Index of the nearest state (modulo the period) of each angle (rad)."""
    period = 2 * math.pi / max(1, prior.symmetry)
    a = np.asarray(prior.state_angles)
    d = np.abs(np.remainder(a[None, :] - np.asarray(angles)[:, None] + period / 2, period) - period / 2)
    return np.argmin(d, 1)


def _next_state(prior: "KnobPrior", angle: float, state: str) -> tuple[Optional[str], float]:
    """The state other than ``state`` whose angle (modulo the period) lies nearest to
    ``angle`` (rad), and that angle taken to the side of ``angle`` (None: no other state)."""
    period = 2 * math.pi / max(1, prior.symmetry)
    best, best_d, best_a = None, math.inf, 0.0
    for name, a in zip(prior.state_names, prior.state_angles):
        if name == state:
            continue
        d = (a - angle + period / 2) % period - period / 2
        if abs(d) < best_d:
            best, best_d, best_a = name, abs(d), angle + d
    return best, best_a


def _wrap(a):
    return np.remainder(np.asarray(a) + np.pi, 2 * np.pi) - np.pi


# -- reading --------------------------------------------------------------------------------------

@dataclass
class KnobDetection:
    """Where the knob was found: centre in the face plane (m, knob x and y at angle 0), the
    image pixel of it, the fit there (``score``: R^2 of the best angle), and the turn ``psi``
    (rad) of the canvas it was found in."""
    center_m: tuple[float, float]
    score: float
    pixel: tuple[float, float]
    psi: float = 0.0
    scale: float = 1.0


@dataclass
class KnobReading:
    """One knob read. ``state`` is a state name or "unknown"; ``angle`` (rad) is None when no
    knob was found; ``confidence`` in [0, 1]; ``evidence``: the fit (``score``), the margin
    over the best other state (``margin``, and that state: ``runner_up``), the snap (share of
    half a state step) and the knob's radius in the image (``radius_px``)."""
    knob_id: str
    found: bool
    state: str = "unknown"
    angle: Optional[float] = None
    confidence: float = 0.0
    detection: Optional[KnobDetection] = None
    angles: dict = field(default_factory=dict)
    evidence: dict = field(default_factory=dict)
    reason: str = ""

    @property
    def angle_deg(self) -> Optional[float]:
        return None if self.angle is None else math.degrees(self.angle)


#: How far apart (m) two cameras must be for their "off" readings to count as two views.
OFF_VIEWS_APART_M = 0.25


class OffViews:
    """"Off" from two places: a reading that passes every check but the off factor
    (``KnobConfig.off_margin_factor``; evidence ``off_one_view``) is remembered per knob, and
    a second such reading from a camera at least ``apart_m`` from the first makes the knob
    off. A reading that leans to another state, or one that gives a state, forgets the knob;
    so does turning it or another knob of its appliance (``forget``: a turn can nudge a
    neighbour). A knob that is on would have to be read off wrongly,
    each time over the calibrated margin, from two places for this to fail: the factor asks
    more of one view, this asks the same of two (docs/knobs.md, "Off from two places").
    Hand-written: a small rule over readings, no library does it."""

    def __init__(self, apart_m: float = OFF_VIEWS_APART_M):
        self.apart_m = float(apart_m)
        self._seen: dict[str, list[np.ndarray]] = {}

    def forget(self, knob_id: str) -> None:
        self._seen.pop(knob_id, None)

    def add(self, reading: "KnobReading", off_state: str, camera: np.ndarray) -> bool:
        """Take ``reading`` (made from a camera at world position ``camera``); True when it
        makes its knob off (a second "off from this view alone" from far enough away)."""
        ev = reading.evidence or {}
        if reading.state != "unknown" or (reading.found and ev.get("leaning") not in (None, off_state)):
            self.forget(reading.knob_id)
            return False
        if not ev.get("off_one_view"):
            return False
        c = np.asarray(camera, dtype=float)[:3]
        seen = self._seen.setdefault(reading.knob_id, [])
        if any(np.linalg.norm(c - o) >= self.apart_m for o in seen):
            self.forget(reading.knob_id)
            return True
        seen.append(c)
        return False


def snap_to_state(angle: float, prior: KnobPrior, proba=None, psi: float = 0.0) -> tuple[str, float]:
    """The nearest discrete state to ``angle`` (rad; modulo the shape's period for a
    symmetric knob) and how far inside half a state step of it the angle lies (1 on the
    state, 0 half-way to the next)."""
    period = 2 * math.pi / max(1, prior.symmetry)
    a = np.asarray(prior.state_angles)
    d = np.abs(np.remainder(a - angle + period / 2, period) - period / 2)
    k = int(np.argmin(d))
    if len(a) > 1:
        diffs = np.abs(np.remainder(a[:, None] - a[None, :] + period / 2, period) - period / 2)
        diffs = diffs[diffs > 1e-6]
        half = float(diffs.min()) / 2 if len(diffs) else period / 2
    else:
        half = period / 2
    return prior.state_names[k], float(max(0.0, 1.0 - d[k] / half))


#: A view is *hard* for the state gate when the knob's radius in the image is under
#: HARD_RADIUS_PX or the camera is more than HARD_OFF_AXIS_DEG off its axis.
HARD_RADIUS_PX = 12.0
HARD_OFF_AXIS_DEG = 45.0


#: ... and *very hard* under VERY_HARD_RADIUS_PX or more than VERY_HARD_OFF_AXIS_DEG off.
VERY_HARD_RADIUS_PX = 8.0
VERY_HARD_OFF_AXIS_DEG = 55.0


def hard_view(radius_px: float, off_axis: float) -> bool:
    """Whether a view of a knob (its radius in pixels, degrees off its axis) is a hard one."""
    return radius_px < HARD_RADIUS_PX or off_axis > HARD_OFF_AXIS_DEG


def view_level(radius_px: float, off_axis: float) -> int:
    """How hard a view is for the state gate: 0, 1 (``hard_view``) or 2 (very hard)."""
    if radius_px < VERY_HARD_RADIUS_PX or off_axis > VERY_HARD_OFF_AXIS_DEG:
        return 2
    return int(hard_view(radius_px, off_axis))


class KnobReader:
    """Templates + gates + configuration: ``read`` gives one KnobReading per prior (module
    docstring). ``detect_gate`` (a ``CalibratedThreshold`` on the fit) says whether a knob is
    in its region; ``state_gate`` (on the margin over the best other state) whether its
    state may be given, and ``state_gate_hard`` the same for hard views (``hard_view``; None:
    ``state_gate``)."""

    def __init__(self, templates: KnobTemplates, detect_gate: CalibratedThreshold,
                 state_gate: CalibratedThreshold, config: KnobConfig = KnobConfig(),
                 state_gate_hard: Optional[CalibratedThreshold] = None,
                 colour_gates: Optional["KnobReader"] = None):
        self.templates, self.detect_gate, self.state_gate, self.config = (
            templates, detect_gate, state_gate, config)
        self.state_gate_hard = state_gate_hard
        #: the gate of very hard views (``view_level`` 2; None: ``state_gate_hard``)
        self.state_gate_very_hard: Optional[CalibratedThreshold] = None
        #: the gates of readings made without a depth image (the fit and margins of colour
        #: alone are on another scale), as a reader whose gates they are; None: these gates
        self.colour_gates = colour_gates
        #: the state gates (view levels 0, 1, 2) of readings whose angle came from a round
        #: body's marker (evidence ``dot``: their margin is on a scale of its own); None: none
        self.dot_gates: Optional[list] = None
        #: the least ``half_turn`` (``_half_turn``) a reading of a knob without symmetry needs
        #: per ``view_level`` (0, 1, 2), calibrated with the state gates; None: no such gate
        self.half_turn_gates: Optional[list] = None
        #: the least ``rival`` (``_half_turn`` of the dot reading against the nearest other
        #: state) a round body's marker reading needs per ``view_level``, calibrated with the
        #: ``dot_gates``; None: no such gate
        self.dot_rival_gates: Optional[list] = None
        self._casters: dict = {}

    def __getstate__(self):
        d = dict(self.__dict__)
        d["_casters"] = {}
        return d

    def with_config(self, config: KnobConfig) -> "KnobReader":
        """This reader reading with ``config``'s read-time settings: its templates and every
        gate as they were calibrated (state, very hard, half-turn, dot and rival gates, and
        those of colour alone), only the configuration replaced."""
        out = copy.copy(self)
        out.config = config
        out._casters = {}
        if getattr(self, "colour_gates", None) is not None:
            out.colour_gates = self.colour_gates.with_config(config)
        return out

    def caster(self, key: str) -> _Caster:
        if key not in self._casters:
            self._casters[key] = _Caster(self.templates.shapes_[key])
        return self._casters[key]

    @property
    def detect_threshold(self) -> float:
        cfg = self.config
        return cfg.threshold if cfg.threshold is not None else self.detect_gate.threshold_

    @property
    def margin_threshold(self) -> float:
        cfg = self.config
        return cfg.margin_threshold if cfg.margin_threshold is not None else self.state_gate.threshold_

    def gates_for(self, depth: bool) -> "KnobReader":
        """The reader whose gates apply to a reading with (or without) depth."""
        g = getattr(self, "colour_gates", None)
        return g if (not depth and g is not None) else self

    def margin_threshold_for(self, hard, dot: bool = False) -> float:
        """The state gate of a view (``view_level``: 0, 1 or 2; or ``hard_view``): the hard
        or very hard views' own when it has one; of a reading from a round body's marker
        (``dot``), the level's ``dot_gates``."""
        cfg = self.config
        if cfg.margin_threshold is not None:
            return cfg.margin_threshold
        level = int(hard)
        if dot:
            dg = getattr(self, "dot_gates", None)
            # a reader made before the marker's readings had gates: never passes one
            return dg[min(level, len(dg) - 1)].threshold_ if dg else math.inf
        g = self.state_gate
        if level >= 1 and getattr(self, "state_gate_hard", None) is not None:
            g = self.state_gate_hard
        if level >= 2 and getattr(self, "state_gate_very_hard", None) is not None:
            g = self.state_gate_very_hard
        return g.threshold_

    def half_turn_gate_for(self, level, dot: bool = False) -> float:
        """The half-turn gate of a view (``view_level``); of a round body's marker reading
        (``dot``), its level's ``dot_rival_gates`` (the gate of its ``rival``); -inf when
        there is none."""
        g = getattr(self, "dot_rival_gates" if dot else "half_turn_gates", None)
        return float(g[min(int(level), len(g) - 1)]) if g else -math.inf

    # OpenBLAS on one thread while reading: the products here are small (windows of a few
    # thousand pixels, 3- and 4-column Gram matrices) and its threads spin on them, which
    # doubled the CPU of a reading for the same wall time (home 5: 115 against 62 ms per knob).
    @single_threaded_blas
    def read(self, image: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray,
             priors: Sequence[KnobPrior], depth: Optional[np.ndarray] = None) -> list[KnobReading]:
        """One reading per prior. ``depth``: the depth image registered to ``image`` (m along
        the optical axis, 0 where there is no reading); read on colour alone without it."""
        rgb = to_rgb(np.asarray(image))
        T_wc = np.asarray(T_world_camera, dtype=float)
        if depth is not None:
            depth = np.asarray(depth, dtype=np.float32)
            if depth.shape[:2] != rgb.shape[:2]:
                raise ValueError(f"the depth image is {depth.shape[1]}x{depth.shape[0]}, the colour "
                                 f"image {rgb.shape[1]}x{rgb.shape[0]}: they must be registered")
        return [self.read_one(rgb, K, T_wc, p, depth) for p in priors]

    # one knob ------------------------------------------------------------------------------
    @single_threaded_blas
    def evidence(self, rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, prior: KnobPrior,
                 depth: Optional[np.ndarray] = None):
        """The knob's fit: a KnobReading with ``found`` and ``angle`` (no gates applied, no
        state) and, when it could be looked at, ``evidence`` (score, margin, runner_up).
        ``depth``: the registered depth image (m along the optical axis, 0: no reading; the
        image's size), fused with the colour fit when given (``depth_weight``)."""
        cfg = self.config
        tm = self.templates
        if prior.shape not in tm.templates_:
            from hearth.perception.errors import PerceptionError
            raise PerceptionError(f"knob {prior.knob_id}: its shape is not among the reader's "
                                  "templates (the models were made for another home)")
        shape = tm.shapes_[prior.shape]
        tpl = tm.templates_[prior.shape]
        theta = math.radians(off_axis_deg(T_wc, prior))
        if math.degrees(theta) > cfg.max_off_axis_deg:
            return KnobReading(prior.knob_id, False, reason="seen too obliquely")
        T_cam_face = np.linalg.inv(T_wc) @ prior.T_world_face()
        pc = T_cam_face[:3, 3]
        if pc[2] <= 0.05:
            return KnobReading(prior.knob_id, False, reason="behind the camera")
        u, v = K.fx * pc[0] / pc[2] + K.cx, K.fy * pc[1] / pc[2] + K.cy
        if not (0 <= u < K.width and 0 <= v < K.height):
            return KnobReading(prior.knob_id, False, reason="outside the image")
        r_px = K.fx * prior.radius / float(np.linalg.norm(pc))
        if r_px < cfg.min_radius_px:
            return KnobReading(prior.knob_id, False, evidence=dict(radius_px=round(r_px, 2)),
                               reason=f"too small in the image ({r_px:.1f} px radius)")
        T_c, psi = prior.canvas_frame(T_wc)
        C = (np.linalg.inv(T_c) @ np.append(T_wc[:3, 3], 1.0))[:3]       # camera, canvas frame

        # (1)-(2) where the knob is: the angle-averaged labels at every offset
        rho = tm.px_per_radius / prior.radius
        n = tm.window_px
        search_m = max(cfg.search_m, cfg.search_radii * prior.radius)
        S = int(math.ceil(search_m * rho))
        size = n + 2 * S
        H = plane_homography(K, T_wc, T_c, rho, size)
        canvas = rectify(rgb, H, size).astype(np.float32)
        ti = tm.bin_of(theta)
        r2 = offset_scores(canvas, tpl.soft[ti], tpl.gram_inv[ti])
        use_depth = depth is not None and tpl.heights is not None and cfg.depth_weight > 0
        if use_depth:
            # the depth image as heights above the believed face plane, the same canvas
            hc, hv = canvas_heights(depth, H, size, float(C[2]), shape.face)
            use_depth = bool(hv.mean() >= 0.3)
        if use_depth:
            dsums = measured_sums(hc, hv, n)
            r2 = r2 + cfg.depth_weight * depth_offset_scores(hc, hv, tpl.heights[ti].mean(0), sums=dsums)
        off = (np.arange(2 * S + 1) - S) / rho
        prior_pen = (off[None, :] ** 2 + off[:, None] ** 2) / (2 * cfg.offset_sigma_m ** 2)
        inside = (off[None, :] ** 2 + off[:, None] ** 2) <= search_m ** 2
        score = np.where(inside, r2 - cfg.offset_weight * prior_pen, -np.inf)
        i0, j0 = np.unravel_index(int(np.argmax(score)), score.shape)

        # (3) the coarse angle: every template at that offset and its neighbours
        cells = [(i, j) for i in range(i0 - 1, i0 + 2) for j in range(j0 - 1, j0 + 2)
                 if 0 <= i <= 2 * S and 0 <= j <= 2 * S]
        patches = np.stack([canvas[i:i + n, j:j + n].reshape(-1, 3) for i, j in cells])
        flat = tpl.labels[ti].reshape(len(tpl.alphas), -1)
        coarse = label_scores(patches, flat, tpl.counts[ti], tpl.n_labels,
                              template_onehot(tpl, ti))                        # (P, A)
        if use_depth:
            hp = np.stack([hc[i:i + n, j:j + n].ravel() for i, j in cells])
            vp = np.stack([hv[i:i + n, j:j + n].ravel() for i, j in cells])
            coarse = coarse + cfg.depth_weight * depth_scores(
                hp, vp, tpl.heights[ti].reshape(len(tpl.alphas), -1))
        best_cell = int(np.argmax(coarse.max(1)))
        ci, cj = cells[best_cell]
        centres: dict = {}

        def depth_center(k: int):
            """Where template ``k``'s heights fit the depth best (``_depth_center``), once."""
            if k not in centres:
                centres[k] = _depth_center(hc, hv, tpl.heights[ti][k], (ci, cj), inside, off, rho,
                                           sums=dsums)
            return centres[k]

        curve = coarse[best_cell]
        center = (off[cj], -off[ci])                     # canvas frame (canvas up = -rows)
        knob_angles = _wrap(tpl.alphas + psi)            # relative angle -> knob angle
        allowed = self._allowed(prior, knob_angles)
        if not allowed.any():
            allowed[:] = True
        state_of = _states_of(prior, knob_angles)
        picks = _candidates(curve, allowed, state_of, cfg.candidates)
        if use_depth:
            # the centre from the depth alone, with the shape at the best coarse angle (the
            # knob's body stands out of the panel whatever its colours), to a fraction of a
            # canvas pixel: colour alone can trade the centre against the angle. Then the
            # coarse angles again, in a canvas centred there.
            c_depth = depth_center(picks[0])
            if c_depth is not None:
                center = c_depth
                curve = self._coarse_at(rgb, depth, K, T_wc, T_c, C, prior, shape, tpl, ti,
                                        flat, center)
                picks = _candidates(curve, allowed, state_of, cfg.candidates)

        # a knob whose body is round about its axis (a skirt and cap) with a dot off the axis:
        # its angle is only where the dot stands about the centre, and only depth places that
        # centre; to a fraction of a pixel from the top's rim at the image's own pixels
        # (``body_center``), then the angle from the dot's colour about it
        fine, from_dot = None, False
        windows: dict = {}                  # the exact checks' windows, by centre (``_refine``)
        if use_depth and cfg.round_body_center:
            fine = self._round_body(rgb, K, T_wc, prior, shape, tpl, ti, T_c, C, center, picks,
                                    allowed, state_of, psi, r_px, depth, theta, flat, windows)
            if fine is not None:
                fine, again, picks, from_dot = fine
                curve = curve if again is None else again

        # (4) the exact check of the candidates at the fine scale; with depth, each candidate
        # at the centre the depth gives the shape at its own angle (a pointer flipped by 180
        # degrees stands elsewhere: the best candidate is the best centre and angle together)
        if fine is not None:
            pass
        elif use_depth:
            if shape.symmetry == 1:
                # and the best coarse angle turned by half a turn, whatever the coarse curve
                # says of it: a marker flipped a radius away is the mistake colour makes. The
                # allowed angle nearest the half turn, within 45 degrees: a knob that turns
                # one way only may stop short of it (home 4: states 0-223 degrees, the best
                # coarse angle 61 with the knob at 222; the half turn, 241, was not allowed,
                # and no angle near the knob's was checked)
                picks = _with_half_turn(tpl.alphas, picks, allowed)
            # candidates whose centres agree (a knob whose body looks the same at every
            # angle) share one window
            groups: list = []
            for c in picks:
                c_at = depth_center(c) or center
                for g in groups:
                    if math.hypot(g[0][0] - c_at[0], g[0][1] - c_at[1]) <= 0.05 * prior.radius:
                        g[1].append(tpl.alphas[c])
                        break
                else:
                    groups.append((c_at, [tpl.alphas[c]]))
            fine = []
            for c_at, alphas in groups:
                fine += self._refine(rgb, K, T_wc, prior, shape, T_c, C, c_at, alphas,
                                     psi, r_px, depth, theta, windows=windows)
        else:
            fine = self._refine(rgb, K, T_wc, prior, shape, T_c, C, center,
                                [tpl.alphas[c] for c in picks], psi, r_px, None, theta,
                                windows=windows)
        fine = [f for f in fine if allowed_angle(prior, f[1])] or fine
        fine.sort(key=lambda f: -f[0])
        best = fine[0]
        s_best = snap_to_state(best[1], prior)[0]
        if not from_dot:
            # the state next to the reading's angle, fitted exactly at its own angle at the
            # reading's centre when no exact check ended in it; where it fits better than the
            # reading, it is the reading (the exact checks' search can stop on the slope
            # between two states: home 787, a reading 10 degrees off between states 17
            # degrees apart, margin 0.35 over a state 35 degrees away, set its level's gate
            # to 0.43; the true state fitted at its own angle gave 1.91 against 1.81). Where
            # it fits worse it is left out: measuring every margin against it shrank right
            # readings' margins, and the recalibrated gates let a packed pointer through 90
            # degrees off (home 4; docs/knobs.md).
            s_next, a_next = _next_state(prior, best[1], s_best)
            if s_next is not None and not any(snap_to_state(f[1], prior)[0] == s_next
                                              for f in fine[1:]):
                probe = self._refine(rgb, K, T_wc, prior, shape, T_c, C, best[2],
                                     [a_next - psi], psi, r_px,
                                     depth if use_depth else None, theta, hold=True,
                                     exact_only=True, windows=windows)[0]
                if probe[0] > best[0]:
                    fine.insert(0, probe)
                    best = probe
                    s_best = s_next
        checked = list(fine)
        rivals = [f for f in fine[1:] if snap_to_state(f[1], prior)[0] != s_best]
        score_best, angle, center_c = best
        if rivals:
            margin = score_best - rivals[0][0]
        else:
            # every exact check ended in the best state (or none of another was allowed):
            # the margin is the coarse one, the best angle over the best of another state
            # among the allowed angles (0 when there is none: the state is not told apart)
            i_best = _states_of(prior, [angle])[0]
            others = np.flatnonzero(allowed & (state_of != i_best))
            margin = float(curve[picks[0]] - curve[others].max()) if len(others) else 0.0
            margin = max(0.0, min(margin, score_best))
        fine = [best] + rivals
        c_best = picks[0]
        half_turn = None
        # the reading against itself turned by half a turn (``_half_turn``), the rival the
        # margin tells worst: the best exact check that ended within 45 degrees of the half
        # turn; else the allowed template angle nearest to the half turn, within 45 degrees,
        # at the centre the depth gives the shape turned so (not refined: an exact check more
        # per knob tripled the CPU of a skirt knob, whose checks seldom end there). None
        # allowed: no half turn to fear.
        near = [f for f in checked[1:] if abs(_wrap(f[1] - angle - math.pi)) < math.radians(45)]
        turned = max(near, key=lambda f: f[0]) if near else None
        # (not for a round body's dot reading: its margin already weighs the dot against
        # every other dot-sized spot of the top, the half turn's place included)
        if shape.symmetry == 1 and turned is None and not from_dot:
            d = np.where(allowed, np.abs(_wrap(knob_angles - angle - math.pi)), np.inf)
            k = int(np.argmin(d))
            if d[k] < math.radians(45):
                c_at = center_c
                if use_depth:
                    c_at = depth_center(k) or center_c
                turned = (None, float(knob_angles[k]), c_at)
        if shape.symmetry == 1 and turned is not None and not from_dot:
            half_turn = self._half_turn(rgb, K, T_wc, prior, shape, T_c, C, (float(angle) - psi, center_c),
                                        (float(turned[1]) - psi, turned[2]), psi, r_px,
                                        depth if use_depth else None, theta, windows=windows)
        center_k = rotate_xy(center_c, psi)              # canvas frame -> knob face frame
        p_world = prior.T_world_face() @ np.array([center_k[0], center_k[1], 0.0, 1.0])
        pcam = np.linalg.inv(T_wc) @ p_world
        pixel = (K.fx * pcam[0] / pcam[2] + K.cx, K.fy * pcam[1] / pcam[2] + K.cy)
        det = KnobDetection((float(center_k[0]), float(center_k[1])), float(score_best),
                            (float(pixel[0]), float(pixel[1])), float(psi))
        ev = dict(score=round(float(score_best), 4), margin=round(float(margin), 4),
                  offset=round(math.hypot(*center_k) / search_m, 3),
                  runner_up=(snap_to_state(fine[1][1], prior)[0] if len(fine) > 1 else None),
                  coarse_score=round(float(curve[c_best]), 4), radius_px=round(r_px, 2),
                  depth=bool(use_depth))
        if use_depth:
            # how much of the knob's relief the depth shows where it was read (``depth_slope``:
            # a coarse canvas centred on the reading, the template nearest its angle)
            k = int(np.argmin(np.abs(_wrap(tpl.alphas - (float(angle) - psi)))))
            hr, vr = canvas_heights(depth, plane_homography(K, T_wc, T_c, rho, n, center_c), n,
                                    float(C[2]), shape.face)
            sl = depth_slope_se(hr, vr, tpl.heights[ti][k])
            if sl is not None:
                ev["stands"], ev["stands_se"] = round(sl[0], 3), round(sl[1], 4)
        if from_dot:
            ev["dot"] = True
            # the marker's reading against the nearest other state (``fine[1]``, at the same
            # centre), compared only where their renderings differ (``_half_turn``: the
            # marker at the one angle against the marker at the other): the dot's margin is
            # an expected error of the angle, blind to a dot read from a speck or a glint
            # beside it; on generated homes 0-19 the wrong validation readings of the marker
            # with the widest margins explained the rival's pixels no better than the rival
            # (docs/knobs.md, "The marker against the next state")
            versus = self._half_turn(rgb, K, T_wc, prior, shape, T_c, C, (float(angle) - psi, center_c),
                                     (float(fine[1][1]) - psi, fine[1][2]), psi, r_px,
                                     depth if use_depth else None, theta, windows=windows) if len(fine) > 1 else None
            if versus is not None:
                ev["rival"] = versus["half_turn"]
        if half_turn is not None:
            ev.update(half_turn)
        if snap_to_state(float(angle), prior)[0] == prior.off_state and not from_dot:
            # an "off" reading against the best "on" candidate, compared only where the two
            # renderings differ (``_half_turn`` with that state in place of the half turn):
            # the one promise the reader keeps is that a knob that is on is never read off, so
            # off must explain the pixels that tell it from on better than on does, whatever
            # the margin over the whole window (``KnobConfig.off_rival_min``)
            on = [(a, c) for _f, a, c in fine[1:] if snap_to_state(float(a), prior)[0] != prior.off_state]
            if not on:
                sa = np.asarray(prior.state_angles, dtype=float)
                names = np.asarray(prior.state_names)
                d = np.where(names == prior.off_state, np.inf, np.abs(_wrap(sa - float(angle))))
                on = [(float(sa[int(np.argmin(d))]), center_c)] if np.isfinite(d).any() else []
            if on:
                vs = self._half_turn(rgb, K, T_wc, prior, shape, T_c, C, (float(angle) - psi, center_c),
                                     (float(on[0][0]) - psi, on[0][1]), psi, r_px,
                                     depth if use_depth else None, theta, windows=windows)
                if vs is not None:
                    ev["off_rival"] = vs["half_turn"]
                    ev["off_rival_state"] = snap_to_state(float(on[0][0]), prior)[0]
        return KnobReading(prior.knob_id, True, angle=float(angle), detection=det,
                           angles={"fused": float(angle)}, evidence=ev)

    def read_one(self, rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, prior: KnobPrior,
                 depth: Optional[np.ndarray] = None) -> KnobReading:
        r = self.evidence(rgb, K, T_wc, prior, depth)
        if not r.found:
            return r
        cfg = self.config
        ev = r.evidence
        gates = self.gates_for(bool(ev.get("depth")))
        why = not_there(ev, cfg)
        if why:
            return KnobReading(prior.knob_id, False, evidence=ev,
                               reason=f"no knob found in its region ({why})")
        if ev["score"] <= gates.detect_threshold:
            return KnobReading(prior.knob_id, False, evidence=ev,
                               reason=f"no knob found in its region (fit {ev['score']:.2f})")
        state, c_snap = snap_to_state(r.angle, prior)
        ev["snap"] = round(1.0 - c_snap, 3)
        oblique = off_axis_deg(T_wc, prior)
        hard = view_level(ev.get("radius_px", 0.0), oblique)
        gate = gates.margin_threshold_for(hard, bool(ev.get("dot")))
        is_off = state == prior.off_state
        need = gate * (cfg.off_margin_factor if is_off else 1.0)
        ev["leaning"] = state
        c_margin = ev["margin"] / max(need, 1e-6)
        r.confidence = float(min(1.0, 0.5 * min(c_margin, 2.0)) * c_snap)
        need_turn = gates.half_turn_gate_for(hard, bool(ev.get("dot")))

        def doubt(need_margin: float) -> Optional[str]:
            """Why the reading may not give its state with a margin gate of ``need_margin``
            (None: it may)."""
            if ev.get("dot") and oblique > cfg.dot_max_off_axis_deg:
                # a marker seen more obliquely than any view its reader was measured on
                # (the bench's views reach 60 degrees): before the centre kept to the knob's
                # own points, readings beyond 55 degrees were read a state or two off with
                # margins well over their gates (docs/knobs.md, "A dot seen obliquely")
                return (f"unsure ({state}: its marker is seen {oblique:.0f} degrees off the "
                        f"knob's axis, at most {cfg.dot_max_off_axis_deg:.0f})")
            if ev["margin"] <= need_margin:
                return (f"unsure ({state}: margin {ev['margin']:.3f} over {ev['runner_up']}, "
                        f"needs {need_margin:.3f})")
            if ev.get("half_turn") is not None and ev["half_turn"] <= need_turn:
                return (f"unsure ({state}: turned by half a turn it fits nearly as well, "
                        f"{ev['half_turn']:.2f}, needs {need_turn:.2f})")
            if ev.get("dot") and ev.get("rival") is not None and ev["rival"] <= need_turn:
                return (f"unsure ({state}: its marker fits nearly as well at {ev['runner_up']}, "
                        f"{ev['rival']:.2f}, needs {need_turn:.2f})")
            if is_off and ev.get("off_rival") is not None and ev["off_rival"] <= cfg.off_rival_min:
                return (f"unsure ({state}: {ev.get('off_rival_state')} fits nearly as well where "
                        f"the two differ, {ev['off_rival']:.2f}, needs {cfg.off_rival_min:.2f})")
            if 1.0 - c_snap > cfg.max_snap:
                return f"unsure ({state}: {math.degrees(r.angle):.0f} degrees lies between states)"
            if r.confidence < cfg.min_confidence:
                return f"unsure ({state}: confidence {r.confidence:.2f} under {cfg.min_confidence:.2f})"
            return None

        r.reason = doubt(need) or ""
        if not r.reason and is_off and getattr(prior, "round_grip", False):
            # a round body's angle rests on its marker alone: one view never says off (a
            # knurled grip with a dot, read 37 degrees off at its off state from one view,
            # passed every gate: home 102 of generator version 7); a second such reading from
            # another place does (``OffViews``)
            r.reason = f"unsure ({state}: a ridged round grip's marker alone says it"
            ev["off_one_view"] = True
            r.reason += ") from this view alone"
            return r
        if not r.reason:
            r.state = state
        elif is_off and need > gate and doubt(gate) is None:
            # every check an "on" state needs is passed; only the off factor is not: a second
            # such reading from another place makes it off (``OffViews``)
            ev["off_one_view"] = True
            r.reason += " from this view alone"
        return r

    def _allowed(self, prior: KnobPrior, angles: np.ndarray) -> np.ndarray:
        return allowed_angles(prior, angles)

    def _coarse_at(self, rgb, depth, K, T_wc, T_c, C, prior, shape, tpl, ti, flat, center):
        """The coarse fit (colour plus ``depth_weight`` times depth) of every template angle
        in a canvas centred at ``center`` (canvas frame, m)."""
        rho = self.templates.px_per_radius / prior.radius
        n = self.templates.window_px
        Hd = plane_homography(K, T_wc, T_c, rho, n, center)
        patch = rectify(rgb, Hd, n).astype(np.float32).reshape(1, -1, 3)
        hd, vd = canvas_heights(depth, Hd, n, float(C[2]), shape.face)
        return (label_scores(patch, flat, tpl.counts[ti], tpl.n_labels, template_onehot(tpl, ti))[0]
                + self.config.depth_weight * depth_scores(
                    hd.reshape(1, -1), vd.reshape(1, -1),
                    tpl.heights[ti].reshape(len(tpl.alphas), -1))[0])

    def _round_body(self, rgb, K, T_wc, prior, shape, tpl, ti, T_c, C, center, picks, allowed,
                    state_of, psi, r_px, depth, theta, flat, windows=None):
        """The candidates of a round-bodied knob (``round_body_levels``, a dot no wider than
        ``dot_max_size`` of its distance from the axis) read at the centre ``body_center``
        gives (from ``center``, the canvas depth fit's): the angle from the dot
        (``_dot_reading``), its fit the exact check's there, and, as rival, the nearest
        other state at the fit less the dot's margin; without a dot profile (``dot_angle``
        off, no top to see it on) the coarse angles again in a canvas centred there, the best
        ones and the best turned by half a turn checked exactly with the centre held. Returns
        (fine, coarse curve, picks, whether from the dot) as ``evidence`` uses them (the curve
        None from the dot: the one before stands), or None (not such a knob, or too few depth
        pixels)."""
        cfg = self.config
        levels = round_body_levels(shape)
        md = marker_dot(shape)
        if levels is None or md is None or md[2] > cfg.dot_max_size * md[1]:
            # a marker across the centre (the plain knob's bar) turns about it whatever the
            # centre's error: its reading needs none of this
            return None
        got = body_center(depth, K, T_wc, T_c, shape, self.caster(prior.shape), levels, center,
                          float(tpl.alphas[picks[0]]), psi)
        if got is None:
            return None
        center = got[0]
        dot = self._dot_reading(rgb, K, T_wc, prior, shape, T_c, center, psi, r_px) if cfg.dot_angle else None
        if dot is not None:
            # the angle from the marker's colour about that centre, the margin the marker's
            # evidence; the fit (for the detect gate) that of the exact check there, at that
            # angle: both come from the image already, and settling the offset by colour and
            # searching the angle (a round body in its panel's colour says little of either)
            # took a fifth of a skirt knob's reading (the coarse curve is the one before)
            a_dot, margin, rival = dot
            fit = self._refine(rgb, K, T_wc, prior, shape, T_c, C, center, [a_dot - psi], psi,
                               r_px, depth, theta, hold=True, exact_only=True, windows=windows)[0][0]
            return [(fit, a_dot, center), (fit - margin, rival, center)], None, picks, True
        curve = self._coarse_at(rgb, depth, K, T_wc, T_c, C, prior, shape, tpl, ti, flat, center)
        picks = _candidates(curve, allowed, state_of, cfg.candidates)
        picks = _with_half_turn(tpl.alphas, picks, allowed)
        fine = self._refine(rgb, K, T_wc, prior, shape, T_c, C, center,
                            [tpl.alphas[c] for c in picks], psi, r_px, depth, theta, hold=True,
                            windows=windows)
        return fine, curve, picks, False

    def _dot_reading(self, rgb, K, T_wc, prior, shape, T_c, center, psi, r_px):
        """The angle of a round-bodied knob from its marker's colour about ``center``
        (``dot_profile``: the best allowed angle, refined by a parabola), a margin and the
        angle of the nearest other state. The margin is what the marker's evidence says of
        the state: how far the angle lies from the edge of its state's half step, in units of
        the angle's expected error (the centre's error, ``dot_center_px`` image pixels, and
        the marker's own, ``dot_blob_px`` pixels over its contrast to noise: a blob's
        position error goes as the noise over its contrast; both seen from the marker's
        distance from the axis), times how much the marker's response stands out over the
        best response of a marker-sized disc anywhere else on the top (a second blob, a
        glint, a marker not seen), to the power ``dot_dominance_power``. None without a
        marker or a top to see it on."""
        cfg = self.config
        prof = dot_profile(rgb, K, T_wc, T_c, shape, center)
        if prof is None:
            return None
        alphas, S, noise = prof
        md = marker_dot(shape)
        knob_a = _wrap(alphas + psi)
        ok = self._allowed(prior, knob_a)
        if not ok.any():
            ok[:] = True
        Sm = np.where(ok, S, -np.inf)
        k = int(np.argmax(Sm))
        step = float(alphas[1] - alphas[0])
        y0, y1, y2 = S[k - 1], S[k], S[(k + 1) % len(S)]
        den = y0 - 2 * y1 + y2
        x = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den < 0 else 0.0
        a_dot = float(_wrap(knob_a[k] + x * step))
        base = float(np.median(S))
        peak = float(S[k]) - base
        if peak <= 0:
            return None
        width = 2 * md[2] / max(md[1], 1e-6) + step          # the marker's angular width
        far = np.abs(_wrap(knob_a - a_dot)) > width
        other = float(S[far & ok].max()) - base if (far & ok).any() else 0.0
        dominance = float(np.clip(1.0 - max(other, 0.0) / peak, 0.0, 1.0))
        snr = peak / max(noise, cfg.dot_noise_floor)
        state, inside = snap_to_state(a_dot, prior)
        sa = np.asarray(prior.state_angles)
        names = np.asarray(prior.state_names)
        steps = np.abs(_wrap(sa[:, None] - sa[None, :]))
        steps = steps[steps > 1e-6]
        half = float(steps.min()) / 2 if len(steps) else math.pi
        pix = prior.radius / max(r_px, 1e-6)                  # m per image pixel at the knob
        # the marker's own error as noise over contrast, not its square root, and no separate
        # factor for a weak marker (which counted its contrast twice); a rival blob weighs
        # as the cube of the dominance: on the dot readings of 16 homes' held-out views
        # (3,926 readings, gates calibrated on their validation views) 2,512 right readings
        # passed against 2,259, and 3 wrong ones against 4 (docs/knobs.md, "The marker's
        # expected error")
        sigma = math.hypot(cfg.dot_center_px, cfg.dot_blob_px / max(snr, 1e-3)) * pix / md[1]
        margin = inside * half / sigma * dominance ** cfg.dot_dominance_power
        d = np.abs(_wrap(sa - a_dot))
        d = np.where(names == state, np.inf, d)
        rival = float(sa[int(np.argmin(d))]) if np.isfinite(d).any() else float(_wrap(a_dot + math.pi))
        return a_dot, float(margin), rival

    def _half_turn(self, rgb, K, T_wc, prior, shape, T_c, C, reading, turned, psi, r_px,
                   depth=None, theta=0.0, windows: Optional[dict] = None) -> Optional[dict]:
        """How much better the reading (``reading`` = (relative angle rad, centre in the canvas
        frame m)) explains the image than the knob turned by half a turn from it
        (``turned``, the same: the exact check that ended nearest the half turn, or the half
        turn at the centre the depth gives it): a knob without symmetry
        looks much the same both ways (a pointer, a tip, a marker: most of the grip
        coincides), so a fit over the whole window tells them apart weakly and the state
        gate was set by such readings. Both are rendered exactly (as ``_refine`` renders,
        each at its own centre) in one window between them and compared only where they
        differ: the window pixels whose labels differ between the two renderings (the marker,
        tip or point under one, the grip, bezel or panel under the other), each weighted by
        the share of its label weights that differ. Each rendering's label colours are its
        own least-squares fit over the whole window; ``half_turn_colour`` is (SSE_turned -
        SSE) / (SSE_turned + SSE + 2 E) of the colour residuals over those pixels, E what
        their residual would be if they fitted as well as the window does on average (near
        1: only the reading explains them, near -1: only the turned knob, 0: both, or
        neither, or noise alone; ``_contrast_ratio``). With
        ``depth``, ``half_turn_depth`` is the same of the depth residuals over the image
        pixels whose rendered depths differ, each rendering put at the measured depth by the
        median difference over the pixels where the two agree (the believed plane's height
        error). ``half_turn``: the colour's plus ``depth_weight`` times the depth's, checked
        against ``half_turn_gate_for`` (calibrated like the state gate). None when the window
        leaves the image. ``windows``: the reading's exact checks' windows (``_refine``)."""
        cfg = self.config
        if r_px > cfg.decimate_above_px:
            rgb = rgb[::2, ::2]
            depth = None if depth is None else depth[::2, ::2]
            K = Intrinsics(K.fx / 2, K.fy / 2, K.cx / 2, K.cy / 2, rgb.shape[1], rgb.shape[0])
        rho = cfg.fine_px_per_radius / prior.radius
        n = 2 * int(math.ceil(self.templates.window_radii * cfg.fine_px_per_radius)) + 1
        mid = ((reading[1][0] + turned[1][0]) / 2, (reading[1][1] + turned[1][1]) / 2)
        # the exact checks' window there when they looked through one (``_refine``'s
        # ``windows``: the same window, rays and, at one centre for both, renderings)
        seen = (windows or {}).get((float(mid[0]), float(mid[1]), depth is None))
        win = seen or _Window(rgb, K, plane_homography(K, T_wc, T_c, rho, n, mid), n,
                              ridge=cfg.fine_ridge_px)
        if win.box is None:
            return None
        if seen is not None and tuple(reading[1]) == tuple(turned[1]):
            labs, ts = seen.render(np.array([reading[0], turned[0]]))
            dirs = (windows or {})[("pixels", win.box, depth is None)][0]
        else:
            dirs = win.rays_camera() @ (np.linalg.inv(T_c)[:3, :3] @ T_wc[:3, :3]).T
            # both in one cast: the rays of each from the camera as seen from its own centre
            origins = np.stack([np.broadcast_to(C - np.array([c[0], c[1], -shape.face]), dirs.shape)
                                for _, c in (reading, turned)])
            labs, ts = self.caster(prior.shape).labels(origins, dirs, np.array([reading[0], turned[0]]),
                                                       -psi, fine=True, with_t=True)
        colour = _contrast_ratio(*win.contrast(labs))
        out = dict(half_turn=colour, half_turn_colour=colour)
        if depth is not None:
            u0, v0, u1, v1 = win.box
            m = depth[v0:v1, u0:u1].ravel().astype(np.float64)
            dz = np.where(np.abs(dirs[:, 2]) > 1e-6, dirs[:, 2], 1e-6)
            panel = -(C[2] + shape.face) / dz          # the panel plane (z = 0 of the knob)
            slack = shape.face / max(math.cos(theta), 0.3) + 0.03
            valid = (m > 0) & (m > panel - slack) & (m < panel + 0.03)
            z = [np.where(np.isfinite(t), t, panel) for t in ts]
            differ = np.abs(z[0] - z[1]) > 1e-4
            agree, d = valid & ~differ, valid & differ
            if valid.mean() >= 0.3 and agree.sum() >= 10 and d.any():
                res, noise = [], 0.0
                for zh in z:
                    e = m - zh - float(np.median(m[agree] - zh[agree]))
                    res.append(float(e[d] @ e[d]))
                    noise += float(np.mean(e[agree] ** 2)) / 2
                out["half_turn_depth"] = _contrast_ratio(res[0], res[1], d.sum() * noise)
                out["half_turn"] += cfg.depth_weight * out["half_turn_depth"]
        return {k: round(float(v), 4) for k, v in out.items()}

    def _refine(self, rgb, K, T_wc, prior, shape, T_c, C, center, alphas0, psi, r_px,
                depth=None, theta=0.0, hold=False, exact_only=False, windows=None):
        """The exact check (module docstring, step 4): the knob rendered as the camera sees
        it, a ray through every image pixel around it from the real camera centre, at
        relative angles around each of ``alphas0`` (rad; the best coarse angle first), with
        its centre at the canvas offset ``center`` (m) and then where it fits best. A knob
        larger than ``decimate_above_px`` in the image is read in every other row and column
        of the image (point samples still, so the rendering models them exactly). Each
        label's pixels are sampled into the fine canvas exactly as the image is (bilinearly:
        soft label maps, ``_Window``) and the maps are fitted to the image (R^2). The
        offset: Gauss-Newton on a rendering (``_Window.settle``). The angle: renderings half a
        template step either side, a parabola through the best three (walking while an end
        is the best; the renderings of all candidates cast and fitted in one batch); with
        ``angle_stages`` 2, for the first candidate the offset again, then the same at a sixth
        of a step (one stage reads as well on most homes but lost packed pointers: home 4's
        state accuracy 0.34 -> 0.14). With ``depth``: each rendering's depth (the knob, else the panel plane) is
        correlated with the measured depth of the same image pixels, and the fit is the
        colour R^2 plus ``depth_weight`` times that squared correlation; the offset then stays
        within ``depth_settle_radii`` of where the depth put the knob (the colour alone of a
        knob without contrast can fit a marker flipped by 180 degrees a radius away).
        ``exact_only``: the fits at ``alphas0`` themselves, at ``center`` (no offset settled,
        no angle searched). ``windows``: a dict one reading keeps, of the windows its exact
        checks looked through by centre (a check at a centre another one ended at, the next
        state's, reuses its window: the same image, rays and fixed visuals' hits), and of
        the rays and depth fit of each image box (``pixels``; ``_half_turn`` reads both). Returns
        [(fit, knob angle, centre in the canvas frame)] per candidate."""
        cfg, tm = self.config, self.templates
        if r_px > cfg.decimate_above_px:
            rgb = rgb[::2, ::2]
            depth = None if depth is None else depth[::2, ::2]
            K = Intrinsics(K.fx / 2, K.fy / 2, K.cx / 2, K.cy / 2, rgb.shape[1], rgb.shape[0])
        rho = cfg.fine_px_per_radius / prior.radius
        n = 2 * int(math.ceil(tm.window_radii * cfg.fine_px_per_radius)) + 1
        caster = self.caster(prior.shape)
        R_canvas_cam = np.linalg.inv(T_c)[:3, :3] @ T_wc[:3, :3]
        max_shift = cfg.search_m * rho
        iterations = cfg.align_iterations
        if depth is not None:
            max_shift = min(max_shift, cfg.depth_settle_radii * cfg.fine_px_per_radius)
        slack = shape.face / max(math.cos(theta), 0.3) + 0.03
        w_depth = cfg.depth_weight

        H_plane = image_of_plane(K, T_wc, T_c)     # every window's homography: this, then its canvas

        def look(c) -> Optional[_Window]:
            key = (float(c[0]), float(c[1]), depth is None)
            if windows is not None and key in windows:
                return windows[key]
            win = _Window(rgb, K, H_plane @ _canvas_to_plane(rho, n, c), n, ridge=cfg.fine_ridge_px)
            if windows is not None:
                windows[key] = win if win.box is not None else None
            if win.box is None:
                return None
            O = C - np.array([c[0], c[1], -shape.face])
            dirs, depth_fit = pixels(win.box, O[2])
            # the fixed visuals' hits are the same for every rendering of this window
            fixed_hits: dict = {}
            win.render = lambda alphas: caster.labels(O, dirs, alphas, -psi, fine=True, with_t=True,
                                                      cache=fixed_hits)
            win.c = c
            win.depth_fit = depth_fit
            return win

        def pixels(box, height: float):
            """The rays of a box's pixels (canvas frame) and, with depth, the fit of the
            measured depth there to renderings' ray parameters (B, N) -> (B,), or None when
            under a third of it is valid. The same for every window on the same box (a
            window moved by a fraction of a pixel, ``settle``): the panel's place along a ray
            depends only on the camera's height over it (``height``, the same for every
            centre), so made once."""
            bkey = ("pixels", box, depth is None)
            got = windows.get(bkey) if windows is not None else None
            if got is not None:
                return got
            u0, v0, u1, v1 = box
            dirs = _box_rays(box, K) @ R_canvas_cam.T
            depth_fit = None
            if depth is not None:
                m = depth[v0:v1, u0:u1].ravel().astype(np.float64)
                dz = np.where(np.abs(dirs[:, 2]) > 1e-6, dirs[:, 2], 1e-6)
                panel = -height / dz                   # the panel plane (z = 0 of the knob)
                valid = (m > 0) & (m > panel - slack) & (m < panel + 0.03)
                if valid.mean() >= 0.3:
                    # ``depth_scores`` of the renderings' depths (compiled: the numpy calls
                    # cost more than the sums)
                    _, Wm, Sw, Sm, Smm, count = measured_heights(m[None], valid[None])
                    args = (panel, valid, Wm[0], float(Sw[0, 0]), float(Sm[0, 0]),
                            float(Smm[0, 0]), bool(count[0, 0] >= DEPTH_MIN_VALID * len(m)))

                    def depth_fit(ts, args=args):
                        out = np.empty(len(ts))
                        knob_kernels.depth_fits(np.ascontiguousarray(ts), *args, out)
                        return out
            got = (dirs, depth_fit)
            if windows is not None:
                windows[bkey] = got
            return got

        def scores(win, labs, ts) -> np.ndarray:
            """The fits of renderings (B, N) and their ray parameters, in one go."""
            f = win.fits(labs)
            return f + w_depth * win.depth_fit(ts) if win.depth_fit is not None else f

        def settle(win: _Window, alpha: float) -> Optional[_Window]:
            if hold:                       # the centre is held where it was given
                return win
            t = win.settle(win.render([alpha])[0][0], iterations, max_shift)
            if np.hypot(*t) <= 0.05:
                return win
            return look((win.c[0] + t[0] / rho, win.c[1] + t[1] / rho))

        win = look(center)
        win = settle(win, alphas0[0]) if win is not None and not exact_only else win
        if win is None:
            return [(0.0, float(_wrap(a + psi)), center) for a in alphas0]
        if exact_only:
            labs, ts = win.render([float(a) for a in alphas0])
            return [(float(sc), float(_wrap(a + psi)), win.c)
                    for sc, a in zip(scores(win, labs, ts), alphas0)]
        step = math.radians(tm.alpha_step_deg) / 2

        def search(win, starts, st, span=1):
            """Parabolic search of each start angle (one rendering for all of them), from
            ``span`` steps either side of it (the coarse angle of a small marker can be a
            few steps off)."""
            ks = list(range(-span, span + 1))
            labs, ts = win.render([a + k * st for a in starts for k in ks])
            fits = iter(scores(win, labs, ts).tolist())
            curves = [{k: next(fits) for k in ks} for _ in starts]     # by whole steps
            for _ in range(2):             # walk while an end is the best (all starts at once)
                steps = []
                for i, found in enumerate(curves):
                    top = max(found, key=found.get)
                    if top in (min(found), max(found)):
                        steps.append((i, top + (1 if top == max(found) else -1)))
                if not steps:
                    break
                labs, ts = win.render([starts[i] + k * st for i, k in steps])
                for (i, k), f in zip(steps, scores(win, labs, ts).tolist()):
                    curves[i][k] = f
            out = []
            for a, found in zip(starts, curves):
                top = max(found, key=found.get)
                y1, ym, yp = found[top], found.get(top - 1), found.get(top + 1)
                if ym is not None and yp is not None and ym - 2 * y1 + yp < 0:
                    x = float(np.clip(0.5 * (ym - yp) / (ym - 2 * y1 + yp), -0.5, 0.5))
                    out.append((float(y1 - 0.25 * (ym - yp) * x), a + (top + x) * st))
                else:
                    out.append((float(y1), a + top * st))
            return out

        found = search(win, [float(a) for a in alphas0], step, cfg.angle_span_steps)
        out = [(sc, float(_wrap(a + psi)), win.c) for sc, a in found]
        if cfg.angle_stages > 1:
            top = int(np.argmax([f[0] for f in found]))
            moved = settle(win, found[top][1])
            if moved is not None:
                sc, a = search(moved, [found[top][1]], step / 3)[0]
                out[top] = (sc, float(_wrap(a + psi)), moved.c)
        return out


def _label_lut(labels: np.ndarray) -> tuple[np.ndarray, int]:
    """The labels present in rendered label images (any shape): a table label -> 0..L-1 and
    L, so that label maps and normal equations have a row per label present only."""
    present = np.flatnonzero(np.bincount(labels.ravel()))
    lut = np.zeros(int(present[-1]) + 1, np.int64)
    lut[present] = np.arange(len(present))
    return lut, len(present)


def _box_rays(box, K: Intrinsics) -> np.ndarray:
    """Camera-frame directions (z = 1) through every pixel centre of an image box (u0, v0,
    u1, v1), row by row."""
    u0, v0, u1, v1 = box
    uu, vv = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    return np.stack([(uu.ravel() - K.cx) / K.fx, (vv.ravel() - K.cy) / K.fy, np.ones(uu.size)], 1)


_GRIDS: dict = {}


def _window_grid(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An n x n window's pixel columns and rows (N,) and their homogeneous points (3, N),
    made once per size (read-only: every window of that size shares them)."""
    got = _GRIDS.get(n)
    if got is None:
        jj, ii = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64))
        jj, ii = jj.ravel(), ii.ravel()
        got = (jj, ii, np.stack([jj, ii, np.ones_like(jj)]))
        for a in got:
            a.flags.writeable = False
        _GRIDS[n] = got
    return got


class _Window:
    """The fine canvas window of an image (``H``: window px -> image px) and how rendered
    label images of the pixels it covers (the box ``box`` = (u0, v0, u1, v1)) become soft
    label maps of the window: each window pixel takes the labels of its four image
    neighbours with the bilinear weights ``cv2.warpPerspective`` gives it, so the maps mix
    labels exactly as the image mixes colours. Shifting the maps by ``t`` (window px,
    canvas x right, y up) samples the rendered labels elsewhere (no new rendering)."""

    def __init__(self, image: np.ndarray, K: Intrinsics, H: np.ndarray, n: int, pad: int = 3,
                 ridge: float = 0.0):
        self.n, self.H, self.K, self.ridge = n, H, K, ridge
        self.window = rectify(image, H, n).astype(np.float32)
        X = self.window.reshape(-1, 3).astype(np.float64)
        self.X = X
        # centred: the ridge (``_solve``) pulls a label's colour towards the window's mean
        self.Xc = X - X.mean(0)
        total = X.sum(0)
        self.sum_sq = float((X * X).sum())
        self.mean_part = float((total * total).sum()) / len(X)
        self.tv = self.sum_sq - self.mean_part
        self.jj, self.ii, self._grid = _window_grid(n)
        uv = self._uv0 = self._image_points(0.0, 0.0)
        if uv is None:
            self.box = None
            return
        u0, v0 = int(np.floor(uv[0].min())) - pad, int(np.floor(uv[1].min())) - pad
        u1, v1 = int(np.ceil(uv[0].max())) + pad + 1, int(np.ceil(uv[1].max())) + pad + 1
        u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, K.width), min(v1, K.height)
        self.box = (u0, v0, u1, v1) if u1 - u0 >= 2 and v1 - v0 >= 2 else None

    def _image_points(self, tx: float, ty: float):
        """Image coordinates (2, N) of the window pixels shifted by -t (the knob moved by t)."""
        grid = self._grid if tx == 0.0 and ty == 0.0 else np.stack([self.jj - tx, self.ii + ty,
                                                                   self._grid[2]])
        p = self.H @ grid
        if np.any(p[2] <= 0):
            return None
        return p[:2] / p[2]

    def rays_camera(self) -> np.ndarray:
        """Camera-frame directions (z = 1) through every pixel centre of the box."""
        return _box_rays(self.box, self.K)

    def _sampling(self, t) -> tuple[np.ndarray, np.ndarray]:
        """The four box pixels (4, N) each window pixel mixes, and their bilinear weights,
        with the knob shifted by ``t`` (cached for no shift)."""
        key = (float(t[0]), float(t[1]))
        if key == (0.0, 0.0) and getattr(self, "_sampling0", None) is not None:
            return self._sampling0
        u0, v0, u1, v1 = self.box
        w, h = u1 - u0, v1 - v0
        uv = self._uv0 if key == (0.0, 0.0) else self._image_points(*key)
        x = np.clip(uv[0] - u0, 0, w - 1)
        y = np.clip(uv[1] - v0, 0, h - 1)
        x0 = np.minimum(np.floor(x).astype(np.int64), w - 2)
        y0 = np.minimum(np.floor(y).astype(np.int64), h - 2)
        fx, fy = x - x0, y - y0
        base = y0 * w + x0
        idx = np.stack([base, base + 1, base + w, base + w + 1])
        wts = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
        if key == (0.0, 0.0):
            self._sampling0 = (idx, wts)
        return idx, wts

    def maps(self, labels: np.ndarray, t=(0.0, 0.0)) -> np.ndarray:
        """(L', N) soft label maps of a rendered box label image (flat), shifted by ``t``."""
        idx, wts = self._sampling(t)
        lut, L = _label_lut(labels)
        W = np.zeros((L, self.n * self.n))
        knob_kernels.label_maps(labels, lut, idx, wts, W)     # (np.bincount's sums, compiled)
        return W

    def _solve(self, W: np.ndarray):
        """Each label's colour (least squares, centred on the window's mean): a ridge of
        ``ridge`` pixels, so that a label only a pixel or two wide (a side face seen edge-on)
        cannot explain the noise or the blurred edge of a marker it happens to fall on."""
        G = W @ W.T
        b = W @ self.Xc
        G.flat[::len(G) + 1] += 1e-6 + self.ridge
        try:
            mu = np.linalg.solve(G, b)
        except np.linalg.LinAlgError:
            mu = np.linalg.lstsq(G, b, rcond=None)[0]
        return mu, b

    def fits(self, labels: np.ndarray) -> np.ndarray:
        """R^2 of the least-squares mix of each of B renderings' (B, N box pixels) soft label
        maps (each label one colour) to the window, at no shift, solved together: the labels
        of all of them are the columns of one batch (a label a rendering lacks has no pixels,
        its colour solves to 0 and adds nothing: the same fit as alone)."""
        B = len(labels)
        if self.tv <= 1e-6 * len(self.X):
            return np.zeros(B)
        idx, wts = self._sampling((0.0, 0.0))
        # each window pixel mixes four box pixels' labels: the Gram matrix W W^T and W X are
        # sums over pixels of those four labels' weight products (sparse, no dense W; the
        # sums np.bincount made), solved, compiled: hearth/perception/knob_kernels.py
        out = np.empty(B)
        knob_kernels.label_fits(np.ascontiguousarray(labels), idx, wts, self.Xc,
                                1e-6 + self.ridge, out)
        return out / self.tv

    def contrast(self, labels: np.ndarray) -> tuple[float, float, float]:
        """The colour residual (sum of squares) of each of two renderings (2, N box pixels)
        over the window pixels whose labels differ between them, each pixel weighted by the
        share of its label weights that differ (``KnobReader._half_turn``), and what the
        residual of those pixels would be if they fitted as well as the window does on
        average (the weights' sum times the mean residual per pixel of the two renderings over
        the whole window: the noise and the edges every pixel has); each rendering's label
        colours are its own least-squares fit over the whole window."""
        idx, wts = self._sampling((0.0, 0.0))
        lut, L = _label_lut(labels)
        N = self.n * self.n
        maps = [np.zeros((L, N)) for _ in labels]
        for lab, W in zip(labels, maps):
            knob_kernels.label_maps(lab, lut, idx, wts, W)
        differ = 0.5 * np.abs(maps[0] - maps[1]).sum(0)
        out, everywhere = [], 0.0
        for one in labels:
            # the Gram matrix and W X as sums over the four labels each pixel mixes (as
            # ``fits``: a dense W W^T of a shape with many labels cost 30 ms)
            G, b = np.zeros((1, L, L)), np.zeros((1, L, 3))
            knob_kernels.label_gram(one[None], lut, idx, wts, self.Xc, G, b)
            G, b = G[0], b[0]
            lab = lut[one[idx]]                                           # (4, N)
            G.flat[::L + 1] += 1e-6 + self.ridge
            mu = np.linalg.solve(G, b)
            r2 = ((self.Xc - np.einsum("kn,knc->nc", wts, mu[lab])) ** 2).sum(1)
            out.append(float(differ @ r2))
            everywhere += float(r2.mean()) / 2
        return out[0], out[1], float(differ.sum()) * everywhere

    def settle(self, labels: np.ndarray, iterations: int, max_shift: float) -> np.ndarray:
        """The shift t (px, canvas x right, y up) of the rendered knob that fits the window
        best: Gauss-Newton (Lucas-Kanade) with the model image's gradient, compiled
        (``hearth.perception.knob_kernels.settle_shift``: the numpy loop it replaces cost a fifth of
        a reading in small array operations; tests/knobs/test_knob_kernels.py keeps it as the
        reference, shifts within 1e-12 px)."""
        lut, L = _label_lut(labels)
        t = knob_kernels.settle_shift(labels, lut, L, self.H, self.jj, self.ii,
                                      np.asarray(self.box, np.int64), self.Xc, self.n,
                                      float(self.ridge), int(iterations), float(max_shift))
        return np.array(t)


def _contrast_ratio(sse: float, sse_other: float, expected: float = 0.0) -> float:
    """(other - this) / (other + this + 2 expected) of two residual sums over the same
    pixels, ``expected`` what each would be if those pixels fitted as well as the rest (so
    that two fits of the noise alone, both small, come out near 0, not anywhere in [-1, 1]):
    in (-1, 1), 0 when they are equal."""
    total = sse + sse_other + 2 * expected
    return (sse_other - sse) / total if total > 1e-12 else 0.0


def allowed_angle(prior: KnobPrior, angle: float, margin: float = math.radians(15)) -> bool:
    """Whether a knob angle (rad) lies within the knob's travel (``KnobPrior.travel``, widened
    by ``margin``; modulo its period for a symmetric knob)."""
    if prior.travel is None:
        return True
    lo, hi = prior.travel
    period = 2 * math.pi / max(1, prior.symmetry)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 + margin
    d = abs(math.remainder(angle - mid, period))
    return d <= half


def _with_half_turn(alphas: np.ndarray, picks: list, allowed: np.ndarray) -> list:
    """``picks`` (indices of ``alphas``, the best first) and the allowed angle nearest the
    best one's half turn, within 45 degrees, where it is not among them."""
    d = np.where(allowed, np.abs(_wrap(alphas - alphas[picks[0]] - math.pi)), np.inf)
    flip = int(np.argmin(d))
    return picks + [flip] if flip not in picks and d[flip] < math.radians(45) else picks


def allowed_angles(prior: KnobPrior, angles, margin: float = math.radians(15)) -> np.ndarray:
    """``allowed_angle`` of each of ``angles`` (rad), in one go: the same remainders (each
    exact: ``np.fmod``'s, moved into the half period either side by a subtraction that is
    exact too), so the same answers."""
    angles = np.asarray(angles, dtype=float)
    if prior.travel is None:
        return np.ones(angles.shape, bool)
    lo, hi = prior.travel
    period = 2 * math.pi / max(1, prior.symmetry)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 + margin
    r = np.fmod(angles - mid, period)
    r = np.where(r > period / 2, r - period, np.where(r < -period / 2, r + period, r))
    return np.abs(r) <= half


def read_knobs(image, K, T_world_camera, priors, reader: KnobReader) -> tuple[list[KnobReading], float]:
    """Readings and the time they took (s)."""
    t0 = time.perf_counter()
    out = reader.read(image, K, T_world_camera, priors)
    return out, time.perf_counter() - t0


# -- round bodies: the centre from the depth at the image's own resolution -----------------------

def round_body_levels(shape: KnobShape, tol: float = 0.02) -> Optional[tuple[float, ...]]:
    """The heights (m above the panel, ascending) of the flat tops of a knob whose body (every
    visual but the markers) is round about its axis: cylinders and discs centred on it (a
    skirt, a cap; the plain knob), so that only the marker tells its angle and the depth of
    its body says nothing of it. None for any other shape (a grip bar, a pointer), for a
    shape without a marker, or a symmetric one. ``tol``: how far (share of the outline radius)
    a visual's rim may stray from a circle about the axis."""
    if shape.symmetry != 1 or "marker" not in shape.roles:
        return None
    levels = []
    for v, role in zip(shape.vertices, shape.roles):
        if role == "marker":
            continue
        rad = np.hypot(v[:, 0], v[:, 1])
        rim = rad > 0.5 * rad.max()
        if (not rim.any() or np.ptp(rad[rim]) > tol * shape.radius
                or abs(v[rim, 0].mean()) > tol * shape.radius or abs(v[rim, 1].mean()) > tol * shape.radius):
            return None
        levels.append(float(v[:, 2].max()))
    if not levels:
        return None
    return tuple(sorted({round(z, 5) for z in levels}))


def body_center(depth: np.ndarray, K: Intrinsics, T_wc: np.ndarray, T_c: np.ndarray, shape: KnobShape,
                caster: "_Caster", levels: Sequence[float], center, alpha: float, psi: float,
                iterations: int = 4, roi_radii: float = 1.35, min_pixels: int = 8):
    """The centre (m, canvas frame of ``T_c``) of a round-bodied knob (``round_body_levels``)
    from the depth image at its own pixels, starting at ``center``: the pixels measured
    above the mid-height between the body's top and the step below it (the cap over the
    skirt), and the same pixels of the body rendered at the current centre (the exact caster,
    the real camera), each mask's centroid taken on the plane of the top; the centre moves by the
    difference of the measured and rendered centroids until it settles. Only the top's mask
    (the pixels above the mid-height between the top and the step below it) is used: the
    marker stands on it. A shift of the knob along its face shifts the mask's centroid by as much,
    while what the view does to the masks (a side wall seen obliquely, the pixel lattice,
    the rim's share of pixels) is the same in both: so the centre comes to a fraction of a
    pixel from a hundred or more rim pixels, where the correlation peak of the canvas heights
    (8 px per radius, ``_depth_center``) places it to about a millimetre. Hand-written: no
    library fits a rendered step-edge outline with perspective and occlusion.
    Returns (centre, dict(pixels, moved_m)) or None when too few pixels were measured."""
    R_canvas_cam = np.linalg.inv(T_c)[:3, :3] @ T_wc[:3, :3]
    C = (np.linalg.inv(T_c) @ np.append(T_wc[:3, 3], 1.0))[:3]
    face = shape.face
    # the image box: the body's outline on the panel and on the face plane
    T_cam_canvas = np.linalg.inv(T_wc) @ T_c
    a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
    rr = roi_radii * shape.radius
    pts = []
    for z in (0.0, -face):
        P = np.stack([center[0] + rr * np.cos(a), center[1] + rr * np.sin(a), np.full_like(a, z),
                      np.ones_like(a)])
        pts.append((T_cam_canvas @ P)[:3])
    P = np.concatenate(pts, 1)
    if np.any(P[2] <= 1e-3):
        return None
    u = K.fx * P[0] / P[2] + K.cx
    v = K.fy * P[1] / P[2] + K.cy
    u0, v0 = max(int(np.floor(u.min())), 0), max(int(np.floor(v.min())), 0)
    u1, v1 = min(int(np.ceil(u.max())) + 1, K.width), min(int(np.ceil(v.max())) + 1, K.height)
    if u1 - u0 < 3 or v1 - v0 < 3:
        return None
    uu, vv = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    dc = np.stack([(uu.ravel() - K.cx) / K.fx, (vv.ravel() - K.cy) / K.fy, np.ones(uu.size)], 1)
    d = dc @ R_canvas_cam.T
    dz = np.where(np.abs(d[:, 2]) > 1e-9, d[:, 2], -1e-9)
    Zm = np.asarray(depth, dtype=np.float64)[v0:v1, u0:u1].ravel()
    hm = C[2] + Zm * d[:, 2] + face                   # measured height above the panel
    Pm = C[None, :2] + Zm[:, None] * d[:, :2]          # the measured points on the face's axes
    valid = (Zm > 0) & (hm > -0.03) & (hm < face + 0.03)
    tops = [float(z) for z in levels]
    taus = [(lo + hi) / 2 for lo, hi in zip([0.0] + tops[:-1], tops)]
    # each pixel's ray on the top's plane (canvas z = top - face)
    q = [C[None, :2] + d[:, :2] * ((tops[-1] - face - C[2]) / dz)[:, None]]
    q_panel = C[None, :2] + d[:, :2] * ((-face - C[2]) / dz)[:, None]
    q_face = C[None, :2] + d[:, :2] * ((0.0 - C[2]) / dz)[:, None]
    c = np.array(center, dtype=float)
    moved, used = 0.0, 0
    for _ in range(iterations):
        roi = valid & ((np.hypot(*(q_panel - c).T) <= rr) | (np.hypot(*(q_face - c).T) <= rr))
        O = C - np.array([c[0], c[1], -face])
        _lab, t = caster.labels(O, d, np.array([alpha]), -psi, with_t=True)
        t = t[0]
        hr = np.where(np.isfinite(t), C[2] + t * d[:, 2] + face, 0.0)
        panel = roi & ~np.isfinite(t)
        if panel.sum() < min_pixels:
            return None
        # the top's rim only: the marker stands on the top, and a lower step's centre (the
        # skirt's) is off the top's when the believed axis leans (and its step over the
        # panel is nearer the depth noise): home 1's centre error 0.60 -> 0.36 mm at the
        # median (p90 1.20 -> 0.89) against both steps weighted by their pixels
        mr = roi & (hr > taus[-1])
        nr = int(mr.sum())
        if nr < min_pixels or not (mr & valid).any():
            return None
        # the measured heights put on the rendered ones by the top itself (the median
        # difference over the rendered top), not by the panel: a knob standing half a
        # millimetre off its panel (a bezel's gap, a recess) moved the cut on the side wall
        # the camera sees, and with it the centre towards the camera, 0.1-0.4 mm with the
        # obliquity on views without noise (docs/knobs.md, "The top as the reference")
        off = float(np.median(hm[mr & valid] - hr[mr & valid]))
        mm = np.flatnonzero(roi)                       # indices, the masks' in their order
        mm = mm[hm[mm] - off > taus[-1]]
        # only measured top pixels that could be this knob's: on the top's plane within its
        # rendered radius and a quarter radius more. A packed neighbour's top (2 radii away,
        # its edge inside the region of interest) would pull the centroid towards it, and
        # each step pulls more: home 8's skirt knobs 2.15 radii apart, centres 7-17 mm off
        # towards the neighbour and dot angles 20-45 degrees off on a quarter of the views.
        r_top = float(np.hypot(*(q[-1][mr] - c).T).max())
        mm = mm[np.hypot(*(q[-1][mm] - c).T) <= r_top + 0.25 * shape.radius]
        # ... and whose measured point itself lies within the rendered top's radius of the
        # axis and half a radius more (a quarter cut noisy rims: home 784's centre p90 1.4 ->
        # 2.6 mm). Projected onto the top's plane, a neighbour's tall cap seen over the knob
        # from 45-60 degrees came within reach, and the centre walked towards it 5-17 mm on
        # views without noise (homes 8 and 17; docs/knobs.md, "Points, not their shadows")
        r3 = float(np.hypot(*(C[None, :2] + t[mr][:, None] * d[mr, :2] - c).T).max())
        mm = mm[np.hypot(*(Pm[mm] - c).T) <= r3 + 0.5 * shape.radius]
        used = int(mm.size)
        if used < min_pixels:
            return None
        step = q[-1][mm].mean(0) - q[-1][mr].mean(0)
        c = c + step
        moved = float(np.hypot(*(c - np.asarray(center))))
        # settled to a tenth of a millimetre (0.02 mm: nearly every call ran its four casts,
        # the depth's noise moving it more than that; the dot's angle moves by 0.5 degrees
        # at most)
        if np.hypot(*step) < 1e-4:
            break
    return (float(c[0]), float(c[1])), dict(pixels=used, moved_m=moved)


def marker_dot(shape: KnobShape) -> Optional[tuple[float, float, float, float]]:
    """Where a round-bodied knob's marker stands at angle 0: (angle about the axis, rad
    counter-clockwise from +y; its distance from the axis; its radius (m, the farthest of its
    points from its centre, in the face plane); the radius of the top it stands on), or None
    without a marker."""
    if "marker" not in shape.roles:
        return None
    mv = np.concatenate([v for v, r in zip(shape.vertices, shape.roles) if r == "marker"])
    m = mv[:, :2].mean(0)
    rho = float(np.hypot(*m))
    size = float(np.max(np.hypot(mv[:, 0] - m[0], mv[:, 1] - m[1])))
    body = [(float(v[:, 2].max()), float(np.hypot(v[:, 0], v[:, 1]).max()))
            for v, r in zip(shape.vertices, shape.roles) if r != "marker"]
    top = max(body)[1] if body else shape.radius
    return math.atan2(-m[0], m[1]), rho, size, top


def marker_proud(shape: KnobShape) -> float:
    """How far (m) a knob's marker stands out of the top of the rest of the knob (0: none,
    flush or sunk)."""
    if "marker" not in shape.roles:
        return 0.0
    mz = max(float(v[:, 2].max()) for v, r in zip(shape.vertices, shape.roles) if r == "marker")
    body = [float(v[:, 2].max()) for v, r in zip(shape.vertices, shape.roles) if r != "marker"]
    return max(0.0, mz - max(body)) if body else 0.0


def dot_profile(rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, T_c: np.ndarray, shape: KnobShape,
                center, px_per_radius: float = 32.0, step_deg: float = 1.0):
    """How much a marker-sized disc on the knob's top differs in colour from the top, at each
    relative angle (canvas frame of ``T_c``, ``step_deg`` apart) about ``center`` (m, canvas
    frame): the face plane rectified at ``px_per_radius`` about the centre, each pixel's
    colour distance from the top's median colour (the top without the marker), averaged over
    a disc of the marker's size (its image is blurred: a matched filter) at the marker's
    distance from the axis. Returns (angles of the marker at relative angle 0 added, rad;
    responses; the top's robust colour noise per pixel) or None (no marker)."""
    md = marker_dot(shape)
    if md is None:
        return None
    a0, rho_d, size, top = md
    rho = px_per_radius / shape.radius
    n = 2 * int(math.ceil(top * rho)) + 3
    H = plane_homography(K, T_wc, T_c, rho, n, center)
    win = rectify(rgb, H, n).astype(np.float32)
    c = (n - 1) / 2.0
    jj, ii = np.meshgrid(np.arange(n) - c, np.arange(n) - c)
    on_top = np.hypot(jj, ii) <= top * rho - 1.0
    if on_top.sum() < 20:
        return None
    ref = np.median(win[on_top], axis=0)
    D = np.linalg.norm(win - ref, axis=2).astype(np.float32)
    noise = float(np.median(D[on_top]) * 1.4826 + 1e-3)
    # disc sample points of the marker's size, its centre on the canvas (x right, y up)
    rr = np.sqrt(np.linspace(0.0, 1.0, 6)[1:])[:, None] * size * 0.8
    tt = np.linspace(0.0, 2 * math.pi, 10, endpoint=False)[None, :]
    disc = np.concatenate([[[0.0, 0.0]], np.stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()], 1)])
    # a marker standing proud of the top shows its side to the camera: seen on the face plane
    # (the marker's top) that side lies towards the camera, by up to its height times the
    # tangent of the obliquity. The disc swept that way is what the marker looks like; a disc
    # alone found it that far towards the camera (on views without noise, the reading's angle
    # error correlated -0.8 with the sine of the marker's direction from the camera's beyond
    # 45 degrees: docs/knobs.md, "The marker's side")
    proud = marker_proud(shape)
    if proud > 0:
        cam = (np.linalg.inv(T_c) @ np.append(T_wc[:3, 3], 1.0))[:3]
        v = cam[:2] - np.asarray(center, dtype=float)
        if cam[2] > 1e-6 and np.hypot(*v) > 1e-9:
            sweep = v * (proud / cam[2])             # towards the camera, proud * tan(obliquity)
            disc = np.concatenate([disc + f * sweep for f in (0.0, 0.5, 1.0)])
    alphas = np.radians(np.arange(0.0, 360.0, step_deg))
    mx, my = -rho_d * np.sin(alphas + a0), rho_d * np.cos(alphas + a0)
    X = (mx[:, None] + disc[None, :, 0]) * rho + c
    Y = c - (my[:, None] + disc[None, :, 1]) * rho
    S = cv2.remap(D, X.astype(np.float32), Y.astype(np.float32), cv2.INTER_LINEAR).mean(1)
    return alphas, S, noise
