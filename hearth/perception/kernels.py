"""Per-pixel loops of the simulated camera compiled by numba, one pass each.

Written by hand because no library has them: numpy makes one pass over memory per
operation, and the per-pixel formulas of the sensor noise (``hearth.robot.noise``) take about
thirty operations over image-sized arrays. On the 2-core machine such passes are bound by
memory bandwidth and the GIL, not by arithmetic: numpy's noise took 6.1 ms a 640x480 frame on
one thread and two threads gained little (measured: two threads streaming out-of-cache
arrays reach 0.83x the time of one; numexpr, which fuses in blocks, was 3-5x slower than
numpy here because its float32 loops are not vectorised). A compiled loop makes one pass
per pixel, vectorised by LLVM.

Every kernel computes **the same float32 operations in the same order** as the numpy
expressions it replaces (the formulas' order in docs/robot-adapter.md), so the frames are the
same bit for bit (tests/robot/test_noise_kernels.py compares them with the numpy formulas):

- no fast-math (no reassociation, no contraction into fused multiply-adds);
- float32 constants passed as float32 (a float64 constant would widen the arithmetic);
- ``np.rint`` of a non-negative float32 below 2^23 as ``(x + 2^23) - 2^23`` (round to nearest,
  ties to even, as rint: exact in float32 for such x; LLVM vectorises it, not the libm call);
- clip, minimum and maximum as comparisons and selects (the same values where nothing is
  NaN, and nothing here is).

``error_model="numpy"``: a division by zero gives inf as numpy does, no check in the loop.
``cache=True``: compiled once per machine into ``__pycache__`` (or numba's user cache where
that is not writable); ``nogil``: the renderer's row bands run them on several threads.
"""
from __future__ import annotations

import numba
import numpy as np

_JIT = dict(nogil=True, cache=True, error_model="numpy")


@numba.njit(**_JIT)
def noise_spread(incidence, z, std, p, lo, r89, half_pi, axial_c, axial_b, axial_a, axial_angle,
                 q_per_z2, g0, g_scale, a0, a1, a2, a3, a4, a5, a6, a7, quantise):
    """Per pixel (flat float32 arrays): the Gaussian part's standard deviation of the axial
    noise into ``std`` and the grazing dropout probability into ``p`` (inf where ``z`` is
    not > 0). The numpy original, operation for operation: tests/robot/test_noise_kernels.py.
    ``a0`` .. ``a7``: hearth.robot.noise._ACOS (the arccos polynomial)."""
    one = np.float32(1.0)
    zero = np.float32(0.0)
    twelve = np.float32(12.0)
    quarter = np.float32(0.25)
    inf = np.float32(np.inf)
    for i in range(z.shape[0]):
        c = incidence[i]
        cs = c if c > lo else lo                     # np.clip(incidence, 1e-3, 1)
        cs = cs if cs < one else one
        acc = cs * a7                                # arccos by Horner's rule
        acc = (acc + a6) * cs
        acc = (acc + a5) * cs
        acc = (acc + a4) * cs
        acc = (acc + a3) * cs
        acc = (acc + a2) * cs
        acc = (acc + a1) * cs
        acc = acc + a0
        theta = acc * np.sqrt(one - cs)
        theta = theta if theta < r89 else r89
        zi = z[i]
        zc = zi if zi > lo else lo
        ang = theta / (half_pi - theta)
        var = zi - axial_c
        var = var * var
        var = var * axial_b
        var = var + axial_a
        t = axial_angle / np.sqrt(zc)
        t = t * ang
        t = t * ang
        var = var + t
        var = var * var
        if quantise:
            q2 = zc * zc
            q2 = q2 * q_per_z2
            q2 = q2 * q2
            q2 = q2 / twelve
            q2 = var - q2
            var = var * quarter
            var = q2 if q2 > var else var
        std[i] = np.sqrt(var)
        g = (g0 - cs) * g_scale
        g = g if g > zero else zero
        g = g if g < one else one
        p[i] = g if zi > zero else inf


