"""The knob reader's exact-check loops compiled by numba (``hearth.perception.knobs._Caster`` and
``_Window``).

Written by hand because no library has them: the exact check (``KnobReader._refine``) fits
each rendering's soft label maps to the image window by least squares, and the normal
equations are sums over the window's pixels of products of the bilinear weights of the four
image pixels each window pixel mixes. numpy made them with ``np.bincount`` over index and
weight arrays 16 times the window's size built for each call (the largest share of a knob's
reading time: ``fits`` alone was a fifth of it). These loops make the same sums without the
arrays. ``label_maps`` adds **in the same order** as ``np.bincount`` (its weights are added to
their bins one after another in the order of the flattened arrays), so its float64 sums are
the same bit for bit. ``label_gram`` and ``settle_shift`` add a window pixel whose four
corners show one label (most pixels: a label's inside) as one product, the square of its
weights' sum, not sixteen: the same sums to rounding (1e-12 of the largest in the tests), a
tenth of a reading faster; over 240 readings of six homes every state and every evidence
figure stayed the same, angles to 1e-9 rad (tests/knobs/test_knob_kernels.py compares them
with the numpy sums). The exact renderings' rays are turned and culled to the visuals'
bounding box (``turn_rays_near_box``) and labelled from their hits (``nearest_labels``), and
a batch of renderings is fitted in one call each to the colours (``label_fits``) and to the
depth (``depth_fits``): there the numpy calls cost more than their sums. No fast-math;
``cache=True`` and ``nogil`` as in ``hearth.perception.kernels``.
"""
from __future__ import annotations

import numba
import numpy as np

_JIT = dict(nogil=True, cache=True, error_model="numpy")


@numba.njit(**_JIT)
def label_gram(labels, lut, idx, wts, xc, G, bv):
    """The normal equations of B renderings' soft label maps: ``G[b]`` (L, L) += the sum
    over window pixels n and corner pairs (k1, k2) of wts[k1, n] wts[k2, n] at the labels of
    corners k1 and k2, ``bv[b]`` (L, 3) += the sum over n and k of wts[k, n] xc[n] at the
    label of corner k. ``labels`` (B, box pixels): each rendering's labels; ``lut``: label ->
    0..L-1; ``idx``, ``wts`` (4, N): the box pixels each window pixel mixes and their weights;
    ``xc`` (N, 3): the window's centred colours. G and bv start at zero. A pixel whose four
    corners show one label (most of a window: a label's inside) adds its 16 products as one,
    the square of its weights' sum, and its colour times that sum (the same sums to rounding:
    ``_bincount_gram`` in tests/knobs/test_knob_kernels.py is the reference, to 1e-12)."""
    B = labels.shape[0]
    N = idx.shape[1]
    for b in range(B):
        for n in range(N):
            l0 = lut[labels[b, idx[0, n]]]
            l1 = lut[labels[b, idx[1, n]]]
            l2 = lut[labels[b, idx[2, n]]]
            l3 = lut[labels[b, idx[3, n]]]
            if l0 == l1 and l0 == l2 and l0 == l3:
                s = wts[0, n] + wts[1, n] + wts[2, n] + wts[3, n]
                G[b, l0, l0] += s * s
                for c in range(3):
                    bv[b, l0, c] += s * xc[n, c]
                continue
            ls = (l0, l1, l2, l3)
            for k1 in range(4):
                w1 = wts[k1, n]
                a = ls[k1]
                for k2 in range(4):
                    G[b, a, ls[k2]] += w1 * wts[k2, n]
                for c in range(3):
                    bv[b, a, c] += w1 * xc[n, c]


@numba.njit(**_JIT)
def label_maps(labels, lut, idx, wts, W):
    """Soft label maps (L, N) of one rendering's box labels: ``W[lut[label of corner k of
    pixel n], n] += wts[k, n]``, corner by corner (np.bincount's order over (4, N)). W starts
    at zero."""
    N = idx.shape[1]
    for k in range(4):
        for n in range(N):
            W[lut[labels[idx[k, n]]], n] += wts[k, n]


