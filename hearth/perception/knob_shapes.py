"""A knob's look as the reader knows it: its shape from the map (``KnobShape``, ``knob_shape``:
visuals as triangle meshes in the knob's frame, which turn and which are fixed) and ray casting
against it (``_Caster``, open3d's Embree scenes). The method is described in
hearth/perception/knobs.py."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hearth.perception import knob_kernels


#: Face classes of a label: front (normal along the knob's axis), or a side facing canvas
#: up, left, down, right.
N_FACE = 5
#: Face classes of the exact check's labels: front, then the sides in ``FINE_AZIMUTHS``
#: directions (canvas frame) and two bands of steepness: about one flat face of a primitive,
#: under one light, per label.
FINE_AZIMUTHS = 36
N_FACE_FINE = 1 + 2 * FINE_AZIMUTHS
#: Ray origins of the parallel (template) rays stand this far out along the view (m).
_FAR = 0.5


@dataclass(frozen=True)
class KnobShape:
    """What the reader knows of a knob's look: its visuals as triangle meshes in the knob
    frame at angle 0 (``vertices`` / ``triangles`` per visual, ``roles`` base/grip/marker,
    ``turns``: False for a fixed base), its outline ``radius`` (m, the farthest point from the
    axis), ``face`` (m, the frontmost z: the canvas plane), its ``symmetry``. ``key``: a
    fingerprint of all of it (knobs of one design share it and their templates)."""
    key: str
    vertices: tuple
    triangles: tuple
    roles: tuple[str, ...]
    turns: tuple[bool, ...]
    radius: float
    face: float
    symmetry: int = 1

    @property
    def period(self) -> float:
        """The angle (rad) after which the shape looks the same again."""
        return 2 * math.pi / self.symmetry


def knob_shape(knob, library: Optional[dict] = None, base_dir=None) -> KnobShape:
    """The ``KnobShape`` of a map ``Knob`` (hearth.worldmodel.geometry ``knob_parts``: the described
    shape, or the plain knob of format 1)."""
    from hearth.worldmodel.geometry import knob_parts, visual_mesh
    verts, tris, roles, turns = [], [], [], []
    for role, v, t in knob_parts(knob, library):
        m = visual_mesh(v, base_dir)
        if len(m.triangles) == 0:
            continue
        verts.append(np.asarray(m.vertices, dtype=np.float64).round(7))
        tris.append(np.asarray(m.triangles, dtype=np.int32))
        roles.append(role)
        turns.append(bool(t))
    if not verts:
        from hearth.perception.errors import PerceptionError
        raise PerceptionError(f"knob {knob.id} has no shape to read")
    allv = np.concatenate(verts)
    radius = float(np.max(np.hypot(allv[:, 0], allv[:, 1])))
    face = float(np.max(allv[:, 2]))
    h = hashlib.sha256()
    for v, t, r, tu in zip(verts, tris, roles, turns):
        h.update(v.tobytes())
        h.update(t.tobytes())
        h.update(f"{r}:{tu}".encode())
    h.update(str(int(knob.symmetry)).encode())
    return KnobShape(h.hexdigest()[:16], tuple(verts), tuple(tris), tuple(roles), tuple(turns),
                     radius, face, int(knob.symmetry))


class _Caster:
    """Ray casting against one shape: a scene of its turning visuals and one of its fixed
    ones (open3d's Embree scenes; built on first use, not pickled), with each triangle's
    visual, normal azimuth (about the knob's axis) and steepness."""

    def __init__(self, shape: KnobShape):
        import open3d as o3d
        self.o3d = o3d
        self.scenes, self.first, self.az, self.nz, self.part = [], [], [], [], []
        self.bounds = []
        for turning in (True, False):
            scene = o3d.t.geometry.RaycastingScene()
            first, az, nz, part, corners = [], [], [], [], []
            count = 0
            for i, (v, t, tu) in enumerate(zip(shape.vertices, shape.triangles, shape.turns)):
                if tu != turning:
                    continue
                v32 = v.astype(np.float32).astype(np.float64)
                corners += [v32.min(0), v32.max(0)]
                mesh = o3d.t.geometry.TriangleMesh()
                mesh.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
                mesh.triangle.indices = o3d.core.Tensor(t)
                scene.add_triangles(mesh)
                n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
                n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
                first.append(count)
                az.append(np.arctan2(-n[:, 0], n[:, 1]))      # 0: facing +y, +pi/2: facing -x
                nz.append(np.abs(n[:, 2]))
                part.append(np.full(len(t), i, dtype=np.int64))
                count += len(t)
            self.scenes.append(scene if count else None)
            # the scene's bounding box (the vertices as the scene holds them), padded by 0.1 mm
            # so that no rounding drops a ray that grazes it (``knob_kernels.turn_rays_near_box``)
            pad = 1e-4
            self.bounds.append((np.min(corners, 0) - pad, np.max(corners, 0) + pad) if count else None)
            self.first.append(np.array(first + [count], dtype=np.int64))
            self.az.append(np.concatenate(az + [np.zeros(1)]))
            self.nz.append(np.concatenate(nz + [np.zeros(1)]))
            self.part.append(np.concatenate(part + [np.zeros(1, np.int64)]))

    def _cast(self, k: int, origins: np.ndarray, dirs: np.ndarray, turns: np.ndarray) -> tuple:
        """Scene ``k``'s hits of the rays ``origins``, ``dirs`` (``labels``' broadcast forms)
        turned back by each of ``turns`` into the visuals' frame: of the rays that can reach
        the scene's bounding box (``knob_kernels.turn_rays_near_box``; the others hit
        nothing, and each ray is cast alone, so the hits are those of casting all), their
        indices (b * N + n), t (inf: nothing), geometry and primitive ids."""
        M = len(turns) * dirs.shape[1]
        rays = np.empty((M, 6), np.float32)
        keep = np.empty(M, np.int64)
        m = knob_kernels.turn_rays_near_box(origins, dirs, np.cos(turns), np.sin(turns),
                                            *self.bounds[k], rays, keep)
        keep = keep[:m]
        if not m:
            return keep, np.empty(0, np.float32), np.empty(0, np.uint32), np.empty(0, np.uint32)
        # one thread: a few thousand rays a call, and Embree's threads cost more CPU than
        # they save (a pointer reading 9.6 -> 9.1 ms CPU, its wall time the same to the noise)
        ans = self.scenes[k].cast_rays(self.o3d.core.Tensor.from_numpy(rays[:m]), nthreads=1)
        return (keep, np.array(ans["t_hit"].numpy()), np.array(ans["geometry_ids"].numpy()),
                np.array(ans["primitive_ids"].numpy()))

    def labels(self, origins: np.ndarray, dirs: np.ndarray, turns: np.ndarray, fixed_turn: float,
               fine: bool = False, with_t: bool = False, cache: Optional[dict] = None):
        """Labels (uint16, 0 = nothing) of rays given in the canvas frame with the knob's
        origin at the canvas origin, for each of ``turns`` (B,): the turning visuals turned
        by it (rad, counter-clockwise about +z), the fixed ones by ``fixed_turn``.
        ``origins`` (3,) or (B, N, 3), ``dirs`` (N, 3) or (B, N, 3). The label is
        1 + visual * classes + face class, the face class from the normal turned into the
        canvas: front (along the axis), else which way it faces (4 sides, or with ``fine``
        ``FINE_AZIMUTHS`` directions in two bands of steepness). With ``with_t``: also the
        ray parameter of each hit (B, N) (inf where nothing is hit). ``cache``: a dict kept
        by a caller that casts the same rays (one window's) at the same ``fixed_turn`` again
        and again: the fixed visuals' hits are cast once into it and reused (the same hits,
        so the same labels)."""
        turns = np.atleast_1d(np.asarray(turns, dtype=float))
        B = len(turns)
        # rays the same for every turn: the fixed visuals' hits are the same for all of them
        # (cast once)
        same_rays = np.ndim(dirs) == 2 and np.ndim(origins) <= 2
        d3 = np.asarray(dirs, dtype=np.float64)
        d3 = d3.reshape((1,) + d3.shape) if d3.ndim == 2 else d3
        N = d3.shape[1]
        # one origin for every ray (the camera centre): (1, 1, 3), else (B, N, 3)
        o3 = np.asarray(origins, dtype=np.float64)
        o3 = o3.reshape(1, 1, 3) if o3.ndim == 1 else o3.reshape((-1,) + o3.shape[-2:])
        best_t = np.full((B, N), np.inf)
        label = np.zeros((B, N), dtype=np.uint16)
        classes = N_FACE_FINE if fine else N_FACE
        for k, scene in enumerate(self.scenes):
            if scene is None:
                continue
            a = turns if k == 0 else np.full(B, float(fixed_turn))
            once = k == 1 and same_rays
            Bc = 1 if once else B
            # into the visuals' frame: turn the rays back by a (compiled, numpy's operations:
            # hearth/perception/knob_kernels.py)
            hits = cache.get("fixed") if (once and cache is not None) else None
            if hits is None:
                hits = self._cast(k, o3, d3, a[:Bc])
                if once and cache is not None:
                    cache["fixed"] = hits
            # the nearer hits' labels: each triangle's face class for each turn, per hit
            knob_kernels.nearest_labels(
                *hits, Bc, self.first[k], self.az[k],
                self.nz[k], self.part[k], a, fine, classes, FINE_AZIMUTHS,
                2 * math.pi / FINE_AZIMUTHS, math.pi / 2, label, best_t)
        return (label, best_t) if with_t else label


def _canvas_points(n: int, px_per_m: float, center=(0.0, 0.0)) -> np.ndarray:
    """(n*n, 2) canvas-plane points (m) of an n x n canvas's pixel centres, row-major; canvas
    right = +x, canvas up = +y, its centre pixel at ``center``."""
    c = (n - 1) / 2.0
    jj, ii = np.meshgrid(np.arange(n), np.arange(n))
    return np.stack([(jj.ravel() - c) / px_per_m + center[0],
                     -(ii.ravel() - c) / px_per_m + center[1]], -1)


#: Stored readers (joblib files, hearth/worldmodel/model_store.py) name their classes by module:
#: these keep the module they were stored under before the reader was split into modules
#: (hearth.perception.knobs, which still exports them), so a stored model reads alike with this
#: code and earlier code, and neither makes the other retrain.
for _cls in (KnobShape,):
    _cls.__module__ = "hearth.perception.knobs"
