"""Scoring a canvas against the templates: colour fits by soft-label regression, depth fits
(heights against the templates', by correlation, and the relief's slope with its standard
error), label fits, and the candidate angles and states they give. The method is described in
hearth/perception/knobs.py."""

from __future__ import annotations

import math
from typing import Optional

import cv2
import numpy as np

from hearth.perception.knob_priors import KnobPrior
from hearth.perception.knob_templates import ShapeTemplates


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
