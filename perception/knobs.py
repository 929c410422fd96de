"""Knob detection and reading (RAMCIP D3.1 5.2.1.2 to 5.2.1.4): HOG + linear SVM detector,
HOG + random forest (36 classes of 10 degrees) and HOG + linear SVR (cos, sin) angle models,
snapping to the knob's discrete states from the map.

Where RAMCIP slides a 48x48 window over a 4-level image pyramid of the raw image, we first
**rectify** the region around each knob with the knob plane known from the map (the registered
or believed knob pose): a homography maps the knob's front-face plane to a *canvas* in which
the knob is seen head-on at a fixed scale (``KnobConfig.px_per_radius`` pixels per knob
radius), whatever the distance (0.5-1.5 m) and the viewing angle (up to 60 degrees off-axis).
The detector and the angle models then only have to cope with what rectification leaves:
registration error (the knob is off the canvas centre: the search), a few percent of scale
(a small pyramid of ``scales``), blur, noise, lighting and the cylinder's side seen obliquely.
An angle read in the canvas is directly the knob's angle about its axis: the canvas axes are
the knob frame's x (right) and y (up) at angle 0.

Everything here is pure: images and poses in, readings out. Estimators have the scikit-learn
shape (the constructor stores parameters, ``fit`` returns self, learned attributes end in
``_``, every other method starts with ``check_is_fitted``, ``predict(X)`` never trains and
answers what the reader uses); their ``X`` is *patches*: (N, P, P) uint8 grey windows with
``P = WINDOW + 2 * BORDER`` (the 48x48 window plus a 2-pixel context border so that HOG
gradients at the window's edge are those of the canvas), or the HOG features of patches.
Training is perception/knob_training.py; storing the models is worldmodel/model_store.py,
asked by skills/knob_models.py.

Frames: ``T_world_camera`` maps camera points (OpenCV axes) to the world; a knob's
``T_world_knob`` is its frame at angle 0 (``worldmodel.nodes.Knob``: +z out of the panel, the
marker at +y at angle 0, angles counter-clockwise about +z); angles are radians in
(-pi, pi].
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Optional, Sequence

import cv2
import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, RegressorMixin
from sklearn.ensemble import RandomForestClassifier
from sklearn.svm import LinearSVC, LinearSVR
from sklearn.utils.validation import check_is_fitted

from perception.camera import Intrinsics
from perception.trained import read_time, trained_fields

WINDOW = 48
BORDER = 2
PATCH = WINDOW + 2 * BORDER
N_CLASSES = 36
ANGLE_METHODS = ("forest", "svr", "fused")


@dataclass(frozen=True)
class KnobConfig:
    """``px_per_radius``: canvas pixels per knob radius (16: the knob's face is 32 px wide in
    a 48 px window); ``search_px``: how far (canvas px at scale 1, 18 px = 2.5 cm for a 22 mm
    knob) the knob may be from where the map puts it; ``scales``: the pyramid (canvas scale
    factors); ``threshold``: SVM score a window needs (None: the detector's own
    ``threshold_``, calibrated on validation views in training, else 0); ``nms_iou``: overlap
    at which NMS drops the weaker window; ``angle_method``: forest, svr or fused (see ``KnobReader``);
    ``min_confidence``: below it the state is "unknown"; ``max_off_axis_deg``: a knob seen
    more obliquely is not read; ``angle_shifts_px``: the angle models read five windows, at
    the detected centre and shifted this far left, right, up and down, and average (0: one
    window), which makes them tolerant of a detection a few pixels off; ``view_aligned``: the
    canvas is turned about the knob's axis so that the direction towards the camera is always
    canvas-up (``KnobPrior.canvas_frame``). Fields declared ``read_time`` can change without
    retraining; every other one is part of the stored model's configuration."""
    px_per_radius: float = 16.0
    search_px: int = 18
    scales: tuple[float, ...] = (0.87, 1.0, 1.15)
    threshold: Optional[float] = read_time(None)
    nms_iou: float = read_time(0.3)
    angle_method: str = read_time("fused")
    fuse_gate_deg: float = read_time(15.0)
    min_confidence: float = read_time(0.3)
    max_off_axis_deg: float = read_time(70.0)
    angle_shifts_px: float = read_time(2.0)
    view_aligned: bool = True

    def trained_fields(self) -> dict:
        """The fields the knob models are trained with (the others, declared ``read_time``,
        change how a trained reader reads and need no retraining)."""
        return trained_fields(self)


