"""The knob reader's compiled label sums (hearth/perception/knob_kernels.py) against the numpy sums
they replaced (np.bincount over index and weight arrays, kept here as the reference): the
label maps the same float64 values bit for bit, the normal equations the same to rounding."""
from __future__ import annotations

import numpy as np
import pytest

from hearth.perception import knob_kernels


def _bincount_gram(labels, lut, idx, wts, xc):
    """``_Window.fits``'s normal equations as numpy made them."""
    B = len(labels)
    L = int(lut.max()) + 1
    lab = lut[labels[:, idx]] + (np.arange(B) * L)[:, None, None]        # (B, 4, N)
    w = np.broadcast_to(wts, lab.shape)
    pair_keys = (lab[:, :, None, :] * L + (lab[:, None, :, :] % L)).ravel()
    pair_w = (w[:, :, None, :] * w[:, None, :, :]).ravel()
    G = np.bincount(pair_keys, pair_w, minlength=B * L * L).reshape(B, L, L)
    keys = lab.ravel()
    b = np.stack([np.bincount(keys, (w * xc[:, c]).ravel(), minlength=B * L)
                  for c in range(3)], -1).reshape(B, L, 3)
    return G, b


def _bincount_maps(labels, lut, idx, wts, N):
    """``_Window.maps`` as numpy made it."""
    L = int(lut.max()) + 1
    rows = lut[labels[idx]] * N + np.arange(N)
    return np.bincount(rows.ravel(), wts.ravel(), minlength=L * N).reshape(L, N)