@numba.njit(**_JIT)
def noise_materials(incidence, labels, p, p_label, shiny_label, lo, shiny_floor, shiny_span):
    """``p`` raised to each pixel's material dropout (``p_label`` per label, the last entry
    for label -1), the shiny ones' scaled by clip((1 - cos) / ``shiny_span``, ``shiny_floor``,
    1) (cos the incidence clipped to [``lo``, 1])."""
    one = np.float32(1.0)
    n = p_label.shape[0]
    for i in range(p.shape[0]):
        k = labels[i]
        k = k + n if k < 0 else k
        pm = p_label[k]
        if shiny_label[k]:
            c = incidence[i]
            cs = c if c > lo else lo
            cs = cs if cs < one else one
            f = (one - cs) / shiny_span
            f = f if f > shiny_floor else shiny_floor
            f = f if f < one else one
            pm = pm * f
        p[i] = p[i] if p[i] > pm else pm


@numba.njit(**_JIT)
def noise_depth(z, std, p, gauss, uniform, out, lo, fb, min_range, max_range, quantise):
    """Axial noise, quantisation in disparity and dropouts of the depth ``z`` into ``out``
    (flat float32), given the spread (``noise_spread``) and the draws."""
    one = np.float32(1.0)
    zero = np.float32(0.0)
    big = np.float32(8388608.0)                      # 2^23: (x + 2^23) - 2^23 = rint(x)
    for i in range(z.shape[0]):
        noisy = std[i] * gauss[i]
        noisy = noisy + z[i]
        if quantise:
            steps = noisy if noisy > lo else lo
            steps = (fb / steps + big) - big         # fb / steps in [0, 3.5e5]: below 2^23
            steps = steps if steps > one else one
            noisy = fb / steps
        drop = (noisy < min_range) | (noisy > max_range) | (uniform[i] < p[i])
        out[i] = zero if drop else noisy


@numba.njit(**_JIT)
def shade(depth, miss, triangle, inv_length, no_hit, tri_labels, abs_dist, colour_shade,
          view_light, tri, labels, incidence, color):
    """Per pixel (flat arrays of a band of rows), hearth.perception.render.Scene.shade's numpy
    passes in one: the triangle (``no_hit`` where ``miss``) into ``tri``, its label into
    ``labels``, the incidence cosine |n . c - h| / (t |d|) (``abs_dist`` per triangle times
    the pixel's inverse ray length over its depth, 0 where missed; at most 1) into
    ``incidence``, and the colour: each channel of the triangle's colour times its shade
    plus ``view_light`` times the incidence, at most 255, truncated to uint8 (``color``,
    (N, 3)). ``colour_shade``: per triangle, red, green, blue and the shade (float32)."""
    one = np.float32(1.0)
    zero = np.float32(0.0)
    top = np.float32(255.0)
    for i in range(depth.shape[0]):
        m = miss[i]
        t = no_hit if m else triangle[i]
        tri[i] = t
        labels[i] = tri_labels[t]
        inv_t = zero if m else inv_length[i] / depth[i]
        inc = abs_dist[t] * inv_t
        inc = one if inc > one else inc              # np.minimum(inc, 1) (NaN stays NaN)
        incidence[i] = inc
        s = view_light * inc
        s = s + colour_shade[t, 3]
        for ch in range(3):
            c = colour_shade[t, ch] * s
            c = top if c > top else c
            color[i, ch] = np.uint8(c)