@numba.njit(**_JIT)
def nearest_labels(keep, t, gid, prim, Bc, first, az, nz, part, turns, fine, classes, n_fine,
                   fine_step, quarter, label, best_t):
    """Where a ray's hit is nearer than ``best_t`` (B, N), its label and t there. The hits
    are those of the rays cast: ray ``keep[j]`` (an index into Bc x N rays; Bc = 1: the same
    rays, so the same hits, for every turn) hit triangle ``first[gid[j]] + prim[j]`` at
    ``t[j]`` (inf: nothing); the rays not cast hit nothing. The label is 1 + visual *
    classes + face class of the triangle hit, the face class from the triangle's normal
    steepness ``nz`` and azimuth ``az`` turned by the turn (``hearth.perception.knobs.
    _Caster.labels``, whose per-turn tables it replaces: the same float64 operations;
    ``fine_step`` 2 pi / n_fine and ``quarter`` pi / 2 as Python computed them)."""
    B, N = label.shape
    last = first.shape[0] - 1
    for j in range(keep.shape[0]):
        tt = t[j]
        if not (tt < np.inf):
            continue
        r = keep[j] // N
        n = keep[j] - r * N
        g = np.int64(gid[j])
        if g > last:
            g = last
        tri = first[g] + np.int64(prim[j])
        b0, b1 = (0, B) if Bc == 1 else (r, r + 1)
        for b in range(b0, b1):
            if not (tt < best_t[b, n]):
                continue
            azv = az[tri] + turns[b]
            if fine:
                sector = np.int64(np.rint(azv / fine_step)) % n_fine
                if nz[tri] > 0.97:
                    face = 0
                elif nz[tri] > 0.5:
                    face = 1 + n_fine + sector
                else:
                    face = 1 + sector
            else:
                if nz[tri] > 0.7:
                    face = 0
                else:
                    face = 1 + np.int64(np.rint(azv / quarter)) % 4
            label[b, n] = np.uint16(1 + part[tri] * classes + face)
            best_t[b, n] = tt


