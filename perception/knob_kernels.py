"""The knob reader's label sums compiled by numba (``perception.knobs._Window``).

Written by hand because no library has them: the exact check (``KnobReader._refine``) fits
each rendering's soft label maps to the image window by least squares, and the normal
equations are sums over the window's pixels of products of the bilinear weights of the four
image pixels each window pixel mixes. numpy made them with ``np.bincount`` over index and
weight arrays 16 times the window's size built for each call (the largest share of a knob's
reading time: ``fits`` alone was a fifth of it). These loops make the same sums without the
arrays, **in the same order** as ``np.bincount`` adds (its weights are added to their bins one
after another in the order of the flattened arrays), so every float64 sum is the same bit for
bit and so is every reading (tests/knobs/test_knob_kernels.py compares them with the numpy
sums). No fast-math; ``cache=True`` and ``nogil`` as in ``perception.kernels``.
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
    ``xc`` (N, 3): the window's centred colours. G and bv start at zero. The order of the
    sums is np.bincount's over arrays shaped (B, 4, 4, N) and (B, 4, N), channel by channel."""
    B = labels.shape[0]
    N = idx.shape[1]
    lab = np.empty((B, 4, N), np.int64)        # the corners' labels, looked up once
    for b in range(B):
        for k in range(4):
            for n in range(N):
                lab[b, k, n] = lut[labels[b, idx[k, n]]]
    for b in range(B):
        for k1 in range(4):
            for k2 in range(4):
                for n in range(N):
                    G[b, lab[b, k1, n], lab[b, k2, n]] += wts[k1, n] * wts[k2, n]
    for c in range(3):
        for b in range(B):
            for k in range(4):
                for n in range(N):
                    bv[b, lab[b, k, n], c] += wts[k, n] * xc[n, c]


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
def turn_rays(origins, dirs, c, s, rays):
    """Rays turned back by each turn's angle about +z into the visuals' frame, as float32
    (origin, direction): x' = c x + s y, y' = -s x + c y, z' = z, in float64 and then
    rounded (numpy's order). ``origins`` (Bo, No, 3) and ``dirs`` (Bd, N, 3) with Bo, Bd 1 or
    the turns' count and No 1 or N (numpy's broadcasting); ``c``, ``s`` (Bc,); ``rays`` (Bc,
    N, 6)."""
    Bc, N = rays.shape[0], rays.shape[1]
    for b in range(Bc):
        bo = b if origins.shape[0] > 1 else 0
        bd = b if dirs.shape[0] > 1 else 0
        cb, sb = c[b], s[b]
        ms = -sb
        for n in range(N):
            no = n if origins.shape[1] > 1 else 0
            x, y = origins[bo, no, 0], origins[bo, no, 1]
            rays[b, n, 0] = cb * x + sb * y
            rays[b, n, 1] = ms * x + cb * y
            rays[b, n, 2] = origins[bo, no, 2]
            x, y = dirs[bd, n, 0], dirs[bd, n, 1]
            rays[b, n, 3] = cb * x + sb * y
            rays[b, n, 4] = ms * x + cb * y
            rays[b, n, 5] = dirs[bd, n, 2]


@numba.njit(**_JIT)
def nearest_labels(t, gid, prim, first, az, nz, part, turns, fine, classes, n_fine, fine_step,
                   quarter, label, best_t):
    """Where a ray's hit ``t`` (Bc, N; Bc = 1: the same hits for every turn) is nearer than
    ``best_t`` (B, N), its label and t there: the label 1 + visual * classes + face class of
    the triangle hit (``first[geometry] + primitive``), the face class from the triangle's
    normal steepness ``nz`` and azimuth ``az`` turned by the turn (``perception.knobs.
    _Caster.labels``, whose per-turn tables it replaces: the same float64 operations;
    ``fine_step`` 2 pi / n_fine and ``quarter`` pi / 2 as Python computed them)."""
    B, N = label.shape
    last = first.shape[0] - 1
    for b in range(B):
        r = b if t.shape[0] > 1 else 0
        a = turns[b]
        for n in range(N):
            tt = t[r, n]
            if not (tt < best_t[b, n]):
                continue
            g = np.int64(gid[r, n])
            if g > last:
                g = last
            tri = first[g] + np.int64(prim[r, n])
            azv = az[tri] + a
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