@numba.njit(**_JIT)
def fill_blocks(blocks, row0, row1, s, xs, ys, coef, no_hit, unset, known, depth, tri):
    """The adaptive cast's filled pixels (hearth.perception.render._AdaptiveCast.run): for every
    block of side ``s`` in block rows ``row0`` .. ``row1`` filled with a triangle
    (``blocks`` (rows, columns) uint32, ``unset`` where not), each of its pixels no ray went
    through (``known`` false) gets that triangle (into ``tri``) and the depth where its ray
    (x, y, 1) meets the triangle's plane: 1 / (A x + B y + C) in float64, in that order,
    rounded to float32 (into ``depth``; ``coef`` (triangles, 3) float64, its row
    ``no_hit`` zeros: a block that saw nothing gets inf, set to 0 as a miss later)."""
    for br in range(row0, row1):
        for bc in range(blocks.shape[1]):
            b = blocks[br, bc]
            if b == unset:
                continue
            t = b if b < no_hit else no_hit
            A = coef[t, 0]
            B = coef[t, 1]
            C = coef[t, 2]
            for dr in range(s):
                r = br * s + dr
                By = B * ys[r]
                for dc in range(s):
                    c = bc * s + dc
                    if known[r, c]:
                        continue
                    inv = A * xs[c]
                    inv = inv + By
                    inv = inv + C
                    depth[r, c] = np.float32(1.0 / inv)
                    tri[r, c] = b


@numba.njit(**_JIT)
def put_hits(idx, gid, prim, t_hit, first, no_hit, no_hit_gid, depth, tri, known):
    """The answers of a batch of rays cast through the flat pixels ``idx``
    (hearth.perception.render._AdaptiveCast._cast): each pixel's depth (``t_hit``), its scene
    triangle (the first triangle of geometry ``gid`` plus the primitive ``prim``, ``first``
    taken with its index clipped into range; ``no_hit`` where ``gid`` is ``no_hit_gid``:
    nothing hit), and that it is known."""
    last = first.shape[0] - 1
    for j in range(idx.shape[0]):
        i = idx[j]
        g = gid[j]
        k = g if g < last else last
        t = first[k] + prim[j]
        tri[i] = no_hit if g == no_hit_gid else t
        depth[i] = t_hit[j]
        known[i] = True


@numba.njit(**_JIT)
def unset_block_pixels(blocks, unset, s, H, W, known):
    """The flat pixels no ray went through yet of the blocks of side ``s`` not filled
    (``blocks`` == ``unset``; the last row and column of blocks reach to the image's edge),
    blocks in row-major order and pixels in row-major order within each (the order of the
    batch decides Embree's last bit, so it is kept)."""
    nr, nc = blocks.shape
    n = 0
    for bi in range(nr):
        for bj in range(nc):
            if blocks[bi, bj] == unset:
                n += (s + 1) * (s + 1)
    out = np.empty(n, np.int64)
    n = 0
    for bi in range(nr):
        r0 = bi * s
        r1 = H if bi == nr - 1 else r0 + s
        for bj in range(nc):
            if blocks[bi, bj] != unset:
                continue
            c0 = bj * s
            c1 = W if bj == nc - 1 else c0 + s
            for r in range(r0, r1):
                for c in range(c0, c1):
                    i = r * W + c
                    if not known[i]:
                        out[n] = i
                        n += 1
    return out[:n]


@numba.njit(**_JIT)
def paint_boxes(r0, r1, c0, c1, out):
    """``out[r0[k]:r1[k], c0[k]:c1[k]] = True`` for every box k (the adaptive cast's blocks
    near an outline's corner, hearth.perception.render._AdaptiveCast._split_near)."""
    for k in range(r0.shape[0]):
        for r in range(r0[k], r1[k]):
            for c in range(c0[k], c1[k]):
                out[r, c] = True


@numba.njit(**_JIT)
def narrowest_widths(u, v, k, cos, sin, out):
    """For each row i of the image points ``u``, ``v`` (boxes, points), over its first ``k``
    points: the smallest over the directions (``cos``, ``sin``) of the extent of u cos + v sin
    (each product in float64, then their sum, as numpy's), into ``out``; NaN where a point
    is NaN, as numpy's max and min give it."""
    for i in range(u.shape[0]):
        best = np.inf
        for j in range(cos.shape[0]):
            cj = cos[j]
            sj = sin[j]
            lo = np.inf
            hi = -np.inf
            for p in range(k):
                x = u[i, p] * cj + v[i, p] * sj
                if x != x:
                    lo = hi = x
                    break
                lo = x if x < lo else lo
                hi = x if x > hi else hi
            w = hi - lo
            if w != w:
                best = w
                break
            best = w if w < best else best
        out[i] = best
