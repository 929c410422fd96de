"""The simulated camera's compiled per-pixel loops (hearth/perception/kernels.py) against the numpy
passes they replaced, kept here as the reference: the same frames bit for bit (noise spread,
noisy depth, shading, the adaptive cast's filled depth and its list of pixels to cast), on
rendered kitchen views and on edge values."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hearth.robot import noise as N
from hearth.perception import kernels
from hearth.perception.camera import Intrinsics

K = Intrinsics.kinect()


# --- the numpy passes, as they were before the kernels ---------------------------------

def _arccos_ref(x):
    acc = np.multiply(x, N._ACOS[7])
    for a in N._ACOS[6:0:-1]:
        acc += a
        acc *= x
    acc += N._ACOS[0]
    root = np.subtract(np.float32(1.0), x)
    np.sqrt(root, out=root)
    acc *= root
    return acc


def spread_ref(incidence, labels, codes, z, m, std, p):
    cos = np.clip(np.asarray(incidence, dtype=np.float32), 1e-3, 1.0)
    theta = _arccos_ref(cos)
    np.minimum(theta, np.float32(math.radians(89.0)), out=theta)
    zc = np.maximum(z, np.float32(1e-3))
    ang = np.subtract(np.float32(math.pi / 2), theta)
    np.divide(theta, ang, out=ang)
    var = np.subtract(z, np.float32(m.axial_c))
    np.square(var, out=var)
    var *= np.float32(m.axial_b)
    var += np.float32(m.axial_a)
    t = np.sqrt(zc)
    np.divide(np.float32(m.axial_angle), t, out=t)
    t *= ang
    t *= ang
    var += t
    np.square(var, out=var)
    if m.quantise:
        q2 = np.multiply(zc, zc, out=zc)
        q2 *= np.float32(m.disparity_step_px / (m.focal_ir_px * m.baseline_m))
        np.square(q2, out=q2)
        q2 /= np.float32(12.0)
        np.subtract(var, q2, out=q2)
        var *= np.float32(0.25)
        np.maximum(q2, var, out=var)
    np.sqrt(var, out=std)
    g0, g1 = math.cos(math.radians(m.grazing_start_deg)), math.cos(math.radians(m.grazing_full_deg))
    np.clip((np.float32(g0) - cos) * np.float32(1.0 / max(g0 - g1, 1e-6)), 0.0, 1.0, out=p)
    if codes.any():
        p_code = np.array([0.0, m.dark_dropout, m.shiny_dropout, m.glass_dropout], np.float32)
        lab = labels.astype(np.intp)
        pm = np.take(p_code[codes], lab)
        is_shiny = codes == 2
        shiny = np.take(is_shiny, lab) if is_shiny.any() else None
        if shiny is not None and shiny.any():
            pm[shiny] *= np.clip((1.0 - cos[shiny]) / np.float32(0.1), 0.3, 1.0)
        np.maximum(p, pm, out=p)
    p[~(z > 0)] = np.inf


def noisy_depth_ref(z, std, p_drop, gauss, uniform, m, out):
    noisy = np.multiply(std, gauss, out=out)
    noisy += z
    if m.quantise:
        fb = np.float32(m.focal_ir_px * m.baseline_m / m.disparity_step_px)
        steps = np.maximum(noisy, np.float32(1e-3))
        np.rint(np.divide(fb, steps, out=steps), out=steps)
        np.divide(fb, np.maximum(steps, np.float32(1), out=steps), out=noisy)
    drop = noisy < m.min_range
    drop |= noisy > m.max_range
    drop |= uniform < p_drop
    noisy[drop] = 0
    return noisy


def shade_ref(depth, miss, triangle, inv_length, no_hit, tri_labels, abs_dist, colour_shade):
    t = triangle.copy()
    np.copyto(t, no_hit, where=miss)
    labels = np.take(tri_labels, t.astype(np.intp))
    inc = np.take(abs_dist, t.astype(np.intp))
    inv_t = np.divide(inv_length, depth, where=~miss, out=np.zeros(len(depth), np.float32))
    inc *= inv_t
    np.minimum(inc, 1, out=inc)
    rgbs = np.take(colour_shade, t.astype(np.intp), axis=0)
    s = np.float32(0.15) * inc
    s += rgbs[:, 3]
    planes = []
    for ch in range(3):
        c = np.multiply(rgbs[:, ch], s)
        np.minimum(c, 255, out=c)
        planes.append(c.astype(np.uint8))
    return t, labels, inc, np.stack(planes, 1)


def fill_ref(blocks, s, xs, ys, coef, no_hit, unset, known, depth, tri):
    pr, pc = blocks.shape
    Wr = pc * s
    t = np.minimum(blocks, np.uint32(no_hit)).astype(np.intp)
    A, B, C = (np.take(np.ascontiguousarray(coef[:, k]), t) for k in range(3))
    filled = blocks != unset
    inv = np.empty(blocks.shape)
    for dr in range(s):
        y = ys[np.arange(pr) * s + dr][:, None]
        r = slice(dr, pr * s, s)
        By = B * y
        for dc in range(s):
            np.multiply(A, xs[np.arange(pc) * s + dc], out=inv)
            inv += By
            inv += C
            with np.errstate(divide="ignore"):
                d = np.divide(1.0, inv, out=inv).astype(np.float32)
            c = slice(dc, Wr, s)
            m = ~known[r, c] & filled
            np.copyto(depth[r, c], d, where=m)
            np.copyto(tri[r, c], blocks, where=m)


def unset_pixels_ref(blocks, unset, ps, H, W, known):
    pr, pc = blocks.shape
    bi, bj = np.nonzero(blocks == unset)
    r0, c0 = bi * ps, bj * ps
    r1 = np.where(bi == pr - 1, H, r0 + ps)
    c1 = np.where(bj == pc - 1, W, c0 + ps)
    rr = r0[:, None] + np.repeat(np.arange(ps + 1), ps + 1)[None]
    cc = c0[:, None] + np.tile(np.arange(ps + 1), ps + 1)[None]
    ok = (rr < r1[:, None]) & (cc < c1[:, None])
    idx = (rr * W + cc)[ok]
    return idx[~known[idx]]


# --- the tests -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def kitchen():
    from hearth.benchmarks import _worlds
    from hearth.benchmarks.robot import _kitchen_views
    from hearth.robot.sim import world_scene
    world = _worlds.load("demo")
    return world_scene(world), _kitchen_views(world)


def _noise_both(inc, labels, codes, z, gauss, uniform, m):
    got = [np.empty_like(z) for _ in range(3)]
    want = [np.empty_like(z) for _ in range(3)]
    N._spread(inc, labels, codes, z, m, std=got[0], p=got[1])
    N._noisy_depth(z, got[0], got[1], gauss, uniform, m, out=got[2])
    spread_ref(inc, labels, codes, z, m, std=want[0], p=want[1])
    noisy_depth_ref(z, want[0], want[1], gauss, uniform, m, out=want[2])
    return got, want


@pytest.mark.parametrize("model", [N.KinectNoise(), N.KinectNoise(quantise=False, axial_b=0.004)])
def test_noise_pass_is_the_numpy_formulas_bit_for_bit_on_kitchen_views(kitchen, model):
    scene, views = kitchen
    rng = np.random.default_rng(5)
    codes = np.array([N.MATERIAL_CODES.get(x, 0) for x in scene.materials] + [0], np.int8)
    assert (codes == 2).any() and (codes == 3).any()         # shiny and glass in the kitchen
    for T in views[:3]:
        r = scene.render(K, T)
        z = N._lateral(r.depth, rng, model)
        gauss = rng.standard_normal(z.shape, dtype=np.float32)
        uniform = rng.random(z.shape, dtype=np.float32)
        got, want = _noise_both(r.incidence, r.labels, codes, z, gauss, uniform, model)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
        assert (got[2] == 0).any() and (got[2] > 0).sum() > z.size // 2


def test_noise_pass_is_the_numpy_formulas_at_edge_values():
    rng = np.random.default_rng(1)
    n = 20_000
    inc = rng.choice(np.array([0, 1e-4, 1e-3, 0.05, 0.3, 0.7, 0.999, 1.0], np.float32), n)
    inc = (inc * rng.uniform(0.9, 1.1, n)).astype(np.float32)
    z = rng.choice(np.array([0, 1e-4, 0.3, 0.45, 1.0, 3.0, 5.99, 6.2, 7.9], np.float32), n)
    z = (z * rng.uniform(0.98, 1.02, n)).astype(np.float32)
    labels = rng.integers(-1, 4, n).astype(np.int32)
    codes = np.array([0, 1, 2, 3, 0], np.int8)          # matte, dark, shiny, glass; -1: matte
    gauss = (rng.standard_normal(n) * 3).astype(np.float32)
    uniform = rng.random(n, dtype=np.float32)
    for m in (N.KinectNoise(), N.KinectNoise(quantise=False), N.KinectNoise(shiny_dropout=1.0)):
        got, want = _noise_both(inc, labels, codes, z, gauss, uniform, m)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
    got, want = _noise_both(inc, labels, np.zeros(5, np.int8), z, gauss, uniform, N.KinectNoise())
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


def test_noise_loops_refuse_an_output_they_cannot_write_into():
    z = np.ones((4, 6), np.float32)
    with pytest.raises(ValueError, match="C-contiguous float32"):
        N._noisy_depth(z, z, z, z, z, N.KinectNoise(), out=np.empty((6, 4), np.float32).T)


def test_shading_pass_is_the_numpy_passes_bit_for_bit(kitchen):
    scene, views = kitchen
    from hearth.perception.render import _pixel_rays
    _, inv_length = _pixel_rays(K)
    for T in views[:3]:
        hits = scene.cast(K, T)
        r = scene.shade(hits)
        dist = scene._tri_normals @ hits.c_world - scene._tri_offsets
        facing = np.where(dist < 0, -1.0, 1.0)[:, None] * scene._tri_normals
        facing[scene._no_hit] = 0
        from hearth.perception.render import AMBIENT, LIGHT_WORLD
        lit = np.clip(facing @ LIGHT_WORLD, 0, 1)
        shade0 = (0.85 * (1 - AMBIENT) * lit + 0.85 * AMBIENT).astype(np.float32)
        shade0[scene._no_hit] = 0
        cs = np.empty((len(shade0), 4), np.float32)
        cs[:, :3] = scene._tri_palette.T
        cs[:, 3] = shade0
        t, labels, inc, color = shade_ref(hits.depth.reshape(-1), hits.miss, hits.triangle,
                                          inv_length, np.uint32(scene._no_hit),
                                          scene._tri_labels, np.abs(dist).astype(np.float32), cs)
        np.testing.assert_array_equal(r.triangle.reshape(-1), t)
        np.testing.assert_array_equal(r.labels.reshape(-1), labels)
        np.testing.assert_array_equal(r.incidence.reshape(-1), inc)
        np.testing.assert_array_equal(r.color.reshape(-1, 3), color)
        assert len(np.unique(labels)) > 3 and color.max() > 100


@pytest.mark.parametrize("shape,s", [((480, 640), 2), ((121, 163), 2), ((60, 80), 4)])
def test_filled_depth_and_pixels_to_cast_are_the_numpy_passes(shape, s):
    rng = np.random.default_rng(len(shape) + s + shape[0])
    H, W = shape
    from hearth.perception.render import _grid
    pr, pc = len(_grid(H, s)) - 1, len(_grid(W, s)) - 1     # the last blocks reach the edge
    unset, no_hit = np.uint32(0xFFFFFFFE), np.uint32(50)
    blocks = rng.integers(0, 51, (pr, pc)).astype(np.uint32)
    blocks[rng.random((pr, pc)) < 0.3] = unset
    coef = rng.normal(0, 1, (51, 3))
    coef[:, 2] += 2.0
    coef[7] = 0.0                                      # a plane the rays never meet: inf
    coef[no_hit] = 0.0
    known = rng.random((H, W)) < 0.2
    xs = (np.arange(W) - W / 2) / 500.0
    ys = (np.arange(H) - H / 2) / 500.0
    d_ref, d_new = (np.full((H, W), -1, np.float32) for _ in range(2))
    t_ref, t_new = (np.full((H, W), 9, np.uint32) for _ in range(2))
    fill_ref(blocks, s, xs, ys, coef, no_hit, unset, known, d_ref, t_ref)
    for band in (slice(0, pr // 3), slice(pr // 3, pr)):
        kernels.fill_blocks(blocks, band.start, band.stop, s, xs, ys, coef, no_hit, unset, known,
                            d_new, t_new)
    np.testing.assert_array_equal(d_new, d_ref)
    np.testing.assert_array_equal(t_new, t_ref)
    assert np.isinf(d_new).any() and (d_new == -1).any()
    flat = known.reshape(-1)
    np.testing.assert_array_equal(kernels.unset_block_pixels(blocks, unset, s, H, W, flat),
                                  unset_pixels_ref(blocks, unset, s, H, W, flat))


def split_near_ref(r0, r1, c0, c1, nr, nc):
    import cv2
    w = nc + 1
    acc = (np.bincount(np.concatenate([r0 * w + c0, r1 * w + c1]), minlength=(nr + 1) * w)
           - np.bincount(np.concatenate([r0 * w + c1, r1 * w + c0]), minlength=(nr + 1) * w))
    acc = cv2.integral(acc.astype(np.float64).reshape(nr + 1, w))
    return acc[1:nr + 1, 1:nc + 1] > 0


def test_wedge_boxes_and_narrowest_widths_are_the_numpy_passes():
    rng = np.random.default_rng(3)
    nr, nc = 120, 160
    r0 = rng.integers(0, nr, 500)
    c0 = rng.integers(0, nc, 500)
    r1 = np.minimum(r0 + rng.integers(1, 18, 500), nr)
    c1 = np.minimum(c0 + rng.integers(1, 18, 500), nc)
    got = np.zeros((nr, nc), bool)
    kernels.paint_boxes(r0, r1, c0, c1, got)
    np.testing.assert_array_equal(got, split_near_ref(r0, r1, c0, c1, nr, nc))
    assert 0 < got.mean() < 1
    from hearth.perception.render import _DIRECTIONS
    cos, sin = np.cos(_DIRECTIONS), np.sin(_DIRECTIONS)
    u = rng.normal(300, 200, (400, 20))
    v = rng.normal(200, 150, (400, 20))
    u[7, 3] = np.nan                                   # numpy's max and min give NaN
    for k in (8, 20):
        proj = u[:, :k, None] * cos + v[:, :k, None] * sin
        want = (proj.max(axis=1) - proj.min(axis=1)).min(axis=1)
        w = np.empty(len(u))
        kernels.narrowest_widths(u, v, k, cos, sin, w)
        np.testing.assert_array_equal(w, want)
