"""The exact check's window: the image pixels over a small canvas on a knob's face plane, fitted
to rendered label images (``_Window``: fits, contrast, settling the shift; the compiled kernels
are hearth/perception/knob_kernels.py). The method is described in hearth/perception/knobs.py."""

from __future__ import annotations

import numpy as np

from hearth.perception import knob_kernels
from hearth.perception.camera import Intrinsics
from hearth.perception.knob_canvas import rectify


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
