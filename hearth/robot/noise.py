"""A Kinect-class (structured light, first generation) RGB-D noise model.

Applied to a noise-free ``hearth.perception.render.Rendering``; pure: a rendering and a numpy
``Generator`` in, a new rendering with noisy ``depth`` and ``color`` out (labels, normals and
incidence stay the noise-free ground truth). Every constant is a field of ``KinectNoise``;
docs/robot-adapter.md gives the formulas and where the numbers come from.

Depth, in the order applied:

1. Lateral noise: at depth discontinuities a pixel reads the depth of a neighbour picked
   with a Gaussian offset of ``lateral_px`` pixels (Nguyen et al. 2012 measured ~0.8 px);
   on smooth surfaces a lateral shift changes nothing, so only edge pixels are touched.
2. Axial noise (Nguyen, Izadi, Lovell 2012, "Modeling Kinect sensor noise for improved 3D
   reconstruction and tracking"), in metres, with z in metres and theta the angle between
   the ray and the surface normal::

       sigma_z(z, theta) = a + b (z - c)^2 + d / sqrt(z) * theta^2 / (pi/2 - theta)^2
       a = 0.0012, b = 0.0019, c = 0.4, d = 0.0001

   ``sigma_z`` is the *total* standard deviation a real sensor shows (the paper measured a
   real Kinect, quantisation included), so the Gaussian part is drawn with
   ``sqrt(sigma_z^2 - q(z)^2 / 12)`` and quantisation (3.) adds the rest.
3. Quantisation: the sensor measures disparity in 1/8 pixel steps; depth is
   ``z = f_ir * baseline / disparity``, so readings snap to ``f_ir * baseline / (k / 8)``
   (step ``q(z) = z^2 / (8 f_ir baseline)``: 2.9 mm at 1 m, 11 mm at 2 m with
   f_ir = 580 px, baseline = 0.075 m).
4. Dropouts (depth 0): outside [min_range, max_range]; at grazing incidence (probability
   rising linearly from 0 at ``grazing_start_deg`` to 1 at ``grazing_full_deg`` between ray
   and normal); on materials: ``dark`` and ``shiny`` surfaces lose readings with
   probabilities ``dark_dropout`` and ``shiny_dropout`` (shiny: mostly where the projector's
   pattern is reflected away, i.e. not seen head-on), ``glass`` with ``glass_dropout``.

Colour: Gaussian per-pixel sensor noise of ``color_std`` grey levels, rounded to whole levels
(the same on the three channels, luma noise), on the renderer's shaded material colours.
Markers stay readable.

The random draws of a frame, from one generator in a fixed order: the depth's standard
normals, the dropouts' uniforms and the colour's levels (all frame-sized, so the simulated
robot starts them before it casts the frame's rays), then the lateral offsets of the edge
pixels. A seed gives the same frames however the work is split into threads.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from concurrent.futures import Future
from dataclasses import dataclass

import cv2
import numpy as np

from hearth.perception import kernels
from hearth.perception.bands import in_bands, pool, row_bands

MATERIAL_CODES = {"matte": 0, "dark": 1, "shiny": 2, "glass": 3}


@dataclass(frozen=True)
class KinectNoise:
    """Constants of the noise model (metres, pixels, degrees, probabilities)."""
    axial_a: float = 0.0012
    axial_b: float = 0.0019
    axial_c: float = 0.4
    axial_angle: float = 0.0001
    lateral_px: float = 0.8
    focal_ir_px: float = 580.0
    baseline_m: float = 0.075
    disparity_step_px: float = 1.0 / 8.0
    quantise: bool = True
    min_range: float = 0.45
    max_range: float = 6.0
    grazing_start_deg: float = 72.0
    grazing_full_deg: float = 85.0
    dark_dropout: float = 0.5
    shiny_dropout: float = 0.35
    glass_dropout: float = 0.9
    color_std: float = 2.0
    edge_jump: float = 0.03

    def axial_std(self, z, theta=0.0):
        """Total axial standard deviation (metres) at depth ``z`` (m) and incidence angle
        ``theta`` (rad between the ray and the surface normal)."""
        z = np.asarray(z, dtype=np.float64)
        theta = np.clip(np.asarray(theta, dtype=np.float64), 0.0, math.radians(89.0))
        return (self.axial_a + self.axial_b * (z - self.axial_c) ** 2
                + self.axial_angle / np.sqrt(np.maximum(z, 1e-3))
                * theta ** 2 / (math.pi / 2 - theta) ** 2)

    def quantisation_step(self, z):
        """Depth step (m) of one disparity step at depth ``z`` (m)."""
        z = np.asarray(z, dtype=np.float64)
        return z ** 2 * self.disparity_step_px / (self.focal_ir_px * self.baseline_m)


def add_kinect_noise(rendering, rng: np.random.Generator | None = None,
                     model: KinectNoise | None = KinectNoise()):
    """A copy of ``rendering`` with Kinect-class noise on ``depth`` (metres, 0 = no reading,
    float32) and ``color`` (uint8 RGB); other fields are shared with the input (ground truth).
    ``model=None`` returns the rendering unchanged. Deterministic for a seeded ``rng``."""
    if model is None:
        return rendering
    return finish_kinect_noise(rendering, start_kinect_noise(rendering.depth, rng, model))


@dataclass(frozen=True)
class NoiseDraws:
    """The random part of one frame's noise, being drawn on a pool thread
    (``start_kinect_noise``): ``lateral``, a future of the laterally jittered depth;
    ``draws``, a future of ``draw_kinect_noise``'s draws: the per-pixel standard normals of
    the depth, uniforms of the dropouts and grey-level offsets of the colour (None without
    colour noise)."""
    model: KinectNoise
    lateral: Future
    draws: Future


def draw_kinect_noise(shape, rng: np.random.Generator,
                      model: KinectNoise = KinectNoise()) -> Future:
    """Start the frame-sized random draws of a frame of ``shape`` (rows, columns) on a pool
    thread: they need nothing but the image size, so the simulated robot starts them before
    it casts the frame's rays (hearth.robot.sim.render_view). A future of the depth's
    standard normals, the dropouts' uniforms and the colour's grey-level offsets (int16; None
    without colour noise). ``rng`` is the drawing thread's until the future is done."""
    shape = tuple(int(s) for s in shape)

    def draw():
        gauss = rng.standard_normal(shape, dtype=np.float32)
        uniform = rng.random(shape, dtype=np.float32)
        levels = None
        if model.color_std > 0:
            levels = np.take(_grey_levels(model.color_std),
                             rng.integers(0, _LEVEL_TABLE, size=shape, dtype=np.uint16))
        return gauss, uniform, levels

    return pool().submit(draw)


