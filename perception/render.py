"""Rendering labelled meshes into depth, colour, normals and node labels by ray casting.

open3d's ``RaycastingScene`` (Embree) does the ray casting; this module adds what it has no
notion of: per-mesh colours and node labels, and simple Lambertian shading. Pure: meshes in,
arrays out. The simulated robot adds sensor noise on top (robot/noise.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import open3d as o3d

from perception.bands import pool, row_bands
from perception.camera import Intrinsics

#: Light direction in the world frame (from above, slightly from the side), for shading.
LIGHT_WORLD = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
AMBIENT = 0.45


@dataclass
class Rendering:
    """One rendered view. ``depth`` in metres along the optical axis (0: no surface),
    ``color`` uint8 RGB (H, W, 3), ``labels`` index into ``nodes`` (-1: nothing),
    ``normals_camera`` unit normals in the camera frame, ``incidence`` cos of the angle
    between the ray and the surface normal."""
    depth: np.ndarray
    color: np.ndarray
    labels: np.ndarray
    nodes: list[str]
    owners: list[str]
    names: list[str]
    materials: list[str]
    normals_camera: np.ndarray
    incidence: np.ndarray

    def mask(self, node_ids: Sequence[str]) -> np.ndarray:
        """Pixels that show any of the given nodes."""
        idx = [i for i, n in enumerate(self.nodes) if n in set(node_ids)]
        return np.isin(self.labels, idx)

    def owner_mask(self, owner_ids: Sequence[str]) -> np.ndarray:
        """Pixels that show anything belonging to the given large objects."""
        idx = [i for i, n in enumerate(self.owners) if n in set(owner_ids)]
        return np.isin(self.labels, idx)


class Scene:
    """A ray-casting scene built once from labelled meshes (see worldmodel.geometry)."""

    def __init__(self, meshes):
        self._scene = o3d.t.geometry.RaycastingScene()
        self.nodes: list[str] = []
        self.owners: list[str] = []
        self.names: list[str] = []
        self.materials: list[str] = []
        colors = []
        geom_ids = []
        for lm in meshes:
            if len(lm.mesh.triangles) == 0:
                continue
            gid = self._scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
            geom_ids.append(gid)
            self.nodes.append(lm.node)
            self.owners.append(lm.owner)
            self.names.append(lm.name)
            self.materials.append(lm.material)
            colors.append(lm.color)
        self._colors = np.asarray(colors, dtype=np.float32).reshape(-1, 3)
        # geometry id -> our index (ids are consecutive from 0 in practice; keep a map anyway)
        self._index = np.full(max(geom_ids, default=-1) + 2, -1, dtype=np.int32)
        for i, gid in enumerate(geom_ids):
            self._index[gid] = i

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
        """Render the view of camera ``K`` at ``T_world_camera``."""
        H, W = K.height, K.width
        T = np.asarray(T_world_camera, dtype=np.float64)
        R_wc = T[:3, :3].astype(np.float32)
        dirs_camera, unit_camera = _pixel_rays(K)
        # Rays in float32 (what Embree uses anyway): pixel directions cached per camera, rotated
        # into the world; this is much cheaper than open3d's float64 create_rays_pinhole.
        rays = np.empty((H, W, 6), dtype=np.float32)
        rays[..., :3] = T[:3, 3]
        _rotate(dirs_camera, R_wc.T, out=rays[..., 3:])
        ans = self._scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        # Directions have z = 1 in the camera frame, so t_hit is depth along the optical axis.
        depth = ans["t_hit"].numpy()
        gid = ans["geometry_ids"].numpy()
        n_world = ans["primitive_normals"].numpy()
        labels = np.empty((H, W), dtype=np.int32)
        normals_camera = np.empty((H, W, 3), dtype=np.float32)
        incidence = np.empty((H, W), dtype=np.float32)
        color = np.empty((H, W, 3), dtype=np.uint8)
        light_camera = (R_wc.T @ LIGHT_WORLD.astype(np.float32)).astype(np.float32)
        palette = np.vstack([self._colors, np.zeros((1, 3), np.float32)]) * np.float32(255.0)

        def shade_rows(rows: slice) -> None:
            d = depth[rows]
            hit = (d <= max_range) & (d > 0)        # NaN and inf (no hit) compare False
            miss = ~hit
            d[miss] = 0
            lab = np.take(self._index, gid[rows], mode="clip")   # no hit: the trailing -1
            lab[miss] = -1
            labels[rows] = lab
            # Normals in the camera frame (n_camera = R_cw n_world), turned to face the camera.
            nc = _rotate(n_world[rows], R_wc)
            cos = np.einsum("hwk,hwk->hw", nc, unit_camera[rows])
            nc *= np.where(cos > 0, np.float32(-1), np.float32(1))[..., None]
            nc[miss] = 0
            inc = np.abs(cos)
            inc[miss] = 0
            normals_camera[rows] = nc
            incidence[rows] = inc
            lit = nc[..., 0] * light_camera[0]
            lit += nc[..., 1] * light_camera[1]
            lit += nc[..., 2] * light_camera[2]
            np.clip(lit, 0, 1, out=lit)
            # A little view-dependent light (0.15 incidence) so faces parallel to the light differ.
            shade = (np.float32(0.85 * (1 - AMBIENT)) * lit + np.float32(0.85 * AMBIENT)
                     + np.float32(0.15) * inc)
            c = palette[lab] * shade[..., None]            # label -1: the trailing black
            np.clip(c, 0, 255, out=c)
            color[rows] = c

        # Row bands in threads: numpy releases the GIL on these array operations, so the
        # per-pixel shading runs on every core like the ray casting does.
        bands = row_bands(H)
        list(pool().map(shade_rows, bands))
        return Rendering(depth=depth, color=color, labels=labels,
                         nodes=self.nodes, owners=self.owners, names=self.names,
                         materials=self.materials, normals_camera=normals_camera,
                         incidence=incidence)


def _rotate(v: np.ndarray, M: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``v @ M`` for (..., 3) float32 vectors and a 3x3 ``M``, written as element-wise
    products on purpose: a BLAS matmul from several threads at once (the shading bands) can
    stall badly when BLAS's own threads compete for a busy machine's cores."""
    if out is None:
        out = np.empty(v.shape, dtype=np.float32)
    for j in range(3):
        col = out[..., j]
        np.multiply(v[..., 0], M[0, j], out=col)
        col += v[..., 1] * M[1, j]
        col += v[..., 2] * M[2, j]
    return out


_RAYS_CACHE: dict = {}


def _pixel_rays(K: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) float32 camera-frame ray directions with z = 1 through every pixel centre
    (integer pixel coordinates, camera.py's convention), and the same normalised. Cached per
    intrinsics: they do not depend on the pose."""
    key = (K.fx, K.fy, K.cx, K.cy, K.width, K.height)
    hit = _RAYS_CACHE.get(key)
    if hit is None:
        u, v = np.meshgrid(np.arange(K.width, dtype=np.float64),
                           np.arange(K.height, dtype=np.float64))
        d = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u)], axis=-1)
        unit = d / np.linalg.norm(d, axis=-1, keepdims=True)
        hit = (d.astype(np.float32), unit.astype(np.float32))
        if len(_RAYS_CACHE) > 16:
            _RAYS_CACHE.clear()
        _RAYS_CACHE[key] = hit
    return hit


def render(meshes, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
    """Build a scene from labelled meshes and render one view (see ``Scene`` to reuse one)."""
    return Scene(meshes).render(K, T_world_camera, max_range)