# -- the knobs the map knows --------------------------------------------------------------------

@dataclass(frozen=True)
class KnobPrior:
    """What the map says of one knob: its frame at angle 0 in the world (registered or
    believed), radius and depth (m), and its discrete states (names, angles in rad)."""
    knob_id: str
    T_world_knob: np.ndarray
    radius: float
    depth: float
    state_names: tuple[str, ...]
    state_angles: tuple[float, ...]

    def T_world_face(self) -> np.ndarray:
        """The knob's front face (z = depth) at angle 0."""
        T = self.T_world_knob.copy()
        T[:3, 3] = T[:3, 3] + T[:3, 2] * self.depth
        return T

    def canvas_frame(self, T_world_camera: np.ndarray, aligned: bool = True) -> tuple[np.ndarray, float]:
        """The face frame turned by ``psi`` about the knob's axis so that its +y points towards
        the camera (projected on the face plane), and ``psi`` (rad); (face frame, 0) when not
        ``aligned``. Seen off-axis, the knob's cylindrical side shows on the face plane on the
        side away from the camera; in this frame it always lies below the face, so the models
        learn one appearance per relative angle instead of one per direction of view. A marker
        at knob angle a is at a - psi in this frame."""
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


def knob_priors(world, object_id: Optional[str] = None,
                T_world_object: Optional[np.ndarray] = None) -> list[KnobPrior]:
    """Priors of every knob in the map (or of one object's knobs). ``T_world_object``: the
    object's registered pose, when it differs from the map's."""
    out = []
    for k in world.knobs(object_id):
        T_wp = world.T_world(world.parent(k.id).id)
        if T_world_object is not None and object_id is not None:
            T_wp = T_world_object @ np.linalg.inv(world.T_world(object_id)) @ T_wp
        out.append(KnobPrior(k.id, T_wp @ k.pose.matrix(), float(k.radius), float(k.depth),
                             tuple(s.name for s in k.states), tuple(float(s.angle) for s in k.states)))
    return out


# -- rectification ---------------------------------------------------------------------------------

def plane_homography(K: Intrinsics, T_world_camera: np.ndarray, T_world_plane: np.ndarray,
                     px_per_m: float, size: int, center=(0.0, 0.0)) -> np.ndarray:
    """3x3 homography from canvas pixels to image pixels: the canvas is ``size`` px square,
    shows the plane z = 0 of ``T_world_plane`` head-on at ``px_per_m``, its centre pixel at
    plane point ``center`` (m), canvas right = plane +x, canvas up = plane +y."""
    T_cp = np.linalg.inv(T_world_camera) @ T_world_plane
    H_img_plane = K.matrix() @ np.column_stack([T_cp[:3, 0], T_cp[:3, 1], T_cp[:3, 3]])
    c = (size - 1) / 2.0
    A = np.array([[1.0 / px_per_m, 0.0, center[0] - c / px_per_m],
                  [0.0, -1.0 / px_per_m, center[1] + c / px_per_m],
                  [0.0, 0.0, 1.0]])
    return H_img_plane @ A


def rectify(gray: np.ndarray, H_img_canvas: np.ndarray, size: int) -> np.ndarray:
    """The ``size`` x ``size`` canvas seen through ``H_img_canvas`` (uint8)."""
    return cv2.warpPerspective(gray, H_img_canvas, (size, size),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REPLICATE)


def to_gray(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return image if image.dtype == np.uint8 else np.clip(image, 0, 255).astype(np.uint8)
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)


def rotate_xy(xy, psi: float) -> tuple[float, float]:
    """A plane point turned by ``psi`` (rad, counter-clockwise)."""
    c, s = math.cos(psi), math.sin(psi)
    return (c * xy[0] - s * xy[1], s * xy[0] + c * xy[1])