@numba.njit(**_JIT)
def settle_shift(labels, lut, L, H, jj, ii, box, xc, n, ridge, iterations, max_shift):
    """``hearth.perception.knobs._Window.settle`` compiled: the shift t (window px, canvas x right,
    y up) of one rendering's labels (``labels``, the box's pixels; ``lut`` label -> 0..L-1)
    that fits the window's centred colours ``xc`` (N, 3) best, by Gauss-Newton
    (Lucas-Kanade): at each step the soft label maps sampled at t (the four box pixels
    each window pixel ``(jj, ii)`` maps to through ``H`` shifted by -t, bilinear weights),
    each label's colour by least squares (a ridge of ``ridge`` + 1e-6), the model image,
    its gradient (``np.gradient``'s differences: central inside, one-sided at the edges),
    and the step that fits the residual, clipped to 1.5 px, t kept within ``max_shift``;
    stopping when both components of a step are under 0.02 px, after ``iterations`` steps,
    or when the step's normal matrix is singular (condition number over 1e10). The same
    operations as the numpy loop, summed in another order (the sparse maps' four corners
    instead of dense products), so a shift may differ in its last bits."""
    u0, v0, u1, v1 = box[0], box[1], box[2], box[3]
    w, h = u1 - u0, v1 - v0
    N = n * n
    t0, t1 = 0.0, 0.0
    lab = np.empty((4, N), np.int64)
    wts = np.empty((4, N))
    model = np.empty((N, 3))
    for _ in range(iterations):
        # the sampling at t
        for q in range(N):
            a = jj[q] - t0
            b = ii[q] + t1
            pz = H[2, 0] * a + H[2, 1] * b + H[2, 2]
            if pz <= 0:
                return t0, t1
            x = (H[0, 0] * a + H[0, 1] * b + H[0, 2]) / pz - u0
            y = (H[1, 0] * a + H[1, 1] * b + H[1, 2]) / pz - v0
            x = min(max(x, 0.0), w - 1.0)
            y = min(max(y, 0.0), h - 1.0)
            x0 = min(np.int64(np.floor(x)), w - 2)
            y0 = min(np.int64(np.floor(y)), h - 2)
            fx, fy = x - x0, y - y0
            base = y0 * w + x0
            lab[0, q] = lut[labels[base]]
            lab[1, q] = lut[labels[base + 1]]
            lab[2, q] = lut[labels[base + w]]
            lab[3, q] = lut[labels[base + w + 1]]
            wts[0, q] = (1 - fx) * (1 - fy)
            wts[1, q] = fx * (1 - fy)
            wts[2, q] = (1 - fx) * fy
            wts[3, q] = fx * fy
        # each label's colour: the normal equations of the soft maps
        # (a pixel whose four corners show one label as one product: ``label_gram``)
        G = np.zeros((L, L))
        bv = np.zeros((L, 3))
        for q in range(N):
            l0 = lab[0, q]
            if l0 == lab[1, q] and l0 == lab[2, q] and l0 == lab[3, q]:
                s = wts[0, q] + wts[1, q] + wts[2, q] + wts[3, q]
                G[l0, l0] += s * s
                for c in range(3):
                    bv[l0, c] += s * xc[q, c]
                continue
            for k1 in range(4):
                l1, w1 = lab[k1, q], wts[k1, q]
                for k2 in range(4):
                    G[l1, lab[k2, q]] += w1 * wts[k2, q]
                for c in range(3):
                    bv[l1, c] += w1 * xc[q, c]
        for l in range(L):
            G[l, l] += 1e-6 + ridge
        mu = np.linalg.solve(G, bv)
        for q in range(N):
            l0 = lab[0, q]
            if l0 == lab[1, q] and l0 == lab[2, q] and l0 == lab[3, q]:
                s = wts[0, q] + wts[1, q] + wts[2, q] + wts[3, q]
                for c in range(3):
                    model[q, c] = s * mu[l0, c]
                continue
            for c in range(3):
                s = 0.0
                for k in range(4):
                    s += wts[k, q] * mu[lab[k, q], c]
                model[q, c] = s
        # the Gauss-Newton step: J = (-d model / dx, d model / dy) (canvas y up: rows down)
        a00, a01, a11, g0, g1 = 0.0, 0.0, 0.0, 0.0, 0.0
        for i in range(n):
            for j in range(n):
                q = i * n + j
                for c in range(3):
                    if j == 0:
                        gx = model[q + 1, c] - model[q, c]
                    elif j == n - 1:
                        gx = model[q, c] - model[q - 1, c]
                    else:
                        gx = (model[q + 1, c] - model[q - 1, c]) / 2.0
                    if i == 0:
                        gy = model[q + n, c] - model[q, c]
                    elif i == n - 1:
                        gy = model[q, c] - model[q - n, c]
                    else:
                        gy = (model[q + n, c] - model[q - n, c]) / 2.0
                    j0, j1 = -gx, gy
                    r = xc[q, c] - model[q, c]
                    a00 += j0 * j0
                    a01 += j0 * j1
                    a11 += j1 * j1
                    g0 += j0 * r
                    g1 += j1 * r
        # the condition number of the symmetric 2 x 2 normal matrix: its eigenvalues' ratio
        half_tr = 0.5 * (a00 + a11)
        disc = np.sqrt((0.5 * (a00 - a11)) ** 2 + a01 * a01)
        big = half_tr + disc
        det = a00 * a11 - a01 * a01
        small = det / big if big > 0 else 0.0
        if not (small > 0) or big / small > 1e10:
            break
        s0 = min(max((a11 * g0 - a01 * g1) / det, -1.5), 1.5)
        s1 = min(max((a00 * g1 - a01 * g0) / det, -1.5), 1.5)
        t0 += s0
        t1 += s1
        d = np.hypot(t0, t1)
        if d > max_shift:
            t0 *= max_shift / d
            t1 *= max_shift / d
        if abs(s0) < 0.02 and abs(s1) < 0.02:
            break
    return t0, t1


@numba.njit(**_JIT)
def label_fits(labels, idx, wts, xc, diag, out):
    """``hearth.perception.knobs._Window.fits`` in one call: for each of B renderings (``labels``
    (B, box pixels)), the normal equations of its soft label maps (``label_gram``, over the
    labels present in any of them, numbered in increasing order as ``_label_lut`` numbers
    them), ``diag`` added to their diagonal, each label's colour solved (LAPACK's gesv, as
    numpy's solve) and ``out[b]`` = the explained sum of squares, sum(b * mu). The numpy
    calls it replaces cost more than their sums on a window (a tenth of a millisecond each
    rendering call)."""
    B = labels.shape[0]
    top = 0
    for b in range(B):
        for p in range(labels.shape[1]):
            if labels[b, p] > top:
                top = labels[b, p]
    lut = np.full(top + 1, -1, np.int64)
    for b in range(B):
        for p in range(labels.shape[1]):
            lut[labels[b, p]] = 0
    L = 0
    for v in range(top + 1):
        if lut[v] == 0:
            lut[v] = L
            L += 1
    G = np.zeros((B, L, L))
    bv = np.zeros((B, L, 3))
    label_gram(labels, lut, idx, wts, xc, G, bv)
    for b in range(B):
        for l in range(L):
            G[b, l, l] += diag
        mu = np.linalg.solve(G[b], bv[b])
        s = 0.0
        for l in range(L):
            for c in range(3):
                s += bv[b, l, c] * mu[l, c]
        out[b] = s