_LEVEL_TABLE = 1 << 16


@functools.lru_cache(maxsize=8)
def _grey_levels(std: float) -> np.ndarray:
    """A table of ``_LEVEL_TABLE`` grey-level offsets (int16) whose entries, picked by a
    uniform 16-bit integer, are distributed as a Gaussian of ``std`` grey levels rounded to
    the nearest level (inverse-CDF sampling of that discrete distribution, to 1/65536 in
    probability: a tail under 1/65536 on either side, beyond about 4.3 standard deviations,
    is not drawn). Five times cheaper than drawing a standard normal per pixel, rounding and
    converting it; numpy has no sampler of a discretised Gaussian, so this table is written
    here."""
    k_max = int(math.ceil(4.5 * std)) + 1
    ks = np.arange(-k_max, k_max + 1)
    upper = np.array([0.5 * (1.0 + math.erf((k + 0.5) / (std * math.sqrt(2.0)))) for k in ks])
    u = (np.arange(_LEVEL_TABLE) + 0.5) / _LEVEL_TABLE
    return ks[np.minimum(np.searchsorted(upper, u, side="right"), len(ks) - 1)].astype(np.int16)


def start_kinect_noise(depth, rng: np.random.Generator | None = None,
                       model: KinectNoise = KinectNoise(), draws: Future | None = None) -> NoiseDraws:
    """Start the noise of a frame whose noise-free depth is ``depth``: the random draws
    (``draws``, from ``draw_kinect_noise`` started earlier on the same ``rng``, or started
    here) and then the lateral jitter, on a pool thread, so that the caller can shade the
    frame meanwhile; ``finish_kinect_noise`` applies them. ``rng`` is the pool thread's until
    then. One generator is drawn in a fixed order, the frame-sized draws (depth normals,
    dropout uniforms, colour levels) first and the lateral offsets of the edge pixels last:
    the same realisation for a seed however the work is split into threads.
    ``add_kinect_noise`` is the two in a row: the same frames for the same seed."""
    rng = np.random.default_rng() if rng is None else rng
    z = np.asarray(depth, dtype=np.float32)
    if draws is None:
        draws = draw_kinect_noise(z.shape, rng, model)

    def jitter():
        draws.result()              # the generator is the drawing thread's until then
        return _lateral(z, rng, model)

    return NoiseDraws(model, pool().submit(jitter), draws)