def canvas_homography(K: Intrinsics, T_world_camera: np.ndarray, prior: KnobPrior, px_per_m: float,
                      size: int, center_m=(0.0, 0.0), cfg: KnobConfig = KnobConfig()) -> tuple[np.ndarray, float]:
    """The homography of a knob's canvas (``plane_homography`` of ``KnobPrior.canvas_frame``)
    centred at ``center_m`` (knob face x, y in m), and the canvas's turn ``psi``."""
    T_c, psi = prior.canvas_frame(T_world_camera, cfg.view_aligned)
    return plane_homography(K, T_world_camera, T_c, px_per_m, size, rotate_xy(center_m, -psi)), psi


def face_patch(gray: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray, prior: KnobPrior,
               center_m=(0.0, 0.0), scale: float = 1.0, cfg: KnobConfig = KnobConfig(),
               size: int = PATCH) -> np.ndarray:
    """A rectified patch of the knob's face plane centred at ``center_m`` (knob face x, y in
    m), at ``scale`` times the canonical scale, in the canvas frame (view-aligned or not)."""
    rho = cfg.px_per_radius * scale / prior.radius
    H, _ = canvas_homography(K, T_world_camera, prior, rho, size, center_m, cfg)
    return rectify(gray, H, size)


def off_axis_deg(T_world_camera: np.ndarray, prior: KnobPrior) -> float:
    """Angle between the knob's axis and the direction from the knob to the camera."""
    v = T_world_camera[:3, 3] - prior.T_world_face()[:3, 3]
    c = float(np.dot(v, prior.T_world_knob[:3, 2]) / max(np.linalg.norm(v), 1e-9))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


# -- HOG ---------------------------------------------------------------------------------------------

#: Detector HOG after RAMCIP 5.2.1.3: 6x6-pixel cells, 9 contrast-insensitive orientations,
#: 2x2-cell L2-Hys blocks clipped at 0.2 (OpenCV's default), 1764 values per 48x48 window.
DETECTOR_HOG = dict(win=(WINDOW, WINDOW), block=(12, 12), stride=(6, 6), cell=(6, 6), nbins=9)
#: Angle HOG: 8x8 cells, 18 orientations over 360 degrees (signed: the dark marker on the light
#: face has a direction), 2x2-cell blocks: 1800 values. RAMCIP used 12x12 cells with 36
#: unsigned orientations; finer cells keep where the marker is, which the angle mostly is.
ANGLE_HOG = dict(win=(WINDOW, WINDOW), block=(16, 16), stride=(8, 8), cell=(8, 8), nbins=18,
                 signed=True)

_HOGS: dict = {}


def _hog_class():
    """OpenCV's HOGDescriptor: in every OpenCV 4 wheel; OpenCV 5 moved it to the contrib
    modules (opencv-contrib-python-headless 5.x binds it as ``cv2.HOGDescriptor`` again)."""
    hog = getattr(cv2, "HOGDescriptor", None)
    if hog is None:
        from perception.errors import PerceptionError
        raise PerceptionError(f"OpenCV {cv2.__version__} has no HOGDescriptor (OpenCV 5 moved it "
                              "to the contrib modules): install opencv-contrib-python-headless "
                              "or opencv-python-headless<5")
    return hog


def hog_descriptor(spec: dict) -> "cv2.HOGDescriptor":
    key = tuple(sorted((k, tuple(v) if isinstance(v, (list, tuple)) else v) for k, v in spec.items()))
    if key not in _HOGS:
        _HOGS[key] = _hog_class()(tuple(spec["win"]), tuple(spec["block"]), tuple(spec["stride"]),
                                  tuple(spec["cell"]), int(spec["nbins"]), 1, -1.0,
                                  cv2.HOGDescriptor_L2Hys, 0.2, False, 64,
                                  bool(spec.get("signed", False)))
    return _HOGS[key]