@numba.njit(**_JIT)
def depth_fits(ts, panel, valid, wm, sw, sm, smm, ok_count, out):
    """``hearth.perception.knobs.depth_scores`` of one window's measured depth against B renderings
    in one call: rendering b's depth along each ray is ``ts[b]`` where it hit the knob, else
    ``panel``; in mm about its mean over all the window's rays, correlated (squared, a
    positive slope only, else 0) with the measured depth where ``valid``. ``wm``: the
    measured depth (mm) where valid, else 0; ``sw``, ``sm``, ``smm``: the count of valid rays
    (at least 1), and the sums of the measured depth and of its square; ``ok_count``: whether
    enough rays are valid. The same operations as numpy's, summed in another order."""
    B, N = ts.shape
    for b in range(B):
        mean = 0.0
        for n in range(N):
            z = ts[b, n] if np.isfinite(ts[b, n]) else panel[n]
            mean += z * 1000.0
        mean /= N
        st, stt, smt = 0.0, 0.0, 0.0
        for n in range(N):
            if valid[n]:
                z = ts[b, n] if np.isfinite(ts[b, n]) else panel[n]
                t = z * 1000.0 - mean
                st += t
                stt += t * t
                smt += wm[n] * t
        cov = smt - sm * st / sw
        vm = smm - sm * sm / sw
        vt = stt - st * st / sw
        if ok_count and cov > 0 and vm > 1e-9 and vt > 1e-9:
            out[b] = cov * cov / max(vm * vt, 1e-12)
        else:
            out[b] = 0.0


@numba.njit(**_JIT)
def turn_rays_near_box(origins, dirs, c, s, lo, hi, out, keep):
    """Rays turned back by each turn's angle about +z into the visuals' frame, kept only
    when they can hit what lies in the box ``lo`` .. ``hi`` (3,) at t >= 0. Turning: x' = c
    x + s y, y' = -s x + c y, z' = z, in float64 and rounded to float32 (numpy's order);
    ``origins`` (Bo, No, 3) and ``dirs`` (Bd, N, 3) with Bo, Bd 1 or the turns' count and No
    1 or N (numpy's broadcasting); ``c``, ``s`` (Bc,). The box test: the slab test in float64
    on the rounded ray. A scene's hits lie inside its bounding box, so a ray that misses the
    box hits nothing: ``hearth.perception.knobs._Caster`` casts only the others (Embree costs about
    40 ns a ray even for one that misses, and most of a window's rays pass beside the knob;
    the box is the caller's, padded so that rounding cannot drop a ray that grazes it). The
    kept rays go to ``out`` (Bc * N, 6) in order and their indices (b * N + n) to ``keep``;
    returns how many."""
    Bc, N = c.shape[0], dirs.shape[1]
    k = 0
    ray = np.empty(6, np.float32)
    for b in range(Bc):
        bo = b if origins.shape[0] > 1 else 0
        bd = b if dirs.shape[0] > 1 else 0
        cb, sb = c[b], s[b]
        ms = -sb
        for n in range(N):
            no = n if origins.shape[1] > 1 else 0
            x, y = origins[bo, no, 0], origins[bo, no, 1]
            ray[0] = cb * x + sb * y
            ray[1] = ms * x + cb * y
            ray[2] = origins[bo, no, 2]
            x, y = dirs[bd, n, 0], dirs[bd, n, 1]
            ray[3] = cb * x + sb * y
            ray[4] = ms * x + cb * y
            ray[5] = dirs[bd, n, 2]
            t0, t1 = 0.0, np.inf
            ok = True
            for a in range(3):
                o = np.float64(ray[a])
                d = np.float64(ray[3 + a])
                if d == 0.0:
                    if o < lo[a] or o > hi[a]:
                        ok = False
                        break
                    continue
                ta = (lo[a] - o) / d
                tb = (hi[a] - o) / d
                if ta > tb:
                    ta, tb = tb, ta
                if ta > t0:
                    t0 = ta
                if tb < t1:
                    t1 = tb
                if t0 > t1:
                    ok = False
                    break
            if ok:
                for j in range(6):
                    out[k, j] = ray[j]
                keep[k] = b * N + n
                k += 1
    return k
