"""Rendering labelled meshes into depth, colour, normals and node labels by ray casting.

open3d's ``RaycastingScene`` (Embree) does the ray casting; this module adds what it has no
notion of: per-mesh colours and node labels, and simple Lambertian shading. Pure: meshes in,
arrays out (the one side effect: building the first scene tunes glibc's malloc for
frame-sized arrays, see ``_keep_freed_memory``). The simulated robot adds sensor noise on
top (hearth/robot/noise.py), drawing it while ``Scene.shade`` runs (``Scene.cast`` first).
"""
from __future__ import annotations

import ctypes
import os
import sys
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import cv2
import numpy as np
import open3d as o3d

from perception.bands import in_bands, row_bands
from perception.camera import Intrinsics

#: Light direction in the world frame (from above, slightly from the side), for shading.
LIGHT_WORLD = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
AMBIENT = 0.45
_NO_HIT = np.uint32(0xFFFFFFFF)         # open3d's geometry and primitive id of a miss


@dataclass
class Rendering:
    """One rendered view. ``depth`` in metres along the optical axis (0: no surface),
    ``color`` uint8 RGB (H, W, 3), ``labels`` index into ``nodes`` (-1: nothing),
    ``normals_camera`` unit normals in the camera frame facing the camera (0 where nothing
    was hit), ``incidence`` cos of the angle between the ray and the surface normal.
    ``triangle``: per pixel, the row of ``triangle_normals_camera`` (the scene's triangles'
    normals in this camera's frame, facing it; the last row, zeros, for no hit) from which
    ``normals_camera`` is gathered when first asked for."""
    depth: np.ndarray
    color: np.ndarray
    labels: np.ndarray
    nodes: list[str]
    owners: list[str]
    names: list[str]
    materials: list[str]
    incidence: np.ndarray
    triangle: np.ndarray
    triangle_normals_camera: np.ndarray

    @cached_property
    def normals_camera(self) -> np.ndarray:
        return np.take(self.triangle_normals_camera, self.triangle, axis=0)

    def mask(self, node_ids: Sequence[str]) -> np.ndarray:
        """Pixels that show any of the given nodes."""
        idx = [i for i, n in enumerate(self.nodes) if n in set(node_ids)]
        return np.isin(self.labels, idx)

    def owner_mask(self, owner_ids: Sequence[str]) -> np.ndarray:
        """Pixels that show anything belonging to the given large objects."""
        idx = [i for i, n in enumerate(self.owners) if n in set(owner_ids)]
        return np.isin(self.labels, idx)


