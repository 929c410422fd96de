"""The knob reader's templates: per shape, off-axis bin and relative angle, a label map of the
canvas (``ShapeTemplates``, ``KnobTemplates``; rendering, no learning). The method is described
in hearth/perception/knobs.py."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from hearth.perception.knob_shapes import KnobShape, N_FACE, _Caster, _FAR, _canvas_points


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


#: Stored readers (joblib files, hearth/worldmodel/model_store.py) name their classes by module:
#: these keep the module they were stored under before the reader was split into modules
#: (hearth.perception.knobs, which still exports them), so a stored model reads alike with this
#: code and earlier code, and neither makes the other retrain.
for _cls in (ShapeTemplates, KnobTemplates):
    _cls.__module__ = "hearth.perception.knobs"