def hog_features(patches: np.ndarray, spec: dict) -> np.ndarray:
    """(N, D) float32 HOG of the 48x48 window inside each (N, PATCH, PATCH) patch."""
    hog = hog_descriptor(spec)
    patches = np.asarray(patches, dtype=np.uint8)
    if patches.ndim == 2:
        patches = patches[None]
    loc = ((BORDER, BORDER),)
    return np.stack([hog.compute(np.ascontiguousarray(p), (8, 8), (0, 0), loc).ravel()
                     for p in patches]).astype(np.float32)


def hog_length(spec: dict) -> int:
    """Values per window of a HOG spec."""
    return int(hog_descriptor(spec).getDescriptorSize())


def _features(X, spec: dict) -> np.ndarray:
    """The estimators' input ``X``: (N, PATCH, PATCH) uint8 patches, or (N, D) HOG features of
    them already computed with ``spec`` (the reader computes the angle HOG once for both
    angle models)."""
    X = np.asarray(X)
    if X.ndim == 2 and X.shape[1] == hog_length(spec):
        return X.astype(np.float32, copy=False)
    if X.ndim != 3 or X.shape[1:] != (PATCH, PATCH):
        raise ValueError(f"expected (n, {PATCH}, {PATCH}) patches or (n, {hog_length(spec)}) "
                         f"HOG features, got shape {X.shape}")
    return hog_features(X, spec)


# -- estimators --------------------------------------------------------------------------------------

class KnobDetector(BaseEstimator, ClassifierMixin):
    """HOG + linear SVM: is a knob centred in this window? ``fit(X, y)`` with y 1 for a knob
    centred within a few pixels at about the canonical scale, 0 otherwise. ``threshold_`` is
    the score a window needs: the SVM's own boundary (0) after ``fit``, the calibrated one
    once ``calibrate_threshold`` (perception/knob_data.py) has set it; ``predict`` and the
    reader both use it."""

    def __init__(self, C: float = 0.01, class_weight: str | None = "balanced", random_state: int = 0):
        self.C = C
        self.class_weight = class_weight
        self.random_state = random_state

    def fit(self, X, y):
        F = _features(X, DETECTOR_HOG)
        y = np.asarray(y).astype(int)
        svm = LinearSVC(C=self.C, class_weight=self.class_weight, random_state=self.random_state,
                        max_iter=5000)
        svm.fit(F, y)
        self.coef_ = svm.coef_.ravel().astype(np.float32)
        self.intercept_ = float(svm.intercept_[0])
        self.classes_ = np.array([0, 1])
        self.n_features_in_ = F.shape[1]
        self.threshold_ = 0.0
        return self

    def decision_function(self, X) -> np.ndarray:
        check_is_fitted(self)
        return _features(X, DETECTOR_HOG) @ self.coef_ + self.intercept_

    def threshold_for(self, cfg: "KnobConfig") -> float:
        """The score a window needs: the configured one, else ``threshold_``."""
        check_is_fitted(self)
        return float(cfg.threshold) if cfg.threshold is not None else float(self.threshold_)

    def predict(self, X) -> np.ndarray:
        """1 where a window scores over ``threshold_``, else 0."""
        check_is_fitted(self)
        return (self.decision_function(X) > self.threshold_).astype(int)

    def scan(self, canvas: np.ndarray) -> np.ndarray:
        """SVM scores of every window of a canvas at HOG block stride (6 px): (rows, cols),
        window (i, j) has its top-left corner at (6 j, 6 i). One HOG pass per canvas (the
        block histograms are shared between overlapping windows)."""
        check_is_fitted(self)
        hog = hog_descriptor(DETECTOR_HOG)
        s = DETECTOR_HOG["stride"][0]
        n = (canvas.shape[0] - WINDOW) // s + 1
        m = (canvas.shape[1] - WINDOW) // s + 1
        f = hog.compute(np.ascontiguousarray(canvas), (s, s), (0, 0)).reshape(n * m, -1)
        return (f @ self.coef_ + self.intercept_).reshape(n, m)


def _wrap(a):
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


def angle_class(angles) -> np.ndarray:
    """Class 0..35 of each angle: class c covers [10c - 5, 10c + 5) degrees."""
    d = np.degrees(np.asarray(angles, dtype=float)) % 360.0
    return (np.round(d / 10.0).astype(int)) % N_CLASSES