class Scene:
    """A ray-casting scene built once from labelled meshes (see worldmodel.geometry).

    Besides the Embree scene it keeps, per triangle, the unit normal and plane offset
    (n . x = h) in the world frame and the mesh's label and colour: with flat triangles the
    normal, the side the camera sees and the Lambertian term are the same over a whole
    triangle, so a view computes them once per triangle and gathers them per pixel."""

    def __init__(self, meshes):
        _keep_freed_memory()
        self._scene = o3d.t.geometry.RaycastingScene()
        self.nodes: list[str] = []
        self.owners: list[str] = []
        self.names: list[str] = []
        self.materials: list[str] = []
        colors, normals, offsets, labels = [], [], [], []
        first = {}                       # geometry id -> its first triangle's index
        count = 0
        for lm in meshes:
            if len(lm.mesh.triangles) == 0:
                continue
            gid = self._scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
            i = len(self.nodes)
            self.nodes.append(lm.node)
            self.owners.append(lm.owner)
            self.names.append(lm.name)
            self.materials.append(lm.material)
            colors.append(lm.color)
            v = np.asarray(lm.mesh.vertices, dtype=np.float64)
            t = np.asarray(lm.mesh.triangles)
            n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
            norm = np.linalg.norm(n, axis=1, keepdims=True)
            n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)   # Embree skips 0-area
            normals.append(n)
            offsets.append(np.einsum("ij,ij->i", n, v[t[:, 0]]))
            labels.append(np.full(len(t), i, dtype=np.int32))
            first[gid] = count
            count += len(t)
        self._colors = np.asarray(colors, dtype=np.float32).reshape(-1, 3)
        # Per-triangle tables with a trailing row for "nothing hit" (label -1, black, no normal).
        self._tri_normals = np.vstack(normals + [np.zeros((1, 3))])
        self._tri_offsets = np.concatenate(offsets + [np.zeros(1)])
        self._tri_labels = np.concatenate(labels + [np.full(1, -1, np.int32)])
        palette = np.vstack([self._colors, np.zeros((1, 3), np.float32)]) * np.float32(255.0)
        self._tri_palette = np.ascontiguousarray(palette[self._tri_labels].T)   # (3, T + 1)
        self._no_hit = count
        # geometry id -> its first triangle (an unknown id, and the miss id, clip to the end).
        self._first = np.full(max(first, default=-1) + 2, count, dtype=np.uint32)
        for gid, f in first.items():
            self._first[gid] = f

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
        """Render the view of camera ``K`` at ``T_world_camera``."""
        return self.shade(self.cast(K, T_world_camera, max_range))

    def cast(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Hits:
        """The ray cast of a view (depth final: 0 where nothing was hit within ``max_range``),
        before shading: ``shade`` makes it a ``Rendering``. Split so that work that needs only
        the depth (the simulated sensor's noise draws) can run while the shading does."""
        H, W = K.height, K.width
        T = np.asarray(T_world_camera, dtype=np.float64)
        R_wc, c_world = T[:3, :3], T[:3, 3]
        rays_camera, _ = _pixel_rays(K)
        # Rays in float32 (what Embree uses anyway): pixel directions cached per camera,
        # rotated into the world and interleaved with the origin by OpenCV (several times
        # cheaper than open3d's float64 create_rays_pinhole or numpy's strided writes). One
        # call over the whole image: made in 7 row bands, some rays (and so depths) moved by
        # an ulp (measured), and the depth must stay what it was.
        origin = np.zeros((3, 4), dtype=np.float32)
        origin[:, 3] = c_world
        rays = cv2.merge([cv2.transform(rays_camera, origin),
                          cv2.transform(rays_camera, R_wc.astype(np.float32))])
        ans = self._scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        # Directions have z = 1 in the camera frame, so t_hit is depth along the optical axis.
        depth = ans["t_hit"].numpy().reshape(-1)
        miss = ~((depth <= max_range) & (depth > 0))    # NaN and inf (no hit) compare False
        depth[miss] = 0
        return Hits(K=K, R_wc=R_wc, c_world=c_world, depth=depth.reshape(H, W), miss=miss,
                    geometry=ans["geometry_ids"].numpy().reshape(-1),
                    primitive=ans["primitive_ids"].numpy().reshape(-1))

    def shade(self, hits: Hits) -> Rendering:
        """Labels, colour, incidence and normals of a ray cast (``cast``) of this scene."""
        K, R_wc, c_world = hits.K, hits.R_wc, hits.c_world
        H, W = K.height, K.width
        _, inv_length = _pixel_rays(K)
        depth, miss, gid, prim = hits.depth.reshape(-1), hits.miss, hits.geometry, hits.primitive
        # Per triangle, for this camera: the plane's signed distance from the camera centre
        # (n . c - h; the camera sees the side the normal points to when it is positive), the
        # normal turned to face the camera, and the shade without the view-dependent term.
        dist = self._tri_normals @ c_world - self._tri_offsets
        facing = np.where(dist < 0, -1.0, 1.0)[:, None] * self._tri_normals
        facing[self._no_hit] = 0
        lit = np.clip(facing @ LIGHT_WORLD, 0, 1)
        shade0 = (0.85 * (1 - AMBIENT) * lit + 0.85 * AMBIENT).astype(np.float32)
        shade0[self._no_hit] = 0
        # A ray along d (z = 1) meets the plane at depth t with n . d = -dist / t, so the cosine
        # between ray and normal is |dist| / (t |d|).
        abs_dist = np.abs(dist).astype(np.float32)
        # Per triangle, colour and shade in one row of four float32 (16 bytes: numpy gathers
        # rows of that size in one step), so that a pixel's are gathered at once.
        colour_shade = np.empty((len(shade0), 4), dtype=np.float32)
        colour_shade[:, :3] = self._tri_palette.T
        colour_shade[:, 3] = shade0
        N = H * W
        tri = np.empty(N, dtype=np.uint32)
        labels = np.empty(N, dtype=np.int32)
        incidence = np.empty(N, dtype=np.float32)
        color = np.empty((N, 3), dtype=np.uint8)

        def shade(rows: slice) -> None:
            if rows.stop <= rows.start:                 # (an empty band: OpenCV refuses it)
                return
            d, m = depth[rows], miss[rows]
            t = np.take(self._first, gid[rows], mode="clip", out=tri[rows])
            t += prim[rows]                             # a miss wraps around: reset next
            np.copyto(t, self._no_hit, where=m)
            # As numpy's index type once: np.take converts any other on every call.
            t = t.astype(np.intp)
            # mode="clip" (the indices are all in range): with the default, take buffers
            # whatever it writes into ``out``.
            np.take(self._tri_labels, t, out=labels[rows], mode="clip")
            inc = np.take(abs_dist, t, out=incidence[rows], mode="clip")
            inv_t = np.divide(inv_length[rows], d, where=~m, out=np.zeros(len(d), np.float32))
            inc *= inv_t
            np.minimum(inc, 1, out=inc)
            # A little view-dependent light (0.15 incidence) so faces parallel to the light differ.
            rgbs = np.take(colour_shade, t, axis=0)     # label -1: the trailing black
            s = np.float32(0.15) * inc
            s += rgbs[:, 3]
            planes = []
            for ch in range(3):
                c = np.multiply(rgbs[:, ch], s)
                np.minimum(c, 255, out=c)
                planes.append(c.astype(np.uint8))
            # Interleaved by OpenCV: numpy's strided stores into one channel cost more.
            color[rows] = cv2.merge(planes).reshape(-1, 3)

        # Row bands in threads: numpy releases the GIL on these array operations, so the
        # per-pixel shading runs on every core like the ray casting does.
        in_bands([slice(b.start * W, b.stop * W) for b in row_bands(H)], shade)
        normals = np.vstack([(facing[:-1] @ R_wc).astype(np.float32), np.zeros((1, 3), np.float32)])
        return Rendering(depth=hits.depth, color=color.reshape(H, W, 3),
                         labels=labels.reshape(H, W), nodes=self.nodes, owners=self.owners,
                         names=self.names, materials=self.materials,
                         incidence=incidence.reshape(H, W), triangle=tri.reshape(H, W),
                         triangle_normals_camera=normals)


@dataclass
class Hits:
    """A ray cast of one view (``Scene.cast``): ``depth`` (H, W) float32 in metres along the
    optical axis, 0 where ``miss`` (H*W bools: nothing hit within the range); open3d's
    per-ray ``geometry`` and ``primitive`` ids (H*W); the camera and its pose."""
    K: Intrinsics
    R_wc: np.ndarray
    c_world: np.ndarray
    depth: np.ndarray
    miss: np.ndarray
    geometry: np.ndarray
    primitive: np.ndarray


_MALLOC_TUNED = False
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3      # glibc's mallopt parameters (malloc.h)


def _keep_freed_memory() -> None:
    """Have glibc's malloc keep up to 128 MB of freed memory for reuse, and serve blocks up to
    32 MB from it, instead of handing frame-sized blocks back to the kernel after every frame.

    A 640x480 frame frees some 15 MB at once (open3d's ray-cast outputs, the rays, numpy's
    temporaries), more than glibc's adaptive trim threshold (twice the largest block freed so
    far), so each frame took ~3,500 fresh pages from the kernel: page faults and zeroing,
    ~10 ms of CPU a frame (15 %, measured). Process-wide, once, when the first scene is
    built; nothing where malloc is not glibc's or where the user has set these thresholds
    (MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_ or GLIBC_TUNABLES)."""
    global _MALLOC_TUNED
    if _MALLOC_TUNED:
        return
    _MALLOC_TUNED = True
    if not sys.platform.startswith("linux") or any(
            k in os.environ for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_",
                                      "GLIBC_TUNABLES")):
        return
    try:
        libc = ctypes.CDLL(None)
        if not hasattr(libc, "gnu_get_libc_version"):     # not glibc (musl: another malloc)
            return
        libc.mallopt(_M_MMAP_THRESHOLD, 32 << 20)
        libc.mallopt(_M_TRIM_THRESHOLD, 128 << 20)
    except (OSError, AttributeError):
        return


_RAYS_CACHE: dict = {}


def _pixel_rays(K: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame ray directions with z = 1 through every pixel centre (integer pixel
    coordinates, camera.py's convention), (H, W, 3) float32, and the inverse of their lengths,
    (H*W,) float32. Cached per intrinsics: they do not depend on the pose."""
    key = (K.fx, K.fy, K.cx, K.cy, K.width, K.height)
    hit = _RAYS_CACHE.get(key)
    if hit is None:
        u, v = np.meshgrid(np.arange(K.width, dtype=np.float64),
                           np.arange(K.height, dtype=np.float64))
        d = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u)], axis=-1)
        hit = (d.astype(np.float32), (1.0 / np.linalg.norm(d, axis=-1)).reshape(-1).astype(np.float32))
        if len(_RAYS_CACHE) > 16:
            _RAYS_CACHE.clear()
        _RAYS_CACHE[key] = hit
    return hit


def render(meshes, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
    """Build a scene from labelled meshes and render one view (see ``Scene`` to reuse one)."""
    return Scene(meshes).render(K, T_world_camera, max_range)
