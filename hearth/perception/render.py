"""Rendering labelled meshes into depth, colour, normals and node labels by ray casting.

open3d's ``RaycastingScene`` (Embree) does the ray casting; this module adds what it has no
notion of: per-mesh colours and node labels, and simple Lambertian shading. Pure: meshes in,
arrays out (the one side effect: building the first scene tunes glibc's malloc for
frame-sized arrays, see ``_keep_freed_memory``). The simulated robot adds sensor noise on
top (hearth/robot/noise.py), drawing it while ``Scene.cast`` and ``Scene.shade`` run.

For images of ``ADAPTIVE_MIN_PIXELS`` (150,000) and more, ``Scene.cast`` casts rays on a
coarse grid and fills the blocks whose corners hit one triangle, and that no outline corner,
narrow piece or coplanar overlap reaches, from that triangle's plane (``_AdaptiveCast``): the
same triangle ids and misses as a ray per pixel on every view checked, depth within float
rounding; ``adaptive=False`` casts every pixel.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import sys
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import cv2
import numpy as np
import open3d as o3d

from hearth.perception import kernels
from hearth.perception.bands import in_bands, pool, row_bands
from hearth.perception.camera import Intrinsics

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
    """A ray-casting scene built once from labelled meshes (see hearth.worldmodel.geometry).

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
        spans = {}                       # geometry id -> its number of triangles
        count = 0
        self._outline_src = []           # what the adaptive cast needs (``_outline``)
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
            self._outline_src.append((v, t, n, offsets[-1], count))
            first[gid] = count
            spans[gid] = len(t)
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
        # Scene triangle -> open3d's geometry and primitive id (the last row: a miss).
        self._tri_gid = np.full(count + 1, _NO_HIT, dtype=np.uint32)
        self._tri_prim = np.full(count + 1, _NO_HIT, dtype=np.uint32)
        for gid, f in first.items():
            n_t = spans[gid]
            self._tri_gid[f:f + n_t] = gid
            self._tri_prim[f:f + n_t] = np.arange(n_t, dtype=np.uint32)
        #: Cast a coarse grid of rays and fill what provably hits one triangle (``cast``);
        #: False: a ray through every pixel (the reference).
        self.adaptive = ADAPTIVE

    @cached_property
    def _outline(self) -> "_Outline":
        """The meshes' outline for the adaptive cast, made when first needed."""
        outline = _Outline()
        for src in self._outline_src:
            outline.add(*src)
        return outline.done()

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
        """Render the view of camera ``K`` at ``T_world_camera``."""
        return self.shade(self.cast(K, T_world_camera, max_range))

    def cast(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0,
             adaptive: bool | None = None, when_coarse=None) -> Hits:
        """The ray cast of a view (depth final: 0 where nothing was hit within ``max_range``),
        before shading: ``shade`` makes it a ``Rendering``. Split so that work that needs only
        the depth (the simulated sensor's noise draws) can run while the shading does.

        ``adaptive`` (default: the scene's ``adaptive``, module constant ``ADAPTIVE``): cast a
        coarse grid of rays and fill the pixels of a block whose corners hit one triangle by
        intersecting their rays with that triangle's plane (see ``_AdaptiveCast``): the same
        triangle ids as a ray per pixel, depth within float rounding. False: a ray per pixel.

        ``when_coarse``, if given, is called (no arguments, on this thread) once the adaptive
        cast has cast its coarsest rays, from where on it leaves a core idle for a while; the
        simulated robot starts its noise's random draws there. A cast of a ray per pixel
        calls it first."""
        H, W = K.height, K.width
        T = np.asarray(T_world_camera, dtype=np.float64)
        R_wc, c_world = T[:3, :3], T[:3, 3]
        if adaptive is None:
            adaptive = self.adaptive and H * W >= ADAPTIVE_MIN_PIXELS
        if adaptive and min(H, W) >= 2:
            depth, tri = _AdaptiveCast(self, K, R_wc, c_world, max_range, when_coarse).run()
            miss = ~((depth <= max_range) & (depth > 0))
            depth[miss] = 0
            return Hits(K=K, R_wc=R_wc, c_world=c_world, depth=depth.reshape(H, W), miss=miss,
                        triangle=tri, tables=(self._tri_gid, self._tri_prim))
        if when_coarse is not None:
            when_coarse()
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
        gid = ans["geometry_ids"].numpy().reshape(-1)
        prim = ans["primitive_ids"].numpy().reshape(-1)
        tri = np.take(self._first, gid, mode="clip")
        tri += prim                                     # a miss wraps around: reset next
        np.copyto(tri, np.uint32(self._no_hit), where=gid == _NO_HIT)
        return Hits(K=K, R_wc=R_wc, c_world=c_world, depth=depth.reshape(H, W), miss=miss,
                    triangle=tri, tables=(self._tri_gid, self._tri_prim), _geometry=gid,
                    _primitive=prim)

    def shade(self, hits: Hits, after=None) -> Rendering:
        """Labels, colour, incidence and normals of a ray cast (``cast``) of this scene.

        ``after(rows, labels, incidence, color)``, if given, is called in the shading's own
        thread as soon as each band of image rows is shaded, with the image-shaped arrays
        (only ``rows`` of them final then): the simulated sensor applies its noise there
        (hearth.robot.noise.NoiseBands)."""
        K, R_wc, c_world = hits.K, hits.R_wc, hits.c_world
        H, W = K.height, K.width
        _, inv_length = _pixel_rays(K)
        depth, miss, triangle = hits.depth.reshape(-1), hits.miss, hits.triangle
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
        labels2, incidence2 = labels.reshape(H, W), incidence.reshape(H, W)
        color2 = color.reshape(H, W, 3)

        def shade(rows: slice) -> None:
            if rows.stop <= rows.start:
                return
            # One compiled pass per pixel (hearth.perception.kernels.shade; the numpy passes it
            # replaced, operation for operation, are in tests/robot/test_noise_kernels.py).
            kernels.shade(depth[rows], miss[rows], triangle[rows], inv_length[rows],
                          np.uint32(self._no_hit), self._tri_labels, abs_dist, colour_shade,
                          np.float32(0.15), tri[rows], labels[rows], incidence[rows], color[rows])
            if after is not None:
                after(slice(rows.start // W, rows.stop // W), labels2, incidence2, color2)

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
    optical axis, 0 where ``miss`` (H*W bools: nothing hit within the range); ``triangle``
    (H*W uint32): the scene's triangle each ray hit (its number of triangles where nothing
    was hit; the triangle hit beyond the range where that was); open3d's per-ray
    ``geometry`` and ``primitive`` ids (H*W, uint32, 0xFFFFFFFF where nothing was hit); the
    camera and its pose."""
    K: Intrinsics
    R_wc: np.ndarray
    c_world: np.ndarray
    depth: np.ndarray
    miss: np.ndarray
    triangle: np.ndarray
    tables: tuple            # (geometry id, primitive id) per scene triangle, last row a miss
    _geometry: np.ndarray | None = None
    _primitive: np.ndarray | None = None

    @property
    def geometry(self) -> np.ndarray:
        if self._geometry is None:
            self._geometry = np.take(self.tables[0], self.triangle)
        return self._geometry

    @property
    def primitive(self) -> np.ndarray:
        if self._primitive is None:
            self._primitive = np.take(self.tables[1], self.triangle)
        return self._primitive


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


# -- adaptive ray casting ------------------------------------------------------------------

#: Scenes cast adaptively (``Scene.cast``) unless told otherwise; False: a ray per pixel.
ADAPTIVE = True
#: Smaller images are cast a ray per pixel unless asked (``Scene.cast(adaptive=True)``): the
#: adaptive cast's fixed cost per view (~3 ms) is more than it saves there (320x240: 9 ms).
ADAPTIVE_MIN_PIXELS = 150_000
#: The coarsest block of the adaptive cast (pixels; halved down to 2, then every pixel).
COARSE_BLOCK = 4
#: A mesh whose projection may be narrower than this many coarsest blocks anywhere is cast
#: at every pixel of its projected bounding box.
THIN_BLOCKS = 2.5
_NEAR = 0.02                    # metres: vertices nearer the camera plane are not projected
_UNSET = np.uint32(0xFFFFFFFE)   # a block not filled (no triangle has this index)
_MIN_ANGLE = np.radians(3.0)    # the sharpest silhouette corner assumed (and for odd ones)
_DIRECTIONS = np.linspace(0, np.pi, 64, endpoint=False)


class _Outline:
    """What the adaptive cast needs of a scene's meshes, collected while it is built: the
    meshes' vertices (merged where they coincide), their edges with the one or two triangles
    on either side, and per mesh an oriented bounding box (principal axes) and whether the
    mesh is convex."""

    def __init__(self):
        self.verts, self.edges, self.edge_faces, self.vert_mesh = [], [], [], []
        self.corners, self.convex, self.n_verts = [], [], 0
        self.middle = []                         # per mesh: its middle extent (m)
        self.outward = []                        # convex, closed, normals pointing out
        self.keys = []                           # per piece: (its mesh's digest, number)
        self._meshes = []                        # (vertices, edges, edge faces, normals, offsets, triangles)

    def add(self, v: np.ndarray, t: np.ndarray, n: np.ndarray, h: np.ndarray, first: int):
        """A mesh (vertices, triangles, their unit normals and plane offsets; its first
        triangle's index in the scene), kept as its connected pieces (a table's legs are
        one mesh of four boxes: each is a piece). The pieces of a mesh are cached by its
        vertices and triangles: a scene rebuilt after a door moved redoes only the door's."""
        key = hashlib.blake2b(v.tobytes() + b"|" + t.tobytes(), digest_size=16).digest()
        parts = _PARTS_CACHE.get(key)
        if parts is None:
            parts = _mesh_parts(v, t, n, h)
            if len(_PARTS_CACHE) > 8192:
                _PARTS_CACHE.clear()
            _PARTS_CACHE[key] = parts
        for part, (uv, edges, ef, sel, pn, ph, tu, corners, middle, convex, outward) in \
                enumerate(parts):
            self.keys.append((key, part))
            self.edges.append(edges + self.n_verts)
            self.edge_faces.append(np.where(ef >= 0, first + sel[np.maximum(ef, 0)], -1))
            self.verts.append(uv)
            self.vert_mesh.append(np.full(len(uv), len(self.corners)))
            self.n_verts += len(uv)
            self.corners.append(corners)
            self.middle.append(middle)
            self.convex.append(convex)
            self.outward.append(outward)
            self._meshes.append((uv, edges, ef, pn, ph, tu))

    def done(self) -> "_Outline":
        self.verts = np.vstack(self.verts) if self.verts else np.zeros((0, 3))
        self.edges = np.vstack(self.edges) if self.edges else np.zeros((0, 2), np.int64)
        self.edge_faces = (np.vstack(self.edge_faces) if self.edge_faces
                           else np.zeros((0, 2), np.int64))
        self.vert_mesh = np.concatenate(self.vert_mesh) if self.vert_mesh else np.zeros(0, int)
        self.corners = np.asarray(self.corners).reshape(-1, 8, 3)
        self.convex = np.asarray(self.convex, dtype=bool)
        self.middle = np.asarray(self.middle, dtype=float)
        self._pierce()
        del self._meshes
        return self

    def _pierce(self) -> None:
        """Where the pieces overlap (the boards of a cupboard do), the outline of what is in
        front has corners that are no vertex, and triangles of two pieces can lie in one
        plane. Kept: ``pierce``, the points where an edge of one piece passes through a
        triangle of another, with ``pierce_dirs``, the edge's direction and the directions of
        the lines where the edge's two triangles meet the other's plane; ``shared``, the
        overlaps of two triangles in one plane (convex polygons, each as 8 points: see
        ``_overlaps``), with their plane (``shared_plane``: n, h; n = 0 where either piece
        is not closed and convex)."""
        parts = self._meshes
        nv = np.array([len(p[0]) for p in parts])
        ne = np.array([len(p[1]) for p in parts])
        nt = np.array([len(p[3]) for p in parts])
        v0, e0, t0 = (np.r_[0, np.cumsum(x)[:-1]] for x in (nv, ne, nt))
        V = np.vstack([p[0] for p in parts]).reshape(-1, 3)
        E = np.vstack([p[1] + o for p, o in zip(parts, v0)]).reshape(-1, 2)
        EF = np.vstack([np.where(p[2] >= 0, p[2] + o, -1) for p, o in zip(parts, t0)]).reshape(-1, 2)
        N = np.vstack([p[3] for p in parts]).reshape(-1, 3)
        Hh = np.concatenate([p[4] for p in parts])
        TV = np.vstack([p[5] + o for p, o in zip(parts, v0)]).reshape(-1, 3)
        outward = np.asarray(self.outward, dtype=bool)
        lo = np.array([p[0].min(axis=0) for p in parts]).reshape(-1, 3)
        hi = np.array([p[0].max(axis=0) for p in parts]).reshape(-1, 3)
        eps = 1e-9
        over = np.all((lo[:, None] <= hi[None] + eps) & (lo[None] <= hi[:, None] + eps), axis=2)
        np.fill_diagonal(over, False)
        I, J = np.nonzero(over)
        # What a pair of pieces gives is cached by their contents: a scene rebuilt after a
        # door moved computes only the pairs with the door's pieces.
        pair_keys = [(self.keys[i], self.keys[j]) for i, j in zip(I, J)]
        new = np.array([k not in _PAIR_CACHE for k in pair_keys], dtype=bool)
        first = np.array([ka <= kb for ka, kb in pair_keys], dtype=bool)

        def pairs(ca, sa, cb, sb):
            """Every (a of piece I, b of piece J) of the new overlapping pairs, and the
            pair's index."""
            keep = np.flatnonzero(new)
            i, j = I[keep], J[keep]
            n = ca[i] * cb[j]
            k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
            rb = np.repeat(cb[j], n)
            return (np.repeat(sa[i], n) + k // rb, np.repeat(sb[j], n) + k % rb,
                    np.repeat(i, n), np.repeat(j, n), np.repeat(keep, n))

        # Edges of I through triangles of J.
        ei, ti, _, _, pair = pairs(ne, e0, nt, t0)
        p, q = V[E[ei, 0]], V[E[ei, 1]]
        nj = N[ti]
        sp = np.einsum("ij,ij->i", p, nj) - Hh[ti]
        sq = np.einsum("ij,ij->i", q, nj) - Hh[ti]
        cross = (sp * sq <= 0) & ~((sp == 0) & (sq == 0))
        ei, ti, p, q, sp, sq, nj, pair = (x[cross] for x in (ei, ti, p, q, sp, sq, nj, pair))
        x = p + (sp / (sp - sq))[:, None] * (q - p)
        A, B, C = V[TV[ti, 0]], V[TV[ti, 1]], V[TV[ti, 2]]
        inside = np.ones(len(ei), dtype=bool)
        for P0, P1 in ((A, B), (B, C), (C, A)):       # (edges included, with a margin)
            inside &= np.einsum("ij,ij->i", np.cross(P1 - P0, x - P0), nj) >= -1e-7
        ei, ti, x, p, q, pair = (v[inside] for v in (ei, ti, x, p, q, pair))
        d = q - p
        lines = []
        for k in (0, 1):
            f = EF[ei, k]
            ln = np.cross(N[np.maximum(f, 0)], N[ti])
            lines.append(np.where((f >= 0)[:, None], ln, d))
        pierce = x.reshape(-1, 3)
        pierce_dirs = np.stack([d, lines[0], lines[1]], axis=1).reshape(-1, 3, 3)
        pierce_pair = pair
        # Triangles of two pieces in one plane that overlap: which of them a ray there hits
        # is down to rounding, so where they overlap is cast at every pixel. (Facing opposite
        # ways, as a plinth on the floor, two closed pieces whose normals point out hide each
        # other's triangles there.)
        a, b, i, j, pair = pairs(nt, t0, nt, t0)
        closed = outward[i] & outward[j]
        dots = np.einsum("ij,ij->i", N[a], N[b])
        same = np.where(closed, dots > 1 - 1e-9, np.abs(dots) > 1 - 1e-9)
        same &= np.abs(Hh[a] - np.sign(dots) * Hh[b]) < 1e-7
        # (Each overlap once: from the pair whose first piece comes first by content, as the
        # cache's keys are, not by place in this scene.)
        same &= first[pair]
        a, b, closed, pair = a[same], b[same], closed[same], pair[same]
        # Where the two triangles overlap: their intersection, a convex polygon in their
        # plane. (Its world-axis box, used before, covers much more than the overlap when
        # the plane is turned: on a cooker standing at 45 degrees the box of its hob's
        # overlap with the body's top spread over half the view, every pixel cast.)
        poly, keep = _overlaps(V[TV[a]], V[TV[b]], N[a])
        a, closed, pair = a[keep], closed[keep], pair[keep]
        plane = np.hstack([N[a] * closed[:, None], np.where(closed, Hh[a], -1.0)[:, None]])
        shared_pair = pair
        # Into the cache per pair, then every overlapping pair's from it.
        if len(_PAIR_CACHE) > 200_000:
            _PAIR_CACHE.clear()
        po, so = np.argsort(pierce_pair, kind="stable"), np.argsort(shared_pair, kind="stable")
        pp, sp_ = pierce_pair[po], shared_pair[so]
        box_rows = np.hstack([poly.reshape(-1, 24), plane])[so]
        prow = np.hstack([pierce, pierce_dirs.reshape(-1, 9)])[po]
        for k in np.flatnonzero(new):
            _PAIR_CACHE[pair_keys[k]] = (
                prow[np.searchsorted(pp, k):np.searchsorted(pp, k, side="right")],
                box_rows[np.searchsorted(sp_, k):np.searchsorted(sp_, k, side="right")])
        got = [_PAIR_CACHE[k] for k in pair_keys]
        prow = np.vstack([g[0] for g in got] + [np.zeros((0, 12))])
        box_rows = np.vstack([g[1] for g in got] + [np.zeros((0, 28))])
        self.pierce, self.pierce_dirs = prow[:, :3], prow[:, 3:].reshape(-1, 3, 3)
        if len(self.pierce):            # (an edge through two triangles' common edge: once)
            _, keep = np.unique(np.round(prow, 9), axis=0, return_index=True)
            keep = np.sort(keep)
            self.pierce, self.pierce_dirs = self.pierce[keep], self.pierce_dirs[keep]
        if len(box_rows):               # (the same overlap found from both pieces: once)
            _, keep = np.unique(np.round(box_rows[:, :24], 9), axis=0, return_index=True)
            box_rows = box_rows[np.sort(keep)]
        # The overlaps' polygons, each as 8 points for ``_AdaptiveCast._project_boxes`` (see
        # ``_overlaps``), and their plane (n . x = h, n pointing out of both pieces where
        # they are closed; 0 and -1 elsewhere: seen from either side).
        self.shared = box_rows[:, :24].reshape(-1, 8, 3)
        self.shared_plane = box_rows[:, 24:].reshape(-1, 4)


# Box corners in the order of a cycle along the box's edges (a Gray code: 000, 001, 011,
# 010, 110, 111, 101, 100): a polygon's vertices put there in turn (the last repeated) have
# every polygon edge among the box's 12 edges, as ``_AdaptiveCast._project_boxes`` clips them.
_CYCLE = np.array([0, 1, 3, 2, 6, 7, 5, 4])


def _overlaps(ta: np.ndarray, tb: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where triangles ``ta`` and ``tb`` (each (m, 3, 3)) that lie in one plane (normal
    ``n``) overlap: the convex polygon of their intersection, as 8 points (``_CYCLE``), and
    which pairs overlap in an area (not only along an edge or at a point). OpenCV's
    ``intersectConvexConvex`` clips in float32, in plane coordinates about the first
    triangle's first vertex (metres: a few 1e-7 m of error, far below the 2 pixels
    ``_AdaptiveCast._paint`` adds); an overlap thinner than 1e-6 m is taken as an edge."""
    out = np.zeros((len(ta), 8, 3))
    keep = np.zeros(len(ta), dtype=bool)
    if not len(ta):
        return out, keep
    o = ta[:, 0]
    e1 = ta[:, 1] - o
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    basis = np.stack([e1, e2], axis=2)                               # (m, 3, 2)
    pa = np.einsum("mkj,mjd->mkd", ta - o[:, None], basis).astype(np.float32)
    pb = np.einsum("mkj,mjd->mkd", tb - o[:, None], basis).astype(np.float32)
    for i in range(len(ta)):
        area, poly = cv2.intersectConvexConvex(pa[i], pb[i])
        if poly is None or area <= 0:
            continue
        q = poly.reshape(-1, 2).astype(np.float64)
        if not np.all(np.abs(q) < 1e6):              # (a degenerate answer: a huge sentinel)
            continue
        ext = np.ptp(q, axis=0)
        if area / max(float(np.hypot(*ext)), 1e-12) <= 1e-6 or len(q) > 8:
            continue
        pts = o[i] + q @ basis[i].T
        out[i, _CYCLE] = pts[np.minimum(np.arange(8), len(q) - 1)]
        keep[i] = True
    return out[keep], keep


_PARTS_CACHE: dict = {}
_PAIR_CACHE: dict = {}
_BOX = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)


def _mesh_parts(v: np.ndarray, t: np.ndarray, n: np.ndarray, h: np.ndarray) -> list:
    """A mesh's connected pieces, each: merged vertices, edges (a < b) with the triangles on
    either side (indices into the piece's triangles; -1 for none: an edge of an open mesh,
    or of more than two triangles, is a silhouette edge from every side), the piece's
    triangles in the mesh, their normals and offsets and vertex indices, the corners of its
    oriented bounding box (principal axes), its middle extent, whether it is convex and
    closed, and whether its normals then point out."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    def pieces(tri: np.ndarray, n_v: int) -> tuple[int, np.ndarray]:
        a = np.concatenate([tri[:, 0], tri[:, 1]])
        b = np.concatenate([tri[:, 1], tri[:, 2]])
        k, comp = connected_components(coo_matrix((np.ones(len(a)), (a, b)),
                                                  shape=(n_v, n_v)), directed=False)
        return k, comp[tri[:, 0]]

    # Pieces by the mesh's own vertex indices (boxes put together into one mesh, such as a
    # door's panel and frame, touch but are pieces of their own), unless that falls apart
    # into loose triangles (a mesh file without shared vertices): then by position.
    k, tri_comp = pieces(t, len(v))
    if k > max(1, len(t) // 4):
        _, inv = np.unique(np.round(v, 9), axis=0, return_inverse=True)
        k, tri_comp = pieces(inv.reshape(-1)[t], len(v))
    out = []
    for c in range(k):
        sel = np.flatnonzero(tri_comp == c)
        if len(sel) == 0:
            continue
        uv, local = np.unique(np.round(v[t[sel]].reshape(-1, 3), 9), axis=0,
                              return_inverse=True)
        tu = local.reshape(-1, 3)
        pn, ph = n[sel], h[sel]
        a = np.concatenate([tu[:, 0], tu[:, 1], tu[:, 2]])
        b = np.concatenate([tu[:, 1], tu[:, 2], tu[:, 0]])
        f = np.tile(np.arange(len(tu)), 3)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        key = lo.astype(np.int64) * (len(uv) + 1) + hi
        order = np.argsort(key, kind="stable")
        key, lo, hi, f = key[order], lo[order], hi[order], f[order]
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        counts = np.diff(np.r_[starts, len(key)])
        ef = np.full((len(starts), 2), -1, dtype=np.int64)
        ef[:, 0] = f[starts]
        two = counts == 2
        ef[two, 1] = f[starts[two] + 1]
        ef[counts > 2, 0] = -1
        centre = uv.mean(axis=0)
        _, _, axes = np.linalg.svd(uv - centre, full_matrices=False)
        if len(axes) < 3:                                   # (fewer than 3 vertices)
            axes = np.eye(3)
        p = (uv - centre) @ axes.T
        lo3, hi3 = p.min(axis=0), p.max(axis=0)
        corners = centre + (lo3 + _BOX * (hi3 - lo3)) @ axes
        # Convex and closed: every edge between two triangles and every triangle's plane
        # with all vertices on one side.
        ok = np.linalg.norm(pn, axis=1) > 0
        convex = len(uv) * len(tu) <= 4_000_000 and bool(np.all(counts == 2))
        outward = False
        if convex:
            side = uv @ pn[ok].T - ph[ok]
            tol = 1e-7 * max(1.0, float(np.abs(uv).max()))
            convex = bool(np.all((side.max(axis=0) <= tol) | (side.min(axis=0) >= -tol)))
            outward = convex and bool(np.all(side.max(axis=0) <= tol))
        out.append((uv, np.stack([lo[starts], hi[starts]], axis=1), ef, sel, pn, ph, tu,
                    corners, float(np.sort(hi3 - lo3)[1]), convex, outward))
    return out


def _grid(n: int, s: int) -> np.ndarray:
    """Sample positions every ``s`` pixels and the last pixel."""
    g = np.arange(0, n, s)
    return g if g[-1] == n - 1 else np.r_[g, n - 1]


def _on_grid(a: np.ndarray, s: int) -> np.ndarray:
    """``a[np.ix_(_grid(H, s), _grid(W, s))]`` by slicing (several times cheaper)."""
    H, W = a.shape
    nr, nc = len(range(0, H, s)), len(range(0, W, s))
    er, ec = (H - 1) % s != 0, (W - 1) % s != 0
    out = np.empty((nr + er, nc + ec), dtype=a.dtype)
    out[:nr, :nc] = a[::s, ::s]
    if er:
        out[nr, :nc] = a[-1, ::s]
    if ec:
        out[:nr, nc] = a[::s, -1]
    if er and ec:
        out[nr, nc] = a[-1, -1]
    return out


def _take2(a: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``a[np.ix_(rows, cols)]`` by two np.take (several times cheaper)."""
    return np.take(np.take(a, rows, axis=0), cols, axis=1)


class _AdaptiveCast:
    """One view's adaptive ray cast (``Scene.cast``).

    Rays are cast on a grid every ``COARSE_BLOCK`` pixels. A block of the grid whose four
    corner rays hit the same triangle (or all nothing) is filled: a triangle's projection is
    convex, so every pixel between the corners sees that triangle's plane, unless something
    in front pokes in between the corners. Other blocks are split in two each way (rays on
    the finer grid) down to blocks of 2 pixels, whose remaining pixels are cast. What could
    poke into a block without covering a corner is made to be cast:

    - a corner of an outline: a silhouette vertex (one with a silhouette edge: an edge
      between a triangle facing the camera and one facing away, or an edge of an open mesh),
      or a point where an edge of one piece passes through a triangle of another (pieces
      that overlap, as a cupboard's boards do). The blocks within a radius that grows as the
      corner gets sharper are split at every level (a wedge of angle a is narrower than a
      block of side s out to s / (2 tan(a / 2)) from its tip). A corner behind the triangle
      that the four corners of its coarsest block see is left out (``_unhidden``);
    - anything narrow: a piece (connected part of a mesh) whose projected oriented bounding
      box is less than ``THIN_BLOCKS`` coarsest blocks wide in some direction, or whose
      middle extent is that little at its farthest depth (the tip of something long pointing
      away), and every piece that is not convex, is cast at every pixel of its projected box
      (knob markers, handles, boards seen edge-on, small objects);
    - where triangles of two pieces lie in one plane and overlap (which of them a ray hits
      there is down to rounding): cast at every pixel.

    Filled pixels get the triangle of their block and the depth where their ray meets that
    triangle's plane (float64, rounded to float32: a few float32 steps from Embree's, more
    at grazing incidence where Embree's own rounding grows). Tested against a ray per pixel
    in tests/robot/test_render_adaptive.py; see docs/robot-adapter.md, "Speed"."""

    def __init__(self, scene: "Scene", K: Intrinsics, R_wc: np.ndarray, c_world: np.ndarray,
                 max_range: float, when_coarse=None):
        self.scene, self.K, self.R, self.c, self.max_range = scene, K, R_wc, c_world, max_range
        self.when_coarse = when_coarse
        H, W = K.height, K.width
        self.H, self.W = H, W
        self.rays, _ = _pixel_rays(K)
        self.flat_dirs = self.rays.reshape(-1, 3)
        self.origin = np.zeros((3, 4), dtype=np.float32)
        self.origin[:, 3] = c_world
        self.Rf = R_wc.astype(np.float32)
        self.depth = np.empty(H * W, dtype=np.float32)
        self.tri = np.empty(H * W, dtype=np.uint32)
        self.known = np.zeros(H * W, dtype=bool)
        self.rays_cast = 0

    def _cast(self, idx: np.ndarray) -> None:
        if len(idx) == 0:
            return
        # np.take along an axis gathers the rows several times faster than indexing does.
        d = np.take(self.flat_dirs, idx, axis=0).reshape(-1, 1, 3)
        # As a ray per pixel (``Scene.cast``): the origin by cv2.transform of the directions by
        # [0 | c] (the camera centre in float32), the directions rotated into the world by
        # OpenCV, the two interleaved by cv2.merge (twice as fast as numpy's strided writes).
        rays = cv2.merge([cv2.transform(d, self.origin), cv2.transform(d, self.Rf)]).reshape(-1, 6)
        ans = self.scene._scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        kernels.put_hits(idx, ans["geometry_ids"].numpy(), ans["primitive_ids"].numpy(),
                         ans["t_hit"].numpy(), self.scene._first, np.uint32(self.scene._no_hit),
                         np.uint32(_NO_HIT), self.depth, self.tri, self.known)
        self.rays_cast += len(idx)

    def _project_boxes(self, Cc: np.ndarray):
        """Pixel coordinates (u, v: (N, 20)) of boxes given by their 8 corners in the camera
        frame (N, 8, 3), clipped at the plane z = _NEAR (the corners in front and the points
        where an edge crosses that plane; repeats stand in for the others), the depths of
        those points, and which boxes reach in front of the plane at all."""
        e0 = np.array([0, 0, 0, 1, 1, 2, 2, 3, 4, 4, 5, 6])
        e1 = np.array([1, 2, 4, 3, 5, 3, 6, 7, 5, 6, 7, 7])
        z = Cc[..., 2]
        P, Q = Cc[:, e0], Cc[:, e1]
        zp, zq = P[..., 2], Q[..., 2]
        crosses = (zp - _NEAR) * (zq - _NEAR) < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(crosses, (_NEAR - zp) / (zq - zp), 0.0)
        X = P + t[..., None] * (Q - P)
        pts = np.concatenate([Cc, X], axis=1)                         # (N, 20, 3)
        ok = np.concatenate([z >= _NEAR, crosses], axis=1)
        seen = ok.any(axis=1)
        stand = pts[np.arange(len(pts)), np.argmax(ok, axis=1)]
        pts = np.where(ok[..., None], pts, stand[:, None])
        zc = np.maximum(pts[..., 2], _NEAR)
        u = self.K.fx * pts[..., 0] / zc + self.K.cx
        v = self.K.fy * pts[..., 1] / zc + self.K.cy
        return u, v, zc, seen

    def _paint(self, mask: np.ndarray, u, v, which) -> None:
        """Mark in ``mask`` (H, W uint8) the convex hull of each chosen point set and every
        pixel within 2 pixels of it."""
        u, v = u[which], v[which]
        inside = ((u.max(axis=1) >= -3) & (u.min(axis=1) <= self.W + 2)
                  & (v.max(axis=1) >= -3) & (v.min(axis=1) <= self.H + 2))
        if not inside.any():
            return
        centre = np.array([self.W / 2.0, self.H / 2.0])
        p = np.stack([u[inside], v[inside]], axis=-1) - centre
        # Far points (clipped at the camera plane) pulled in along their direction.
        r = np.sqrt(np.einsum("...i,...i->...", p, p))[..., None]
        p = p * np.minimum(1.0, 1e5 / np.maximum(r, 1e-9)) + centre
        for q in np.round(p * 16).astype(np.int32):
            hull = cv2.convexHull(q)
            cv2.fillConvexPoly(mask, hull, 1, shift=4)
            cv2.polylines(mask, [hull], True, 1, thickness=5, shift=4)

    def _narrow(self, Cc: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Pixel boxes (r0, r1, c0, c1) of the meshes cast at every pixel, and which: those
        whose projected bounding box (clipped at the camera plane) is narrower than
        ``THIN_BLOCKS`` coarsest blocks in some direction, or whose middle extent is at
        their farthest (the tip of something long pointing away), and those not convex."""
        ol = self.scene._outline
        u, v, zc, seen = self._project_boxes(Cc)
        # The width across each of _DIRECTIONS. A box wholly in front of the camera plane
        # has only its 8 corners (the 12 other points repeat one of them): the same widths
        # from 8 points as from 20, at less than half the cost.
        width = np.empty(len(u))
        front = np.all(Cc[..., 2] >= _NEAR, axis=1)
        cos, sin = np.cos(_DIRECTIONS), np.sin(_DIRECTIONS)
        for sel, k in ((front, 8), (~front, u.shape[1])):
            if sel.any():
                w = np.empty(int(sel.sum()))
                kernels.narrowest_widths(u[sel], v[sel], k, cos, sin, w)
                width[sel] = w
        far = np.minimum(zc.max(axis=1), self.max_range)
        thin_px = THIN_BLOCKS * COARSE_BLOCK
        narrow = seen & ((width < thin_px) | (self.K.fx * ol.middle / far < thin_px)
                         | ~ol.convex)
        self._paint(mask, u, v, narrow)
        return narrow

    def _corners(self, narrow: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Silhouette vertices in the image: pixel coordinates and the angle of the outline
        there (``_MIN_ANGLE`` where it is not one clear corner)."""
        K, ol, sc = self.K, self.scene._outline, self.scene
        dist = sc._tri_normals[:-1] @ self.c - sc._tri_offsets[:-1]
        front = dist > 0
        flat = np.abs(dist) < 1e-9
        f0, f1 = ol.edge_faces[:, 0], ol.edge_faces[:, 1]
        one = (f0 < 0) | (f1 < 0)
        g0, g1 = np.maximum(f0, 0), np.maximum(f1, 0)
        sil = one | (front[g0] != front[g1]) | flat[g0] | flat[g1]
        e = ol.edges[sil]
        A = np.concatenate([e[:, 0], e[:, 1]])
        B = np.concatenate([e[:, 1], e[:, 0]])
        Vc = (ol.verts - self.c) @ self.R
        a, b = Vc[A], Vc[B]
        keep = (a[:, 2] >= _NEAR) & ~narrow[ol.vert_mesh[A]]
        A, a, b = A[keep], a[keep], b[keep]
        d = b - a
        du = K.fx * (d[:, 0] * a[:, 2] - a[:, 0] * d[:, 2])
        dv = K.fy * (d[:, 1] * a[:, 2] - a[:, 1] * d[:, 2])
        theta = np.arctan2(dv, du)
        bad = np.hypot(du, dv) <= 1e-12 * (np.abs(du) + np.abs(dv) + 1.0)
        order = np.argsort(A, kind="stable")
        A, theta, bad, a = A[order], theta[order], bad[order], a[order]
        starts = np.flatnonzero(np.r_[True, A[1:] != A[:-1]]) if len(A) else np.zeros(0, int)
        counts = np.diff(np.r_[starts, len(A)])
        angle = np.full(len(starts), _MIN_ANGLE)
        two = counts == 2
        i0, i1 = starts[two], starts[two] + 1
        gap = np.abs(theta[i0] - theta[i1]) % (2 * np.pi)
        gap = np.minimum(gap, 2 * np.pi - gap)
        ok = ~(bad[i0] | bad[i1])
        angle[two] = np.where(ok, np.maximum(gap, _MIN_ANGLE), _MIN_ANGLE)
        p = a[starts]
        # Only corners whose widest wedge radius reaches the image count; the points where
        # an edge passes through another piece's triangle are many (a cupboard's boards:
        # thousands) and most lie outside the view, so they are picked before their angles
        # are worked out.
        reach = 8.0 * COARSE_BLOCK + 2

        def near(q: np.ndarray):
            u = K.fx * q[:, 0] / q[:, 2] + K.cx
            v = K.fy * q[:, 1] / q[:, 2] + K.cy
            return (u > -reach) & (u < self.W - 1 + reach) & (v > -reach) & (v < self.H - 1 + reach), u, v

        keep, u, v = near(p)
        p, u, v, angle = p[keep], u[keep], v[keep], angle[keep]
        # Where an edge passes through another mesh's triangle: the outline there turns
        # between the edge and the lines where its triangles cut that triangle's plane.
        X = (ol.pierce - self.c) @ self.R
        sel = np.flatnonzero(X[:, 2] >= _NEAR)
        keep, ux, vx = near(X[sel])
        sel, ux, vx = sel[keep], ux[keep], vx[keep]
        X = X[sel]
        # One (3N, 3) product: a stack of N 3x3 products costs ten times more.
        D = (ol.pierce_dirs[sel].reshape(-1, 3) @ self.R).reshape(-1, 3, 3)
        du = K.fx * (D[..., 0] * X[:, None, 2] - X[:, None, 0] * D[..., 2])
        dv = K.fy * (D[..., 1] * X[:, None, 2] - X[:, None, 1] * D[..., 2])
        th = np.arctan2(dv, du)
        small = np.hypot(du, dv) <= 1e-12 * (np.abs(du) + np.abs(dv) + 1.0)
        pa = []
        for k in (1, 2):
            g = np.abs(th[:, 0] - th[:, k]) % np.pi
            g = np.minimum(g, np.pi - g)
            pa.append(np.where(small[:, 0] | small[:, k], _MIN_ANGLE, g))
        pa = np.maximum(np.minimum(pa[0], pa[1]), _MIN_ANGLE)
        return (np.concatenate([u, ux]), np.concatenate([v, vx]),
                np.concatenate([p[:, 2], X[:, 2]]), np.concatenate([angle, pa]))

    def _unhidden(self, u, v, z, angle, uni, c00, s, coef):
        """The outline corners not hidden: a corner whose pixel lies in a block of side
        ``s`` whose four corners see one triangle, behind that triangle's plane there, is
        inside the outline of what is in front of it, so no corner of anything's outline
        (where its own pieces cross that triangle, the crossing points are corners too)."""
        nr, nc = uni.shape
        bi = np.floor(v / s).astype(np.int64)
        bj = np.floor(u / s).astype(np.int64)
        inside = (u >= 0) & (v >= 0) & (bi < nr) & (bj < nc)
        bi, bj = np.clip(bi, 0, nr - 1), np.clip(bj, 0, nc - 1)
        t = c00[bi, bj]
        co = coef[np.minimum(t, np.uint32(self.scene._no_hit))]
        x = (u - self.K.cx) / self.K.fx
        y = (v - self.K.cy) / self.K.fy
        inv = co[:, 0] * x + co[:, 1] * y + co[:, 2]         # 1 / depth of that plane there
        hidden = (inside & uni[bi, bj] & (t != self.scene._no_hit)
                  & (inv * (z * (1 - 1e-4) - 1e-4) > 1))
        keep = ~hidden
        return u[keep], v[keep], angle[keep]

    def _split_near(self, u, v, angle, s: int, nr: int, nc: int) -> np.ndarray:
        """Blocks (nr x nc, side ``s``) within the wedge radius of a silhouette vertex."""
        rad = np.minimum(s * (1.0 + 0.5 / np.tan(angle / 2.0)) + 1.5, 8.0 * s)
        r0 = np.floor((v - rad) / s).astype(np.int64)
        r1 = np.floor((v + rad) / s).astype(np.int64)
        c0 = np.floor((u - rad) / s).astype(np.int64)
        c1 = np.floor((u + rad) / s).astype(np.int64)
        ok = (r1 >= 0) & (r0 < nr) & (c1 >= 0) & (c0 < nc)
        r0, r1 = np.clip(r0[ok], 0, nr - 1), np.clip(r1[ok], 0, nr - 1) + 1
        c0, c1 = np.clip(c0[ok], 0, nc - 1), np.clip(c1[ok], 0, nc - 1) + 1
        out = np.zeros((nr, nc), dtype=bool)
        kernels.paint_boxes(r0, r1, c0, c1, out)
        return out

    def _coef(self) -> np.ndarray:
        """Per triangle, 1 / depth = a x + b y + c on its plane for the ray (x, y, 1): with
        n the normal in the camera frame and d = n . c - h, 1/t = -(n . ray)/d."""
        sc = self.scene
        n_cam = sc._tri_normals @ self.R
        dist = sc._tri_normals @ self.c - sc._tri_offsets
        with np.errstate(divide="ignore", invalid="ignore"):
            coef = np.ascontiguousarray(n_cam / -dist[:, None])
        coef[sc._no_hit] = 0                                # no hit: 1/t = 0, t = inf
        return np.nan_to_num(coef, copy=False, posinf=0.0, neginf=0.0)

    def run(self) -> tuple[np.ndarray, np.ndarray]:
        H, W = self.H, self.W
        ol = self.scene._outline
        Cc = (ol.corners.reshape(-1, 3) - self.c) @ self.R
        force = np.zeros((H, W), dtype=np.uint8)
        narrow = self._narrow(Cc.reshape(-1, 8, 3), force)
        if len(ol.shared):
            # Only where the shared plane faces the camera (the other side is inside both).
            facing = ol.shared_plane[:, :3] @ self.c - ol.shared_plane[:, 3] > 0
            u, v, _, seen = self._project_boxes(
                ((ol.shared[facing].reshape(-1, 3) - self.c) @ self.R).reshape(-1, 8, 3))
            self._paint(force, u, v, seen)
        # The outline's corners and the planes' depth coefficients on a pool thread while
        # Embree casts the forced pixels and the coarsest grid (it releases the GIL): none
        # needs the others.
        corners = pool().submit(self._corners, narrow)
        coef = pool().submit(self._coef)
        self._cast(np.flatnonzero(force))
        sc = self.scene
        known2 = self.known.reshape(H, W)
        tri2 = self.tri.reshape(H, W)
        # Per level, per block: the triangle it is filled with (_UNSET: not filled). A grid
        # point in a block filled at a coarser level takes that block's triangle (it lies
        # in the block: the same argument), so only the others are cast.
        blocks, prev = None, None
        s = COARSE_BLOCK
        while s >= 2:
            rows, cols = _grid(H, s), _grid(W, s)
            nr, nc = len(rows) - 1, len(cols) - 1
            G = _on_grid(known2, s)
            if blocks is None:
                need = ~G
            else:
                ps, pr, pc = prev
                inherited = _take2(blocks, np.minimum(rows // ps, pr - 1),
                                   np.minimum(cols // ps, pc - 1))
                need = ~G & (inherited == _UNSET)
            self._cast((rows[:, None] * W + cols[None, :])[need])
            C = _on_grid(tri2, s)
            if blocks is not None:
                C = np.where(G | (inherited == _UNSET), C, inherited)
            c00 = C[:-1, :-1]
            uni = (c00 == C[:-1, 1:]) & (c00 == C[1:, :-1]) & (c00 == C[1:, 1:])
            if blocks is None:
                u, v, z, angle = corners.result()
                coef = coef.result()
                if self.when_coarse is not None:
                    self.when_coarse()
                u, v, angle = self._unhidden(u, v, z, angle, uni, c00, s, coef)
            uni &= ~self._split_near(u, v, angle, s, nr, nc)
            here = np.where(uni, c00, _UNSET)
            if blocks is not None:
                ps, pr, pc = prev
                parent = _take2(blocks, np.minimum(np.arange(nr) * s // ps, pr - 1),
                                np.minimum(np.arange(nc) * s // ps, pc - 1))
                here = np.where(parent != _UNSET, parent, here)
            blocks, prev = here, (s, nr, nc)
            s //= 2
        # Pixels: the triangle of their finest block where it is filled, else a ray.
        ps, pr, pc = prev
        rmap = np.minimum(np.arange(H) // ps, pr - 1)
        cmap = np.minimum(np.arange(W) // ps, pc - 1)
        # The pixels of the blocks not filled (the last row and column of blocks reach to
        # the image's edge) that no ray went through yet, in the order they always had (with
        # open3d 0.20 a ray's depth did not depend on its place in the batch: permuted, split
        # and single-ray casts of three kitchen views gave the same depths bit for bit; but
        # Embree does not promise it).
        self._cast(kernels.unset_block_pixels(blocks, _UNSET, ps, H, W, self.known))
        # Depth of the filled pixels: 1 / depth on their triangle's plane (``coef``), made
        # per band of block rows and per pixel position in the block (a block's pixels share
        # a triangle), and put where no ray went.
        xs = self.rays[0, :, 0].astype(np.float64)
        ys = self.rays[:, 0, 1].astype(np.float64)
        Hr, Wr = pr * ps, pc * ps                   # the image but a last row or column
        depth2 = self.depth.reshape(H, W)
        coef_c = np.ascontiguousarray(coef)
        # One compiled pass over the blocks (hearth.perception.kernels.fill_blocks: the same float64
        # operations in the same order as the numpy passes it replaced, in
        # tests/robot/test_noise_kernels.py), in bands of block rows on the pool's threads.
        in_bands(row_bands(pr), lambda brows: kernels.fill_blocks(
            blocks, brows.start, brows.stop, ps, xs, ys, coef_c, np.uint32(sc._no_hit), _UNSET,
            known2, depth2, tri2))
        # The last row and column where they belong to the blocks before them.
        for rows, cols in ((slice(Hr, H), slice(0, W)), (slice(0, Hr), slice(Wr, W))):
            if rows.stop <= rows.start or cols.stop <= cols.start:
                continue
            f = _take2(blocks, rmap[rows], cmap[cols])
            m = (f != _UNSET) & ~known2[rows, cols]
            c_ = np.take(coef, np.minimum(f, np.uint32(sc._no_hit)), axis=0, mode="clip")
            inv = c_[..., 0] * xs[cols] + c_[..., 1] * ys[rows, None] + c_[..., 2]
            with np.errstate(divide="ignore"):
                np.copyto(depth2[rows, cols], np.divide(1.0, inv).astype(np.float32), where=m)
            np.copyto(tri2[rows, cols], f, where=m)
        return self.depth, self.tri