class KnobAngleForest(BaseEstimator, ClassifierMixin):
    """HOG + random forest over 36 classes of 10 degrees (RAMCIP 5.2.1.4). ``fit(X, angles)``
    with angles in rad; ``predict(X)`` gives a continuous angle (rad): the probability-weighted
    circular mean of the winning class and its two neighbours; ``predict_proba(X)`` the
    (N, 36) class probabilities."""

    def __init__(self, n_estimators: int = 100, max_features: str | float = "sqrt",
                 min_samples_leaf: int = 1, random_state: int = 0, n_jobs: int | None = None):
        self.n_estimators = n_estimators
        self.max_features = max_features
        self.min_samples_leaf = min_samples_leaf
        self.random_state = random_state
        self.n_jobs = n_jobs

    def fit(self, X, angles):
        F = _features(X, ANGLE_HOG)
        y = angle_class(angles)
        self.forest_ = RandomForestClassifier(
            n_estimators=self.n_estimators, max_features=self.max_features,
            min_samples_leaf=self.min_samples_leaf, random_state=self.random_state,
            n_jobs=self.n_jobs).fit(F, y)
        # reading is one small batch at a time: threads would cost more than they save
        self.forest_.set_params(n_jobs=None)
        self.classes_ = np.arange(N_CLASSES)
        self.n_features_in_ = F.shape[1]
        return self

    def predict_proba(self, X) -> np.ndarray:
        check_is_fitted(self)
        F = _features(X, ANGLE_HOG)
        p = self.forest_.predict_proba(F)
        out = np.zeros((len(F), N_CLASSES))
        out[:, self.forest_.classes_] = p
        return out

    def predict(self, X) -> np.ndarray:
        check_is_fitted(self)
        return proba_to_angle(self.predict_proba(X))


def proba_to_angle(p: np.ndarray) -> np.ndarray:
    """Continuous angles (rad) from (N, 36) class probabilities."""
    best = p.argmax(1)
    idx = (best[:, None] + np.array([-1, 0, 1])[None]) % N_CLASSES
    w = np.take_along_axis(p, idx, 1)
    a = np.radians(idx * 10.0)
    return np.arctan2((w * np.sin(a)).sum(1), (w * np.cos(a)).sum(1))


class KnobAngleSVR(BaseEstimator, RegressorMixin):
    """HOG + two linear SVRs regressing cos and sin of the angle; ``predict(X)`` = atan2 (rad).
    ``C`` is chosen from ``C_grid`` by ``cv``-fold cross-validation in ``fit`` (as RAMCIP did)
    unless the grid has one value. ``n_jobs`` threads run the fits of ``fit`` (liblinear
    releases the GIL; the result does not depend on it)."""

    def __init__(self, C_grid: Sequence[float] = (0.03, 0.3), epsilon: float = 0.0,
                 cv: int = 3, cv_samples: int = 3000, random_state: int = 0,
                 n_jobs: int | None = None):
        self.C_grid = C_grid
        self.epsilon = epsilon
        self.cv = cv
        self.cv_samples = cv_samples
        self.random_state = random_state
        self.n_jobs = n_jobs

    def _fit_one(self, X, y, C):
        # The primal solver (squared epsilon-insensitive loss) is much faster than the dual
        # one when there are more samples than HOG values, as in training.
        return LinearSVR(C=C, epsilon=self.epsilon, loss="squared_epsilon_insensitive",
                         dual=False, random_state=self.random_state, max_iter=2000).fit(X, y)

    def _fit_all(self, jobs):
        """``jobs``: (X, y, C) triples, fitted on ``n_jobs`` threads, in order."""
        from joblib import Parallel, delayed
        return Parallel(n_jobs=self.n_jobs, prefer="threads")(
            delayed(self._fit_one)(X, y, C) for X, y, C in jobs)

    def fit(self, X, angles):
        X = _features(X, ANGLE_HOG)
        a = np.asarray(angles, dtype=float)
        Y = np.stack([np.cos(a), np.sin(a)], 1)
        grid = list(self.C_grid)
        if len(grid) > 1:
            rng = np.random.default_rng(self.random_state)
            # cross-validate on at most cv_samples samples: C hardly depends on more
            sub = rng.permutation(len(X))[:self.cv_samples]
            Xs, Ys, As = X[sub], Y[sub], a[sub]
            fold = rng.integers(0, self.cv, len(Xs))
            runs = [(C, f) for C in grid for f in range(self.cv)]
            models = iter(self._fit_all([(Xs[fold != f], Ys[fold != f, i], C)
                                         for C, f in runs for i in range(2)]))
            e = {}
            for C, f in runs:
                te = fold == f
                cos_m, sin_m = next(models), next(models)
                pa = np.arctan2(sin_m.predict(Xs[te]), cos_m.predict(Xs[te]))
                e.setdefault(C, []).append(np.median(np.abs(_wrap(pa - As[te]))))
            errs = [float(np.mean(e[C])) for C in grid]
            self.C_ = grid[int(np.argmin(errs))]
            self.cv_errors_deg_ = [math.degrees(v) for v in errs]
        else:
            self.C_ = grid[0]
        cos_m, sin_m = self._fit_all([(X, Y[:, i], self.C_) for i in range(2)])
        self.coef_ = np.stack([cos_m.coef_, sin_m.coef_]).astype(np.float32)
        self.intercept_ = np.array([float(np.ravel(cos_m.intercept_)[0]),
                                    float(np.ravel(sin_m.intercept_)[0])], dtype=np.float32)
        self.n_features_in_ = X.shape[1]
        return self

    def predict(self, X) -> np.ndarray:
        check_is_fitted(self)
        cs = _features(X, ANGLE_HOG) @ self.coef_.T + self.intercept_
        return np.arctan2(cs[:, 1], cs[:, 0])


