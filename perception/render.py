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
        self._index = np.full(max(geom_ids, default=-1) + 2, -1, dtype=np.int64)
        for i, gid in enumerate(geom_ids):
            self._index[gid] = i

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
        """Render the view of camera ``K`` at ``T_world_camera``."""
        H, W = K.height, K.width
        # open3d casts the ray of pixel (u, v) through (u + 0.5, v + 0.5); our camera model
        # (camera.py) puts pixel centres at integer coordinates, so shift the principal point.
        Km = K.matrix()
        Km[0, 2] += 0.5
        Km[1, 2] += 0.5
        rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
            o3d.core.Tensor(Km, dtype=o3d.core.float64),
            o3d.core.Tensor(np.linalg.inv(T_world_camera), dtype=o3d.core.float64), W, H)
        ans = self._scene.cast_rays(rays)
        t_hit = ans["t_hit"].numpy()
        gid = ans["geometry_ids"].numpy().astype(np.int64)
        n_world = ans["primitive_normals"].numpy()
        dirs = rays.numpy()[..., 3:6]
        hit = np.isfinite(t_hit) & (t_hit < max_range * 4)
        # Rays from create_rays_pinhole are unnormalised with z = 1 in the camera frame, so
        # t_hit is already depth along the optical axis.
        depth = np.where(hit, t_hit, 0.0).astype(np.float32)
        depth[depth > max_range] = 0.0
        hit &= depth > 0
        safe_gid = np.where(hit, gid, self._index.shape[0] - 1)
        labels = np.where(hit, self._index[np.clip(safe_gid, 0, self._index.shape[0] - 1)], -1)
        dn = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
        # Normals face the camera.
        cos = np.sum(n_world * dn, axis=-1)
        n_world = np.where(cos[..., None] > 0, -n_world, n_world)
        incidence = np.abs(cos).astype(np.float32)
        incidence[~hit] = 0
        R_cw = np.linalg.inv(T_world_camera)[:3, :3]
        normals_camera = (n_world @ R_cw.T).astype(np.float32)
        normals_camera[~hit] = 0
        shade = AMBIENT + (1 - AMBIENT) * np.clip(n_world @ LIGHT_WORLD, 0, 1)
        # A little view-dependent light so that faces parallel to the light still differ.
        shade = 0.85 * shade + 0.15 * incidence
        base = np.zeros((H, W, 3), dtype=np.float32)
        if len(self._colors):
            base[hit] = self._colors[labels[hit]]
        color = np.clip(base * shade[..., None] * 255.0, 0, 255).astype(np.uint8)
        color[~hit] = 0
        return Rendering(depth=depth, color=color, labels=labels.astype(np.int32),
                         nodes=self.nodes, owners=self.owners, names=self.names,
                         materials=self.materials, normals_camera=normals_camera,
                         incidence=incidence)


def render(meshes, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0) -> Rendering:
    """Build a scene from labelled meshes and render one view (see ``Scene`` to reuse one)."""
    return Scene(meshes).render(K, T_world_camera, max_range)
