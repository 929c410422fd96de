"""Semantic segmentation of one RGB-D frame ("Find my mug", HOBBIT D3.2 appendix, section 3).

Pipeline: over-segmentation into patches -> 17 features per patch -> random forest class
probabilities -> pairwise Potts MRF over patch adjacency, solved by loopy belief propagation.
Labels: floor, wall, ceiling, table, chair, cabinet, object, unknown.

**Over-segmentation.** The paper uses VCCS supervoxels (Papon et al.), which neither open3d
nor any package we ship provides, and a Python supervoxel clustering would cost seconds per
frame. We cut the organised image instead, which gives the same kind of patches (small,
planar, depth-continuous, adjacency known) in a few milliseconds: pixels are grouped by an
image grid cell (``cell_px``), by the bin of their world-frame normal (up, down, or one of
eight horizontal directions) and split at depth discontinuities; connected components
(OpenCV) of equal (cell, bin) become patches; fragments below ``min_points`` are merged into
the nearest patch (scipy's distance transform). Normals come from the smoothed depth image.

**Features** (14 as in the paper, and 3 of context): the scatter-matrix eigenvalues as pointness (l0),
surfaceness (l1 - l0) and linearness (l2 - l1); the height above the floor of the centroid,
the lowest and the highest point; the angle between the mean normal and the floor's up
direction and the normals' circular standard deviation; mean and standard deviation of
CIELAB L, a, b. Heights are world z: the floor is z = 0 and the camera pose is known (the
paper fitted a floor plane to NYU frames because their camera pose was unknown). Three more
describe a patch's surroundings (``context_features``): the extent and height span of the
plane it belongs to and how far the structure next to it rises above it; without them a coffee
table's top, a chair's seat, a shelf and a drawer unit's top were alike.

**Classifier.** ``PatchClassifier``: a scikit-learn ``RandomForestClassifier`` in estimator
shape (parameters in the constructor, ``fit`` returns self, learned attributes end in ``_``).

**MRF.** Unary cost lambda (1 - p(y | x)); Potts pairwise cost exp(-|c_i - c_j| / sigma)
between adjacent patches with centroids c_i, c_j, as in the paper, times a contrast factor
exp(-|Lab_i - Lab_j|^2 / 2 sigma_c^2) of the patches' mean colours (a contrast-sensitive
Potts term, Boykov and Jolly 2001): without it the smoothing swallowed small objects into
the table under them (object recall 0.73 -> 0.87 on held-out rendered scenes). Min-sum loopy belief propagation, as the
paper does, written here in numpy (vectorised over edges; a Potts message is O(labels)):
for ~1-2 thousand patches ten iterations take a few milliseconds. PyMaxflow's
alpha-expansion would solve the same energy (Potts is a metric) but adds a compiled
dependency for no gain at this size.

Pure: arrays in, arrays out. Training is hearth/perception/segmentation_training.py; the forest is
stored by hearth/worldmodel/model_store.py, asked by hearth/skills/segmentation_model.py.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage, sparse
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.ensemble import RandomForestClassifier
from sklearn.utils.validation import check_is_fitted

from hearth.perception.camera import Intrinsics
from hearth.perception.errors import PerceptionError
from hearth.perception.trained import read_time, trained_fields

LABELS = ("floor", "wall", "ceiling", "table", "chair", "cabinet", "object", "unknown")
N_FEATURES = 17
FEATURE_NAMES = ("pointness", "surfaceness", "linearness", "centroid_height", "min_height",
                 "max_height", "normal_angle", "normal_circular_std", "L_mean", "a_mean",
                 "b_mean", "L_std", "a_std", "b_std",
                 "plane_extent", "plane_height_span", "height_above")


@dataclass(frozen=True)
class SegmentationConfig:
    """Parameters of the over-segmentation and the MRF. Pixel sizes are for 640 pixels width
    and scale with the image. The over-segmentation makes the patches the forest is trained
    on, so its fields are trained ones (part of the stored model's configuration); the MRF's
    are declared ``read_time`` and can change without retraining."""
    cell_px: int = 28                 # grid cell edge (pixels)
    smooth_px: int = 7                # depth box filter before normals
    normal_step_px: int = 3           # neighbour offset for normals
    up_cos: float = 0.8               # |n_z| above this: horizontal surface (up/down bins)
    depth_jump_m: float = 0.02        # discontinuity threshold: this + depth_jump_rel * z
    depth_jump_rel: float = 0.03
    min_points: int = 30              # smaller fragments merge into a neighbour
    coplanar_m: float = 0.03          # adjacent patches this close to one plane share it
    context_radius_m: float = 0.3     # horizontal reach of ``height_above``
    unary_weight: float = read_time(1.0)         # lambda
    pair_sigma_m: float = read_time(0.5)         # sigma of the Potts term
    pair_weight: float = read_time(0.6)          # scales the Potts term relative to the unary
    pair_color_sigma: float = read_time(20.0)    # CIELAB distance scale of the contrast term (0: off)
    bp_iterations: int = read_time(12)
    bp_damping: float = read_time(0.5)

    def trained_fields(self) -> dict:
        """The fields the forest is trained with (see ``hearth.perception.trained``)."""
        return trained_fields(self)


@dataclass
class Patches:
    """The over-segmentation of one frame. ``ids`` (H, W): patch index per pixel (-1: no
    depth); ``features`` (N, 17); ``centroids_world`` (N, 3); ``sizes`` (N,) pixels;
    ``edges`` (E, 2) adjacent patch pairs; ``points_world`` (H, W, 3) float32 (NaN where no
    depth)."""
    ids: np.ndarray
    features: np.ndarray
    centroids_world: np.ndarray
    sizes: np.ndarray
    edges: np.ndarray
    points_world: np.ndarray

    def majority(self, classes: np.ndarray) -> np.ndarray:
        """Per patch the most frequent of ``classes`` (H, W) (ints >= 0; -1 ignored); -1 for
        a patch without any."""
        ok = (self.ids >= 0) & (classes >= 0)
        n_cls = int(classes.max()) + 1 if ok.any() else 1
        counts = np.bincount(self.ids[ok] * n_cls + classes[ok],
                             minlength=len(self.sizes) * n_cls).reshape(len(self.sizes), n_cls)
        out = counts.argmax(axis=1)
        out[counts.sum(axis=1) == 0] = -1
        return out


@dataclass
class Segmentation:
    """``labels`` (H, W) int8 index into ``LABELS`` (-1: no depth); ``patch_labels`` (N,);
    ``patch_proba`` (N, 8) forest probabilities; ``patches`` the over-segmentation."""
    labels: np.ndarray
    patch_labels: np.ndarray
    patch_proba: np.ndarray
    patches: Patches

    def points(self, label: str) -> np.ndarray:
        """World points (M, 3) labelled ``label``."""
        m = self.labels == LABELS.index(label)
        return self.patches.points_world[m].astype(np.float64)


# -- over-segmentation and features ----------------------------------------------------------

def _box_mean(a: np.ndarray, valid: np.ndarray, k: int) -> np.ndarray:
    """Mean over a k x k window of the valid pixels only."""
    num = cv2.blur(np.where(valid, a, 0).astype(np.float32), (k, k))
    den = cv2.blur(valid.astype(np.float32), (k, k))
    return np.where(den > 0.2, num / np.maximum(den, 1e-6), 0).astype(np.float32)


def _points_camera(depth: np.ndarray, K: Intrinsics) -> np.ndarray:
    H, W = depth.shape
    u = (np.arange(W, dtype=np.float32) - K.cx) / K.fx
    v = (np.arange(H, dtype=np.float32) - K.cy) / K.fy
    z = depth.astype(np.float32)
    return np.stack([u[None, :] * z, v[:, None] * z, z], axis=-1)


def extract_patches(depth: np.ndarray, color: np.ndarray, K: Intrinsics,
                    T_world_camera: np.ndarray, config: SegmentationConfig | None = None) -> Patches:
    """Over-segment a frame and compute the 17 features per patch. ``depth`` metres (0 or NaN:
    no reading), ``color`` uint8 RGB, world z up with the floor at z = 0."""
    c = config or SegmentationConfig()
    depth = np.nan_to_num(np.asarray(depth, dtype=np.float32), nan=0.0)
    H, W = depth.shape
    if color.shape[:2] != (H, W):
        raise PerceptionError("colour and depth images differ in size")
    scale = W / 640.0
    valid = depth > 0
    if valid.sum() < c.min_points:
        raise PerceptionError("too few depth readings to segment")
    R, t = T_world_camera[:3, :3].astype(np.float32), T_world_camera[:3, 3].astype(np.float32)
    pts_cam = _points_camera(depth, K)
    pts_world = pts_cam @ R.T + t
    pts_world[~valid] = np.nan

    # Normals from the smoothed depth: cross product of the horizontal and vertical differences.
    k = max(3, int(round(c.smooth_px * scale)) | 1)
    zs = _box_mean(depth, valid, k)
    ps = _points_camera(zs, K)
    s = max(1, int(round(c.normal_step_px * scale)))
    # central differences inside, repeated outwards at the image border
    dx = np.pad(ps[:, 2 * s:] - ps[:, :-2 * s], ((0, 0), (s, s), (0, 0)), mode="edge")
    dy = np.pad(ps[2 * s:, :] - ps[:-2 * s, :], ((s, s), (0, 0), (0, 0)), mode="edge")
    n_cam = np.cross(dx, dy)
    n_cam /= np.maximum(np.linalg.norm(n_cam, axis=-1, keepdims=True), 1e-9)
    # face the camera
    flip = np.sum(n_cam * ps, axis=-1) > 0
    n_cam[flip] *= -1
    n_world = n_cam @ R.T

    # Codes: grid cell x normal bin.
    nz = n_world[..., 2]
    az = np.arctan2(n_world[..., 1], n_world[..., 0])
    nbin = (np.floor((az + np.pi + np.pi / 8) / (np.pi / 4)).astype(np.int32) % 8) + 2
    nbin[nz > c.up_cos] = 0
    nbin[nz < -c.up_cos] = 1
    cell = max(4, int(round(c.cell_px * scale)))
    vv, uu = np.mgrid[0:H, 0:W]
    code = ((vv // cell) * (W // cell + 1) + uu // cell) * 10 + nbin
    thr = c.depth_jump_m + c.depth_jump_rel * depth
    edge = np.zeros((H, W), dtype=bool)
    jump_r = np.abs(depth[:, 1:] - depth[:, :-1]) > thr[:, :-1]
    jump_d = np.abs(depth[1:, :] - depth[:-1, :]) > thr[:-1, :]
    edge[:, :-1] |= (code[:, 1:] != code[:, :-1]) | jump_r
    edge[:-1, :] |= (code[1:, :] != code[:-1, :]) | jump_d
    inner = valid & ~edge
    n_comp, comp = cv2.connectedComponents(inner.astype(np.uint8), connectivity=4)
    comp = comp.astype(np.int32) - 1          # -1: background / edge
    sizes = np.bincount(comp[comp >= 0], minlength=n_comp - 1)
    big = sizes >= max(4, int(c.min_points * scale * scale))
    remap = np.full(n_comp, -1, dtype=np.int32)
    remap[1:][big] = np.arange(int(big.sum()))
    ids = remap[comp + 1]
    if not big.any():
        raise PerceptionError("no patch large enough to classify")
    # Edge pixels and small fragments join the nearest patch.
    hole = valid & (ids < 0)
    if hole.any():
        _, (iy, ix) = ndimage.distance_transform_edt(ids < 0, return_indices=True)
        ids = np.where(hole, ids[iy, ix], ids)
    ids[~valid] = -1
    n = int(big.sum())

    # Features by per-patch sums (bincount) over the valid pixels.
    m = ids >= 0
    lab = ids[m]
    P = pts_world[m].astype(np.float64) - t.astype(np.float64)   # centred for precision
    cnt = np.bincount(lab, minlength=n).astype(np.float64)
    mu = np.stack([np.bincount(lab, P[:, i], n) for i in range(3)], axis=1) / cnt[:, None]
    cov = np.empty((n, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            v = np.bincount(lab, P[:, i] * P[:, j], n) / cnt - mu[:, i] * mu[:, j]
            cov[:, i, j] = cov[:, j, i] = v
    ev = np.linalg.eigvalsh(cov)                       # ascending l0 <= l1 <= l2
    ev = np.maximum(ev, 0)
    zw = pts_world[m][:, 2].astype(np.float64)
    # lowest / highest point: one sort by patch (a radix sort while ids fit 16 bits), then
    # reduceat over the runs; scipy.ndimage.minimum sorts twice and costs ~3x more.
    order = np.argsort(lab.astype(np.uint16) if n < 65536 else lab, kind="stable")
    starts = np.concatenate([[0], np.cumsum(cnt[:-1]).astype(np.int64)])
    zsorted = zw[order]
    zmin = np.minimum.reduceat(zsorted, starts)
    zmax = np.maximum.reduceat(zsorted, starts)
    nw = n_world[m].astype(np.float64)
    nsum = np.stack([np.bincount(lab, nw[:, i], n) for i in range(3)], axis=1)
    Rlen = np.linalg.norm(nsum, axis=1) / cnt
    nmean = nsum / np.maximum(np.linalg.norm(nsum, axis=1, keepdims=True), 1e-9)
    angle = np.arccos(np.clip(nmean[:, 2], -1, 1))
    circ_std = np.sqrt(-2 * np.log(np.clip(Rlen, 1e-6, 1.0)))
    labc = cv2.cvtColor(np.ascontiguousarray(color), cv2.COLOR_RGB2LAB)[m].astype(np.float64)
    lmean = np.stack([np.bincount(lab, labc[:, i], n) for i in range(3)], axis=1) / cnt[:, None]
    lsq = np.stack([np.bincount(lab, labc[:, i] ** 2, n) for i in range(3)], axis=1) / cnt[:, None]
    lstd = np.sqrt(np.maximum(lsq - lmean ** 2, 0))
    centroid = mu + t.astype(np.float64)

    # Adjacency: neighbouring pixels of different patches without a depth jump.
    a = np.concatenate([ids[:, :-1][~jump_r], ids[:-1, :][~jump_d]])
    b = np.concatenate([ids[:, 1:][~jump_r], ids[1:, :][~jump_d]])
    ok = (a >= 0) & (b >= 0) & (a != b)
    lo, hi = np.minimum(a[ok], b[ok]).astype(np.int64), np.maximum(a[ok], b[ok]).astype(np.int64)
    pairs = np.unique(lo * n + hi)
    edges = np.stack([pairs // n, pairs % n], axis=1)
    context = context_features(centroid, nmean, zmin, zmax, cnt, edges, c)
    feats = np.column_stack([ev[:, 0], ev[:, 1] - ev[:, 0], ev[:, 2] - ev[:, 1], centroid[:, 2],
                             zmin, zmax, angle, circ_std, lmean, lstd, context])
    return Patches(ids=ids, features=feats, centroids_world=centroid, sizes=cnt.astype(np.int64),
                   edges=edges, points_world=pts_world)


def context_features(centroids: np.ndarray, normals: np.ndarray, zmin: np.ndarray,
                     zmax: np.ndarray, sizes: np.ndarray, edges: np.ndarray,
                     config: SegmentationConfig) -> np.ndarray:
    """(N, 3) features of a patch's surroundings, which its own 14 cannot see: a coffee table's
    top and a chair's seat are alike patch by patch, but the table top is one wide plane with
    nothing tall above it and the seat is small with a backrest rising behind it.

    - ``plane_extent``: the horizontal spread (m, the root of the largest eigenvalue of the
      size-weighted covariance of centroid x, y) of the plane the patch belongs to: adjacent
      patches with parallel mean normals (cosine > 0.95) within ``coplanar_m`` of each other's
      plane, joined transitively (scipy connected components);
    - ``plane_height_span``: highest minus lowest point of that plane (m): a wall, a cupboard
      front and a drawer front differ;
    - ``height_above``: how far the highest patch within ``context_radius_m`` horizontally
      rises above this patch's top (m, 0 .. 2): the backrest over a seat, the shelf over a
      shelf, nothing over a table top but the small objects on it.
    """
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree
    n = len(centroids)
    if n == 0:
        return np.zeros((0, 3))
    a, b = edges[:, 0], edges[:, 1]
    par = np.einsum("ij,ij->i", normals[a], normals[b]) > 0.95
    gap = np.abs(np.einsum("ij,ij->i", normals[a], centroids[a] - centroids[b]))
    keep = par & (gap < config.coplanar_m)
    graph = sparse.coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(n, n))
    _, region = connected_components(graph, directed=False)
    w = sizes.astype(np.float64)
    r = region.max() + 1
    sw = np.bincount(region, w, r)
    mx = np.bincount(region, w * centroids[:, 0], r) / sw
    my = np.bincount(region, w * centroids[:, 1], r) / sw
    dx, dy = centroids[:, 0] - mx[region], centroids[:, 1] - my[region]
    cxx = np.bincount(region, w * dx * dx, r) / sw
    cyy = np.bincount(region, w * dy * dy, r) / sw
    cxy = np.bincount(region, w * dx * dy, r) / sw
    top = 0.5 * (cxx + cyy) + np.sqrt(0.25 * (cxx - cyy) ** 2 + cxy ** 2)
    extent = np.sqrt(np.maximum(top, 0))[region]
    span = (np.full(r, -np.inf), np.full(r, np.inf))
    np.maximum.at(span[0], region, zmax)
    np.minimum.at(span[1], region, zmin)
    height_span = (span[0] - span[1])[region]
    tree = cKDTree(centroids[:, :2])
    near = tree.query_ball_point(centroids[:, :2], config.context_radius_m)
    highest = np.array([zmax[idx].max() for idx in near])
    above = np.clip(highest - zmax, 0.0, 2.0)
    return np.column_stack([extent, height_span, above])


# -- classifier ------------------------------------------------------------------------------

class PatchClassifier(ClassifierMixin, BaseEstimator):
    """Random forest over patch features; ``predict_proba`` has one column per ``LABELS``
    entry (classes absent from training get probability 0). ``n_jobs`` threads fit the
    forest; predicting (one frame's patches at a time) uses one."""

    def __init__(self, n_estimators: int = 40, max_depth: int | None = 18,
                 min_samples_leaf: int = 2, class_weight: str | None = "balanced",
                 random_state: int | None = 0, n_jobs: int | None = 1):
        self.n_estimators = n_estimators
        self.max_depth = max_depth
        self.min_samples_leaf = min_samples_leaf
        self.class_weight = class_weight
        self.random_state = random_state
        self.n_jobs = n_jobs

    def fit(self, X, y, sample_weight=None):
        X = np.asarray(X, dtype=np.float64)
        y = np.asarray(y)
        if X.ndim != 2 or X.shape[1] != N_FEATURES:
            raise ValueError(f"expected (n, {N_FEATURES}) features, got {X.shape}")
        self.forest_ = RandomForestClassifier(
            n_estimators=self.n_estimators, max_depth=self.max_depth,
            min_samples_leaf=self.min_samples_leaf, class_weight=self.class_weight,
            random_state=self.random_state, n_jobs=self.n_jobs).fit(X, y, sample_weight=sample_weight)
        self.forest_.set_params(n_jobs=None)
        self.classes_ = np.arange(len(LABELS))
        self.n_features_in_ = N_FEATURES
        return self

    def predict_proba(self, X) -> np.ndarray:
        check_is_fitted(self)
        X = np.asarray(X, dtype=np.float64)
        p = np.zeros((len(X), len(LABELS)))
        if len(X):
            p[:, self.forest_.classes_.astype(int)] = self.forest_.predict_proba(X)
        return p

    def predict(self, X) -> np.ndarray:
        check_is_fitted(self)
        return self.predict_proba(X).argmax(axis=1)


# -- MRF -------------------------------------------------------------------------------------

def potts_lbp(unary: np.ndarray, edges: np.ndarray, weights: np.ndarray,
              iterations: int = 12, damping: float = 0.5) -> np.ndarray:
    """Approximate MAP labels of a pairwise Potts MRF by min-sum loopy belief propagation.

    ``unary`` (N, L) costs; ``edges`` (E, 2) undirected; ``weights`` (E,) cost of giving the
    two ends different labels. Returns (N,) labels.
    """
    N, L = unary.shape
    if len(edges) == 0:
        return unary.argmin(axis=1)
    src = np.concatenate([edges[:, 0], edges[:, 1]])
    dst = np.concatenate([edges[:, 1], edges[:, 0]])
    w = np.concatenate([weights, weights])[:, None]
    E2 = len(src)
    rev = np.concatenate([np.arange(E2 // 2, E2), np.arange(0, E2 // 2)])
    inc = sparse.csr_matrix((np.ones(E2), (dst, np.arange(E2))), shape=(N, E2))
    msg = np.zeros((E2, L))
    for _ in range(iterations):
        belief = unary + inc @ msg
        h = belief[src] - msg[rev]                     # what src knows, minus dst's own message
        new = np.minimum(h, h.min(axis=1, keepdims=True) + w)
        new -= new.min(axis=1, keepdims=True)
        msg = damping * msg + (1 - damping) * new
    return (unary + inc @ msg).argmin(axis=1)


def segment(depth: np.ndarray, color: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray,
            classifier: PatchClassifier, config: SegmentationConfig | None = None) -> Segmentation:
    """Label every pixel of an RGB-D frame with one of ``LABELS`` (see module docstring)."""
    c = config or SegmentationConfig()
    patches = extract_patches(depth, color, K, T_world_camera, c)
    proba = classifier.predict_proba(patches.features)
    unary = c.unary_weight * (1.0 - proba)
    e = patches.edges
    dist = np.linalg.norm(patches.centroids_world[e[:, 0]] - patches.centroids_world[e[:, 1]], axis=1)
    w = c.pair_weight * np.exp(-dist / c.pair_sigma_m)
    if c.pair_color_sigma > 0:
        f = patches.features
        dlab = np.linalg.norm(f[e[:, 0], 8:11] - f[e[:, 1], 8:11], axis=1)
        w = w * np.exp(-0.5 * (dlab / c.pair_color_sigma) ** 2)
    lab = potts_lbp(unary, e, w, c.bp_iterations, c.bp_damping)
    pix = np.full(patches.ids.shape, -1, dtype=np.int8)
    m = patches.ids >= 0
    pix[m] = lab[patches.ids[m]]
    return Segmentation(labels=pix, patch_labels=lab, patch_proba=proba, patches=patches)


def accuracy(pred: np.ndarray, truth: np.ndarray, scored: np.ndarray | None = None) -> dict:
    """Per-pixel accuracy where the truth knows a class other than unknown and ``scored``
    holds (default: where ``pred`` has a label, i.e. the sensor gave a depth reading; pass
    ``truth >= 0`` to count pixels without depth as wrong): ``global_`` (all such pixels),
    ``per_class`` recall by class name, ``class_average`` their mean, and ``right`` /
    ``total`` pixel counts per class so that several frames can be pooled."""
    unk = LABELS.index("unknown")
    m = (truth >= 0) & (truth != unk) & (pred >= 0 if scored is None else scored)
    t, p = truth[m].astype(np.int64), pred[m].astype(np.int64)
    total = np.bincount(t, minlength=len(LABELS))
    right = np.bincount(t[p == t], minlength=len(LABELS))
    per = {LABELS[i]: right[i] / total[i] for i in range(len(LABELS)) if total[i] > 0}
    return dict(global_=float(right.sum() / max(total.sum(), 1)), per_class=per,
                class_average=float(np.mean(list(per.values()))) if per else math.nan,
                right=right, total=total)