# -- reading --------------------------------------------------------------------------------------

@dataclass
class KnobDetection:
    """The best window of a knob's region: centre in the face plane (m, knob x and y at angle
    0), pyramid scale, SVM score, the image pixel of the centre, and the turn ``psi`` (rad) of
    the canvas it was found in (``KnobPrior.canvas_frame``)."""
    center_m: tuple[float, float]
    scale: float
    score: float
    pixel: tuple[float, float]
    candidates: int = 0
    psi: float = 0.0


@dataclass
class KnobReading:
    """One knob read. ``state`` is a state name or "unknown"; ``angle`` (rad) is None when no
    knob was found; ``angles`` holds each angle model's estimate; ``confidence`` in [0, 1]."""
    knob_id: str
    found: bool
    state: str = "unknown"
    angle: Optional[float] = None
    confidence: float = 0.0
    detection: Optional[KnobDetection] = None
    angles: dict = field(default_factory=dict)
    reason: str = ""

    @property
    def angle_deg(self) -> Optional[float]:
        return None if self.angle is None else math.degrees(self.angle)


def nms(boxes: list, scores: list, score_threshold: float, iou: float) -> list[int]:
    """Indices kept by OpenCV's non-maximum suppression, best first."""
    if not boxes:
        return []
    # NMSBoxes wants a non-negative threshold: shift the scores (the order is what counts)
    keep = cv2.dnn.NMSBoxes(boxes, [float(s) - score_threshold for s in scores], 0.0, iou)
    keep = [int(i) for i in np.asarray(keep).ravel()]
    return sorted(keep, key=lambda i: -scores[i])