def finish_kinect_noise(rendering, started: NoiseDraws):
    """``add_kinect_noise``'s result for ``rendering`` from the draws started on its depth."""
    bands = NoiseBands(started, rendering.materials, rendering.depth.shape)
    in_bands(row_bands(rendering.depth.shape[0]),
             lambda rows: bands.band(rows, rendering.labels, rendering.incidence,
                                     rendering.color))
    return bands.result(rendering)


class NoiseBands:
    """The noise of one frame applied band by band of rows (``band``), from the draws
    started on its depth (``start_kinect_noise``): the renderer calls ``band`` for each band
    as soon as it has shaded it (``hearth.perception.render.Scene.shade``'s ``after``), so that the
    noise's per-pixel work runs in the shading's threads while its inputs are in the cache,
    with no wait between the two. The same frame as ``finish_kinect_noise``, whatever the
    bands."""

    def __init__(self, started: NoiseDraws, materials, shape):
        self.started = started
        self.codes = np.array([MATERIAL_CODES.get(x, 0) for x in materials] + [0], np.int8)
        self.depth = np.empty(shape, dtype=np.float32)
        self.color = np.empty(tuple(shape) + (3,), dtype=np.uint8)

    def band(self, rows: slice, labels: np.ndarray, incidence: np.ndarray,
             color: np.ndarray) -> None:
        """Rows ``rows`` of the noisy depth and colour, given the noise-free labels,
        incidence and colour there (image-shaped arrays)."""
        if rows.stop <= rows.start:
            return
        m = self.started.model
        z = self.started.lateral.result()[rows]
        # Per pixel, the Gaussian part's standard deviation and the dropout probability.
        std, p_drop = np.empty_like(z), np.empty_like(z)
        _spread(incidence[rows], labels[rows], self.codes, z, m, std=std, p=p_drop)
        gauss, uniform, levels = self.started.draws.result()
        _noisy_depth(z, std, p_drop, gauss[rows], uniform[rows], m, out=self.depth[rows])
        self.color[rows] = _noisy_color(color[rows], None if levels is None else levels[rows], m)

    def result(self, rendering):
        """``rendering`` with the noisy depth and colour (once every band is done)."""
        return dataclasses.replace(rendering, depth=self.depth, color=self.color)


def _spread(incidence: np.ndarray, labels: np.ndarray, codes: np.ndarray, z: np.ndarray,
            m: KinectNoise, std: np.ndarray, p: np.ndarray) -> None:
    """Per pixel of the (laterally jittered) depth ``z``, into ``std`` and ``p``: the standard
    deviation of the Gaussian part of the axial noise, and the dropout probability (inf
    where nothing was seen: always dropped); ``codes``: per label, and a trailing one for
    label -1, the material's code. float32 throughout, in one compiled pass per pixel
    (hearth.perception.kernels; the numpy expressions it replaced, operation for operation, are in
    tests/robot/test_noise_kernels.py): this runs on every simulated frame. The arrays are
    C-contiguous image rows (a band of them)."""
    f = np.float32
    inc, zf = _flat_in(incidence), _flat_in(z)
    g0, g1 = math.cos(math.radians(m.grazing_start_deg)), math.cos(math.radians(m.grazing_full_deg))
    # (a + b (z - c)^2 + d / sqrt(z) * ang * ang)^2, ang = theta / (pi/2 - theta), the
    # Gaussian part leaving room for the quantisation's own variance; then the grazing
    # dropouts.
    kernels.noise_spread(inc, zf, _flat_out(std), _flat_out(p), f(1e-3), f(math.radians(89.0)),
                         f(math.pi / 2), f(m.axial_c), f(m.axial_b), f(m.axial_a),
                         f(m.axial_angle), f(m.disparity_step_px / (m.focal_ir_px * m.baseline_m)),
                         f(g0), f(1.0 / max(g0 - g1, 1e-6)), *_ACOS, bool(m.quantise))
    if codes.any():
        # Materials (per label, and a trailing "matte" for label -1); shiny surfaces reflect
        # the pattern away except when seen nearly head-on.
        p_code = np.array([0.0, m.dark_dropout, m.shiny_dropout, m.glass_dropout], np.float32)
        kernels.noise_materials(inc, _flat_in(labels, np.int32), _flat_out(p), p_code[codes],
                                codes == 2, f(1e-3), f(0.3), f(0.1))