def _window(rng, n_box: int, N: int, n_labels: int, B: int):
    labels = rng.integers(0, n_labels, (B, n_box)).astype(np.uint16)
    labels[:, : n_box // 3] = 0                                  # most pixels miss the knob
    present = np.flatnonzero(np.bincount(labels.ravel()))
    lut = np.zeros(int(present[-1]) + 1, np.int64)
    lut[present] = np.arange(len(present))
    base = rng.integers(0, n_box - 41, N)
    idx = np.stack([base, base + 1, base + 40, base + 41])       # a box 40 pixels wide
    fx, fy = rng.random(N), rng.random(N)
    wts = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
    xc = rng.normal(0.0, 40.0, (N, 3))
    return labels, lut, idx, wts, xc


@pytest.mark.parametrize("seed", range(4))
def test_label_gram_is_bincounts_sums(seed):
    """The same sums as numpy's to rounding, on windows whose labels come in patches (most
    pixels' four corners one label, as a rendering's) and on noise (every pixel mixed)."""
    rng = np.random.default_rng(seed)
    labels, lut, idx, wts, xc = _window(rng, 1600, 961, 30 + 10 * seed, 1 + 4 * seed)
    p = np.arange(1600)
    blocks = labels[:, 1000:1025]                       # 8 x 8 pixel blocks of the 40-wide box
    patches = np.ascontiguousarray(blocks[:, (p // 320) * 5 + (p % 40) // 8])
    one = (patches[:, idx] == patches[:, idx[:1]]).all(1)
    assert 0.5 < one.mean() < 0.95
    for labs in (labels, patches):
        present = np.flatnonzero(np.bincount(labs.ravel()))
        lut = np.zeros(int(present[-1]) + 1, np.int64)
        lut[present] = np.arange(len(present))
        G0, b0 = _bincount_gram(labs, lut, idx, wts, xc)
        L = len(present)
        G, b = np.zeros((len(labs), L, L)), np.zeros((len(labs), L, 3))
        knob_kernels.label_gram(labs, lut, idx, wts, xc, G, b)
        assert np.abs(G - G0).max() <= 1e-12 * np.abs(G0).max()
        assert np.abs(b - b0).max() <= 1e-12 * np.abs(b0).max()


@pytest.mark.parametrize("seed", range(3))
def test_label_fits_are_numpys_least_squares(seed):
    """The fused fit (labels numbered, normal equations, ridge, solve, explained sum) against
    numpy's: the labels present in any rendering, ``np.linalg.solve`` and the sum."""
    rng = np.random.default_rng(seed)
    labels, _, idx, wts, xc = _window(rng, 1600, 961, 20 + 10 * seed, 1 + 3 * seed)
    labels[:, 1000:] = labels[:, 1000:] * 2          # label values with gaps, as renderings have
    present = np.flatnonzero(np.bincount(labels.ravel()))
    lut = np.zeros(int(present[-1]) + 1, np.int64)
    lut[present] = np.arange(len(present))
    G, b = _bincount_gram(labels, lut, idx, wts, xc)
    L = len(present)
    G[:, np.arange(L), np.arange(L)] += 0.5
    want = np.einsum("blc,blc->b", b, np.linalg.solve(G, b))
    got = np.empty(len(labels))
    knob_kernels.label_fits(labels, idx, wts, xc, 0.5, got)
    assert np.allclose(got, want, rtol=1e-10, atol=0)


@pytest.mark.parametrize("seed", range(4))
def test_label_maps_are_bincounts_sums_bit_for_bit(seed):
    rng = np.random.default_rng(100 + seed)
    labels, lut, idx, wts, _ = _window(rng, 1600, 961, 20, 1)
    W0 = _bincount_maps(labels[0], lut, idx, wts, 961)
    W = np.zeros_like(W0)
    knob_kernels.label_maps(labels[0], lut, idx, wts, W)
    assert W.tobytes() == W0.tobytes()


def _numpy_labels(caster, origins, dirs, turns, fixed_turn, fine):
    """``_Caster.labels`` as numpy made it (per-turn label tables, broadcast rays)."""
    import math
    from hearth.perception.knobs import FINE_AZIMUTHS, N_FACE, N_FACE_FINE
    turns = np.atleast_1d(np.asarray(turns, dtype=float))
    B = len(turns)
    same_rays = np.ndim(dirs) == 2 and np.ndim(origins) <= 2
    dirs = np.broadcast_to(dirs, (B,) + np.shape(dirs)[-2:])
    N = dirs.shape[1]
    origins = (np.broadcast_to(origins, (B, 1, 3)) if np.ndim(origins) == 1
               else np.broadcast_to(origins, (B, N, 3)))
    best_t = np.full((B, N), np.inf)
    label = np.zeros((B, N), dtype=np.uint16)
    classes = N_FACE_FINE if fine else N_FACE
    for k, scene in enumerate(caster.scenes):
        if scene is None:
            continue
        a = turns if k == 0 else np.full(B, float(fixed_turn))
        Bc = 1 if (k == 1 and same_rays) else B
        c, s = np.cos(a[:Bc])[:, None], np.sin(a[:Bc])[:, None]
        rays = np.empty((Bc, N, 6), np.float32)
        for off, v in ((0, origins[:Bc]), (3, dirs[:Bc])):
            rays[..., off] = c * v[..., 0] + s * v[..., 1]
            rays[..., off + 1] = -s * v[..., 0] + c * v[..., 1]
            rays[..., off + 2] = v[..., 2]
        ans = scene.cast_rays(caster.o3d.core.Tensor.from_numpy(rays.reshape(-1, 6)))
        t = np.broadcast_to(ans["t_hit"].numpy().reshape(Bc, N), (B, N))
        hit = t < best_t
        gid = np.broadcast_to(ans["geometry_ids"].numpy().reshape(Bc, N).astype(np.int64), (B, N))
        prim = np.broadcast_to(ans["primitive_ids"].numpy().reshape(Bc, N).astype(np.int64), (B, N))
        no_hit = len(caster.az[k]) - 1
        tri = np.where(hit, caster.first[k][np.minimum(gid, len(caster.first[k]) - 1)] + prim, no_hit)
        az = caster.az[k][None, :] + a[:, None]
        nz = caster.nz[k][None, :]
        if fine:
            sector = np.round(az / (2 * math.pi / FINE_AZIMUTHS)).astype(np.int64) % FINE_AZIMUTHS
            face = np.where(nz > 0.97, 0, 1 + (nz > 0.5) * FINE_AZIMUTHS + sector)
        else:
            face = np.where(nz > 0.7, 0, 1 + np.round(az / (math.pi / 2)).astype(np.int64) % 4)
        table = (1 + caster.part[k][None, :] * classes + face).astype(np.uint16)
        lab = np.take(table, tri + (np.arange(B) * table.shape[1])[:, None])
        label = np.where(hit, lab, label)
        best_t = np.where(hit, t, best_t)
    return label, best_t


@pytest.mark.parametrize("home", [1, 4])
def test_the_exact_renderings_labels_are_numpys_bit_for_bit(home):
    """A skirt knob (home 1) and a pointer with a fixed base (home 4), seen from cameras
    around the axis, every turn and both face-class sets; one camera centre for all rays
    and one origin per ray."""
    from hearth.perception.knob_shapes import _Caster, knob_shape
    from hearth.worldmodel.homegen import generate_home
    w = generate_home(home)
    k = w.knobs()[0]
    caster = _Caster(knob_shape(k, w.apartment.library, w.base_dir))
    rng = np.random.default_rng(home)
    r = k.radius
    for _ in range(3):
        C = np.array([rng.uniform(-3, 3) * r, rng.uniform(-3, 3) * r, rng.uniform(4, 40) * r])
        target = rng.uniform(-1.3 * r, 1.3 * r, (1500, 3))
        target[:, 2] = rng.uniform(-0.5 * r, 0.5 * r, 1500)
        dirs = target - C
        turns = rng.uniform(-np.pi, np.pi, 5)
        per_ray = np.broadcast_to(C, (5, 1500, 3)) + rng.normal(0, 1e-4, (5, 1500, 3))
        for origins, d in ((C, dirs), (per_ray, dirs), (per_ray, np.broadcast_to(dirs, (5, 1500, 3)))):
            for fine in (False, True):
                lab0, t0 = _numpy_labels(caster, origins, d, turns, 0.3, fine)
                lab, t = caster.labels(origins, d, turns, 0.3, fine=fine, with_t=True)
                assert np.count_nonzero(lab0) > 100
                assert lab.tobytes() == lab0.tobytes() and t.tobytes() == t0.tobytes()


@pytest.mark.parametrize("home", [1, 4])
def test_only_rays_that_miss_a_scenes_box_are_left_uncast(home):
    """``turn_rays_near_box`` keeps every ray that hits the scene (each scene's rays cast
    whole here) and leaves out most of those that pass beside the knob, grazing ones
    included."""
    import open3d as o3d
    from hearth.perception.knob_shapes import _Caster, knob_shape
    from hearth.worldmodel.homegen import generate_home
    w = generate_home(home)
    k = w.knobs()[0]
    caster = _Caster(knob_shape(k, w.apartment.library, w.base_dir))
    rng = np.random.default_rng(home)
    r = k.radius
    C = np.array([0.5 * r, -r, 12 * r])
    target = rng.uniform(-3 * r, 3 * r, (4000, 3))
    target[:, 2] = 0.0
    rays = np.concatenate([np.broadcast_to(C, (4000, 3)), target - C], 1).astype(np.float32)

    def near(r, lo, hi, keep):
        """The kernel on rays (M, 6), each with its own origin, not turned."""
        out = np.empty((len(r), 6), np.float32)
        return knob_kernels.turn_rays_near_box(r[None, :, :3], r[None, :, 3:], np.ones(1),
                                               np.zeros(1), lo, hi, out, keep)
    for scene, bounds in zip(caster.scenes, caster.bounds):
        if scene is None:
            continue
        lo, hi = bounds
        hit = np.isfinite(scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy())
        keep = np.empty(len(rays), np.int64)
        m = near(rays.astype(np.float64), lo, hi, keep)
        kept = np.zeros(len(rays), bool)
        kept[keep[:m]] = True
        assert hit.sum() > 50 and not np.any(hit & ~kept)
        assert m < 0.6 * len(rays)
        # a ray along a face of the box, just inside it, is kept; just outside, not
        along = np.array([[lo[0] + 1e-6, 0.0, hi[2] + 1.0, 0.0, 0.0, -1.0],
                          [lo[0] - 1e-6, 0.0, hi[2] + 1.0, 0.0, 0.0, -1.0]], np.float32)
        along[:, 1] = 0.5 * (lo[1] + hi[1])
        assert near(along.astype(np.float64), lo, hi, np.empty(2, np.int64)) == 1


def _numpy_settle(win, labels, iterations, max_shift):
    """``_Window.settle`` as numpy made it (before ``knob_kernels.settle_shift``)."""
    n = win.n
    t = np.zeros(2)
    for _ in range(iterations):
        W = win.maps(labels, t)
        mu, _ = win._solve(W)
        model = (W.T @ mu).reshape(n, n, 3)
        gy, gx = np.gradient(model, axis=(0, 1))
        J = np.stack([-gx.ravel(), gy.ravel()], 1)
        r = (win.Xc.reshape(n, n, 3) - model).ravel()
        A = J.T @ J
        if np.linalg.cond(A) > 1e10:
            break
        step = np.clip(np.linalg.solve(A, J.T @ r), -1.5, 1.5)
        t = t + step
        if np.hypot(*t) > max_shift:
            t = t * (max_shift / np.hypot(*t))
        if np.all(np.abs(step) < 0.02):
            break
    return t


def test_the_compiled_settle_finds_numpys_shift(reader, monkeypatch):
    """The exact check's Gauss-Newton offset, compiled, on the windows of real readings
    (rendered views of the demo oven's knobs, Kinect noise): the shift numpy's loop finds,
    within 1e-9 px (the sums are made in another order), and the readings' states and
    angles are the ones that shift gives."""
    import hearth.perception.knob_window as kn
    from hearth.robot.noise import add_kinect_noise
    from hearth.perception.knob_data import KnobDataConfig, KnobScenes, render_views
    from tests.conftest import DEMO_WORLD
    from hearth.worldmodel import load_world
    world = load_world(DEMO_WORLD)
    views = render_views(world, 12, 5, KnobDataConfig(at_states=True, missing_rate=0.0),
                         reader.config, noise=add_kinect_noise, scenes=KnobScenes(world))
    compiled = kn._Window.settle
    pairs = []

    def both(win, labels, iterations, max_shift):
        t = compiled(win, labels, iterations, max_shift)
        pairs.append((t, _numpy_settle(win, labels, iterations, max_shift)))
        return t
    monkeypatch.setattr(kn._Window, "settle", both)
    moved = 0
    for v in views:
        reader.read(v.image, v.K, v.T_world_camera, [v.believed], depth=v.depth)
    assert len(pairs) >= 12
    for t, ref in pairs:
        assert np.abs(t - ref).max() < 1e-9, (t, ref)
        moved += np.hypot(*ref) > 0.05
    assert moved >= 3              # the views' pose errors: most windows do move


@pytest.mark.parametrize("seed", range(3))
def test_depth_fits_are_depth_scores(seed):
    """One window's measured depth against renderings' ray parameters (inf: the ray missed
    the knob and meets the panel), compiled, against ``depth_scores``: the same scores, the
    zeros (too few valid rays, a negative slope) included."""
    from hearth.perception.knobs import depth_scores, measured_heights
    rng = np.random.default_rng(seed)
    N, B = 900, 6
    panel = 0.5 + rng.normal(0, 0.002, N)
    ts = np.where(rng.random((B, N)) < 0.4, panel - rng.uniform(0.005, 0.02, (B, N)), np.inf)
    ts[-1] = panel + (panel - np.where(np.isfinite(ts[0]), ts[0], panel))   # the knob inverted
    m = np.where(np.isfinite(ts[0]), ts[0], panel) + rng.normal(0, 5e-4, N)
    for share in (0.8, 0.3):
        valid = rng.random(N) < share
        want = depth_scores(m[None], valid[None], np.where(np.isfinite(ts), ts, panel[None]))[0]
        _, Wm, Sw, Sm, Smm, count = measured_heights(m[None], valid[None])
        got = np.empty(B)
        knob_kernels.depth_fits(ts, panel, valid, Wm[0], float(Sw[0, 0]), float(Sm[0, 0]),
                                float(Smm[0, 0]), bool(count[0, 0] >= 0.5 * N), got)
        assert np.allclose(got, want, rtol=1e-9, atol=1e-12)
        assert (want[0] > 0.5) == (share == 0.8) and want[-1] == 0.0