def detect_knob(gray: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray, prior: KnobPrior,
                detector: KnobDetector, cfg: KnobConfig = KnobConfig()) -> Optional[KnobDetection]:
    """Search the knob's region (the map's knob position +- ``search_px``) over the pyramid;
    None when no window scores above the threshold."""
    size = WINDOW + 2 * cfg.search_px
    threshold = detector.threshold_for(cfg)
    boxes, scores, where = [], [], []
    psi = 0.0
    for s in cfg.scales:
        rho = cfg.px_per_radius * s / prior.radius
        H, psi = canvas_homography(K, T_world_camera, prior, rho, size, cfg=cfg)
        score = detector.scan(rectify(gray, H, size))
        st = DETECTOR_HOG["stride"][0]
        for i, j in zip(*np.nonzero(score > threshold)):
            # a window's box in metres on the plane, so that scales compare
            cx = (j * st + (WINDOW - 1) / 2 - (size - 1) / 2) / rho
            cy = -(i * st + (WINDOW - 1) / 2 - (size - 1) / 2) / rho
            half = WINDOW / 2 / rho
            boxes.append([cx - half, -cy - half, 2 * half, 2 * half])
            scores.append(float(score[i, j]))
            where.append((s, rho, cx, cy, score, i, j))
    if not boxes:
        return None
    # NMSBoxes works in any unit; scale metres up so its integer-free maths has room.
    keep = nms([[v * 1000 for v in b] for b in boxes], scores, threshold, cfg.nms_iou)
    s, rho, cx, cy, score, i, j = where[keep[0]]
    # Sub-window refinement: a parabola through the best score and its grid neighbours
    # (the window grid is 6 px; the angle models want the centre within ~2 px).
    st = DETECTOR_HOG["stride"][0]
    dx = _parabola(score, i, j, 0) * st / rho
    dy = -_parabola(score, i, j, 1) * st / rho
    center = rotate_xy((cx + dx, cy + dy), psi)   # canvas frame -> knob face frame
    p_world = prior.T_world_face() @ np.array([center[0], center[1], 0.0, 1.0])
    pc = np.linalg.inv(T_world_camera) @ p_world
    pixel = (K.fx * pc[0] / pc[2] + K.cx, K.fy * pc[1] / pc[2] + K.cy)
    return KnobDetection(center, s, float(score[i, j]), (float(pixel[0]), float(pixel[1])), len(keep),
                         psi)


def _parabola(score: np.ndarray, i: int, j: int, axis: int) -> float:
    """Offset (in grid steps, within +-0.5) of the peak of a parabola through the score at
    (i, j) and its two neighbours along ``axis`` (0: columns, x; 1: rows, y)."""
    if axis == 0:
        if not 0 < j < score.shape[1] - 1:
            return 0.0
        a, b, c = score[i, j - 1], score[i, j], score[i, j + 1]
    else:
        if not 0 < i < score.shape[0] - 1:
            return 0.0
        a, b, c = score[i - 1, j], score[i, j], score[i + 1, j]
    den = a - 2 * b + c
    return 0.0 if den >= 0 else float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))


def snap_to_state(angle: float, prior: KnobPrior, proba: Optional[np.ndarray] = None,
                  psi: float = 0.0) -> tuple[str, float]:
    """The nearest discrete state to ``angle`` (rad) and a confidence: how far inside half a
    state step of that state the angle lies (1 on the state, 0 half-way to the next), averaged,
    when class probabilities are given, with the forest's probability mass within that half
    step (a forest torn between states lowers it). The classes are angles in a canvas turned
    by ``psi`` (class c is the knob angle 10 c degrees + psi)."""
    a = np.asarray(prior.state_angles)
    d = np.abs(_wrap(a - angle))
    k = int(np.argmin(d))
    if len(a) > 1:
        steps = np.abs(_wrap(np.diff(np.sort(a))))
        half = float(np.min(steps[steps > 1e-6])) / 2 if np.any(steps > 1e-6) else np.pi
    else:
        half = np.pi
    conf = float(max(0.0, 1.0 - d[k] / half))
    if proba is not None:
        centres = np.radians(np.arange(N_CLASSES) * 10.0) + psi
        near = np.abs(_wrap(centres - a[k])) <= half + 1e-9
        conf = 0.5 * conf + 0.5 * float(proba[near].sum())
    return prior.state_names[k], conf