def _flat_in(a: np.ndarray, dtype=np.float32) -> np.ndarray:
    """``a`` as a flat C-contiguous array of ``dtype`` for a compiled loop (a view when it
    is one already)."""
    return np.ascontiguousarray(a, dtype=dtype).reshape(-1)


def _flat_out(a: np.ndarray) -> np.ndarray:
    """A flat view of ``a`` for a compiled loop to write into (a copy would lose what it
    writes, so anything but C-contiguous float32 is refused)."""
    if a.dtype != np.float32 or not a.flags.c_contiguous:
        raise ValueError("a compiled noise loop writes into C-contiguous float32 arrays only")
    return a.reshape(-1)


#: Abramowitz and Stegun 4.4.46: arccos(x) = sqrt(1 - x) (a0 + a1 x + ... + a7 x^7) on
#: [0, 1], error at most 2e-8 rad (numpy's float32 arccos is not vectorised: 3.7 ms a frame,
#: this 0.85 ms in numpy, less in the compiled pass).
_ACOS = tuple(np.float32(a) for a in (1.5707963050, -0.2145988016, 0.0889789874, -0.0501743046,
                                      0.0308918810, -0.0170881256, 0.0066700901, -0.0012624911))


def _noisy_depth(z: np.ndarray, std: np.ndarray, p_drop: np.ndarray, gauss: np.ndarray,
                 uniform: np.ndarray, m: KinectNoise, out: np.ndarray) -> np.ndarray:
    """Axial noise, quantisation and dropouts of the depth ``z`` into ``out``, given the
    per-pixel spread (``_spread``) and draws (C-contiguous image rows), in one compiled pass
    (hearth.perception.kernels)."""
    f = np.float32
    kernels.noise_depth(_flat_in(z), _flat_in(std), _flat_in(p_drop), _flat_in(gauss),
                        _flat_in(uniform), _flat_out(out), f(1e-3),
                        f(m.focal_ir_px * m.baseline_m / m.disparity_step_px), f(m.min_range),
                        f(m.max_range), bool(m.quantise))
    return out


def _lateral(z: np.ndarray, rng: np.random.Generator, m: KinectNoise) -> np.ndarray:
    """Edge pixels read a neighbour picked with a Gaussian pixel offset (Nguyen: sigma_L ~
    0.8 px). Smooth surfaces are unchanged by a sub-pixel shift, so only pixels next to a
    depth jump are touched, which keeps this cheap."""
    if m.lateral_px <= 0:
        return z.copy()
    jump = np.float32(m.edge_jump)
    dx = _absdiff(z[:, 1:], z[:, :-1]) > jump
    dy = _absdiff(z[1:], z[:-1]) > jump
    edge = np.zeros(z.shape, dtype=bool)
    edge[:, 1:] = dx
    edge[:, :-1] |= dx
    edge[1:, :] |= dy
    edge[:-1, :] |= dy
    out = z.copy()
    # Flat indices (row-major, as np.nonzero's), ten times cheaper than np.nonzero's pairs.
    idx = np.flatnonzero(edge)
    if len(idx) == 0:
        return out
    vs, us = np.divmod(idx, z.shape[1])
    off = np.rint(rng.standard_normal((2, len(idx))) * m.lateral_px).astype(np.int64)
    v2 = np.clip(vs + off[0], 0, z.shape[0] - 1)
    u2 = np.clip(us + off[1], 0, z.shape[1] - 1)
    out.reshape(-1)[idx] = z[v2, u2]
    return out


def _absdiff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b|: OpenCV's absdiff in one pass (numpy takes a difference, then its absolute
    value); OpenCV answers None for an empty image."""
    return cv2.absdiff(a, b) if a.size else np.abs(a - b)


def _noisy_color(color: np.ndarray, levels, m: KinectNoise) -> np.ndarray:
    """Grey-level Gaussian noise of ``color_std`` (rounded to integer levels: ``levels``,
    int16, drawn by ``draw_kinect_noise``) on every channel. OpenCV adds with saturation in
    one pass (4x numpy's widen, add, clip, narrow)."""
    if levels is None or m.color_std <= 0 or color.size == 0:  # (OpenCV refuses no pixels)
        return color.copy()
    return cv2.add(color, cv2.merge([levels, levels, levels]), dtype=cv2.CV_8U)