class KnobReader:
    """Detector + angle models + configuration: ``read`` gives one KnobReading per prior.

    ``angle_method``: "forest" (36-class random forest, continuous from its probabilities),
    "svr" (cos/sin linear SVR), or "fused" (the circular mean of both when the SVR's lies
    within ``fuse_gate_deg`` of the forest's, else the forest's: the forest is robust, the
    SVR occasionally far off: where they agree, their errors partly cancel). Confidence = the detection's (a logistic of the SVM
    score's margin over the threshold) times the state's (``snap_to_state``)."""

    def __init__(self, detector: KnobDetector, forest: KnobAngleForest, svr: KnobAngleSVR,
                 config: KnobConfig = KnobConfig()):
        if config.angle_method not in ANGLE_METHODS:
            raise ValueError(f"angle_method must be one of {ANGLE_METHODS}")
        self.detector, self.forest, self.svr, self.config = detector, forest, svr, config

    def read(self, image: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray,
             priors: Sequence[KnobPrior], method: Optional[str] = None) -> list[KnobReading]:
        cfg = self.config
        method = method or cfg.angle_method
        gray = to_gray(image)
        readings, patches, found = [], [], []
        for prior in priors:
            if off_axis_deg(T_world_camera, prior) > cfg.max_off_axis_deg:
                readings.append(KnobReading(prior.knob_id, False, reason="seen too obliquely"))
                continue
            pc = np.linalg.inv(T_world_camera) @ prior.T_world_face()[:, 3]
            if pc[2] <= 0.05:
                readings.append(KnobReading(prior.knob_id, False, reason="behind the camera"))
                continue
            u, v = K.fx * pc[0] / pc[2] + K.cx, K.fy * pc[1] / pc[2] + K.cy
            if not (0 <= u < K.width and 0 <= v < K.height):
                readings.append(KnobReading(prior.knob_id, False, reason="outside the image"))
                continue
            det = detect_knob(gray, K, T_world_camera, prior, self.detector, cfg)
            if det is None:
                readings.append(KnobReading(prior.knob_id, False, reason="no knob found in its region"))
                continue
            readings.append(KnobReading(prior.knob_id, True, detection=det))
            d = cfg.angle_shifts_px * prior.radius / (cfg.px_per_radius * det.scale)
            shifts = [(0.0, 0.0)] + ([(d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)] if d > 0 else [])
            for sx, sy in shifts:
                c = (det.center_m[0] + sx, det.center_m[1] + sy)
                patches.append(face_patch(gray, K, T_world_camera, prior, c, det.scale, cfg))
            found.append((len(readings) - 1, prior))
        if not found:
            return readings
        n_views = len(patches) // len(found)
        X = hog_features(np.stack(patches), ANGLE_HOG)
        proba = self.forest.predict_proba(X).reshape(len(found), n_views, N_CLASSES).mean(1)
        # the models read angles in the (turned) canvas: add its turn back
        psi = np.array([readings[idx].detection.psi for idx, _ in found])
        a_rf = _wrap(proba_to_angle(proba) + psi)
        s_svr = self.svr.predict(X).reshape(len(found), n_views)
        a_svr = _wrap(np.arctan2(np.sin(s_svr).sum(1), np.cos(s_svr).sum(1)) + psi)
        gate = math.radians(cfg.fuse_gate_deg)
        for n, (idx, prior) in enumerate(found):
            r = readings[idx]
            fused = (_circular_mean(a_rf[n], a_svr[n]) if abs(_wrap(a_svr[n] - a_rf[n])) <= gate
                     else a_rf[n])
            r.angles = {"forest": float(a_rf[n]), "svr": float(a_svr[n]), "fused": float(fused)}
            r.angle = r.angles[method]
            state, c_state = snap_to_state(r.angle, prior, proba[n], psi[n])
            margin = r.detection.score - self.detector.threshold_for(cfg)
            c_det = 1.0 / (1.0 + math.exp(-2.0 * margin))
            r.confidence = float(c_state * c_det)
            if r.confidence >= cfg.min_confidence:
                r.state = state
            else:
                r.reason = f"unsure ({state} at {r.confidence:.2f})"
        return readings


def _circular_mean(a: float, b: float) -> float:
    return float(math.atan2(math.sin(a) + math.sin(b), math.cos(a) + math.cos(b)))


def read_knobs(image, K, T_world_camera, priors, reader: KnobReader) -> tuple[list[KnobReading], float]:
    """Readings and the time they took (s)."""
    t0 = time.perf_counter()
    out = reader.read(image, K, T_world_camera, priors)
    return out, time.perf_counter() - t0
