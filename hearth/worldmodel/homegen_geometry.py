"""Plane geometry and small meshes for the home generator (hearth/worldmodel/homegen.py).

- Convex footprints on the floor: ``convex_hull_xy`` (scipy), ``polygons_overlap`` (the
  separating axis test), ``point_polygon_distance``; all points are (x, y) in metres in one
  frame (a room's, while a room is laid out).
- Meshes for furniture that is not made of primitives: vertices and triangles as numpy arrays
  (``box_mesh``, ``extrude``, ``merge``, ``transformed``) written as ASCII PLY bytes
  (``ply_bytes``), so the generator can write them atomically (hearth.worldmodel.io.atomic_write) and
  byte-identically for a seed. open3d reads them (hearth/worldmodel/geometry.py).

Written by hand: the separating axis test and the point-to-polygon distance are a few lines
each and no dependency of Hearth has them for 2-D polygons; open3d writes PLY only to a path,
not to bytes.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull

Mesh = tuple[np.ndarray, np.ndarray]   # (V (N, 3) float, F (M, 3) int), faces counter-clockwise


# -- polygons ---------------------------------------------------------------------------------

def convex_hull_xy(points) -> np.ndarray:
    """(K, 2) counter-clockwise vertices of the convex hull of (N, 2) or (N, 3) points."""
    P = np.asarray(points, dtype=float)[:, :2]
    hull = ConvexHull(P)
    return P[hull.vertices]        # scipy gives 2-D hull vertices counter-clockwise


def rect(cx: float, cy: float, sx: float, sy: float, yaw: float = 0.0) -> np.ndarray:
    """(4, 2) counter-clockwise corners of an sx x sy rectangle centred at (cx, cy), turned
    by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    half = np.array([[-sx, -sy], [sx, -sy], [sx, sy], [-sx, sy]]) / 2
    return half @ np.array([[c, s], [-s, c]]) + (cx, cy)


def transform_polygon(T: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """A floor polygon mapped by the planar part of a 4x4 transform."""
    T = np.asarray(T)
    return np.asarray(poly) @ T[:2, :2].T + T[:2, 3]


def _axes(poly: np.ndarray) -> np.ndarray:
    edges = np.roll(poly, -1, axis=0) - poly
    normals = np.c_[edges[:, 1], -edges[:, 0]]
    n = np.linalg.norm(normals, axis=1)
    return normals[n > 1e-12] / n[n > 1e-12, None]


def polygons_overlap(a: np.ndarray, b: np.ndarray, gap: float = 0.0) -> bool:
    """Whether two convex polygons come closer than ``gap`` along every edge normal of either
    (the separating axis test; with ``gap`` > 0 it is conservative: polygons further apart
    than ``gap`` only diagonally count as overlapping)."""
    (ax0, ay0), (ax1, ay1) = a.min(0), a.max(0)
    (bx0, by0), (bx1, by1) = b.min(0), b.max(0)
    if ax1 + gap <= bx0 or bx1 + gap <= ax0 or ay1 + gap <= by0 or by1 + gap <= ay0:
        return False                           # bounding boxes apart: cheap and common
    for axis in np.vstack([_axes(a), _axes(b)]):
        pa, pb = a @ axis, b @ axis
        if pa.max() + gap <= pb.min() or pb.max() + gap <= pa.min():
            return False
    return True


def point_polygon_distance(p, poly: np.ndarray) -> float:
    """Distance from a point to a convex counter-clockwise polygon's boundary, negative when the
    point is inside."""
    p = np.asarray(p, dtype=float)[:2]
    a = np.asarray(poly, dtype=float)
    b = np.roll(a, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18),
                0.0, 1.0)
    d = float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))
    cross = ab[:, 0] * (p[1] - a[:, 1]) - ab[:, 1] * (p[0] - a[:, 0])
    return -d if np.all(cross >= 0) else d


def disc_clear(p, poly: np.ndarray, r: float) -> bool:
    """Whether a disc of radius ``r`` at ``p`` stays clear of a convex polygon."""
    x, y = float(p[0]), float(p[1])
    lo, hi = poly.min(0), poly.max(0)
    if x < lo[0] - r or x > hi[0] + r or y < lo[1] - r or y > hi[1] + r:
        return True
    return point_polygon_distance((x, y), poly) >= r


def polygon_inside_rect(poly: np.ndarray, bounds, tol: float = 1e-6) -> bool:
    x0, y0, x1, y1 = bounds
    return bool(poly[:, 0].min() >= x0 - tol and poly[:, 0].max() <= x1 + tol
                and poly[:, 1].min() >= y0 - tol and poly[:, 1].max() <= y1 + tol)


# -- meshes -----------------------------------------------------------------------------------

def box_mesh(centre, size) -> Mesh:
    """An axis-aligned box, outward-facing triangles."""
    cx, cy, cz = centre
    sx, sy, sz = (float(v) / 2 for v in size)
    V = np.array([[cx + i * sx, cy + j * sy, cz + k * sz]
                  for k in (-1, 1) for j in (-1, 1) for i in (-1, 1)], dtype=float)
    # vertex index = i_bit + 2 j_bit + 4 k_bit
    F = np.array([[0, 2, 1], [1, 2, 3],        # bottom (-z)
                  [4, 5, 6], [5, 7, 6],        # top (+z)
                  [0, 1, 4], [1, 5, 4],        # -y
                  [2, 6, 3], [3, 6, 7],        # +y
                  [0, 4, 2], [2, 4, 6],        # -x
                  [1, 3, 5], [3, 7, 5]])       # +x
    return V, F


def extrude(poly_xy, z0: float, z1: float) -> Mesh:
    """A prism: the convex counter-clockwise polygon ``poly_xy`` from z0 to z1 (z1 > z0)."""
    P = np.asarray(poly_xy, dtype=float)
    n = len(P)
    V = np.vstack([np.c_[P, np.full(n, z0)], np.c_[P, np.full(n, z1)]])
    F = []
    for i in range(1, n - 1):                  # fans: bottom faces down, top faces up
        F.append([0, i + 1, i])
        F.append([n, n + i, n + i + 1])
    for i in range(n):
        j = (i + 1) % n
        F.append([i, j, n + j])
        F.append([i, n + j, n + i])
    return V, np.array(F, dtype=int)


def rounded_rect(sx: float, sy: float, r: float, segments: int = 6) -> np.ndarray:
    """Counter-clockwise outline of an sx x sy rectangle with corners rounded by ``r``."""
    r = min(r, sx / 2, sy / 2)
    pts = []
    for (cx, cy, a0) in ((sx / 2 - r, -sy / 2 + r, -math.pi / 2), (sx / 2 - r, sy / 2 - r, 0.0),
                         (-sx / 2 + r, sy / 2 - r, math.pi / 2), (-sx / 2 + r, -sy / 2 + r, math.pi)):
        for k in range(segments + 1):
            a = a0 + (math.pi / 2) * k / segments
            pts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    return np.array(pts)


def transformed(mesh: Mesh, T: np.ndarray) -> Mesh:
    """The mesh moved by a rigid 4x4 transform (a rotation keeps the triangles' winding)."""
    V, F = mesh
    return V @ np.asarray(T)[:3, :3].T + np.asarray(T)[:3, 3], F


def merge(*meshes: Mesh) -> Mesh:
    Vs, Fs, n = [], [], 0
    for V, F in meshes:
        Vs.append(V)
        Fs.append(F + n)
        n += len(V)
    return np.vstack(Vs), np.vstack(Fs)


def ply_bytes(mesh: Mesh) -> bytes:
    """ASCII PLY of a triangle mesh, 0.01 mm resolution (the same mesh gives the same bytes)."""
    V, F = mesh
    lines = ["ply", "format ascii 1.0", "comment Hearth home generator",
             f"element vertex {len(V)}", "property float x", "property float y",
             "property float z", f"element face {len(F)}", "property list uchar int vertex_indices",
             "end_header"]
    lines += [f"{x:.5f} {y:.5f} {z:.5f}" for x, y, z in np.round(V, 5) + 0.0]
    lines += [f"3 {a} {b} {c}" for a, b, c in F]
    return ("\n".join(lines) + "\n").encode("ascii")


def fan_prism(poly_xy, z0: float, z1: float) -> Mesh:
    """A prism of a polygon star-shaped about its centroid (a knurled grip's ridged outline,
    counter-clockwise), from z0 to z1: caps fanned from the centroid (``extrude`` fans from a
    corner and needs a convex polygon)."""
    P = np.asarray(poly_xy, dtype=float)
    n = len(P)
    c = P.mean(axis=0)
    V = np.vstack([np.c_[P, np.full(n, z0)], np.c_[P, np.full(n, z1)], [[c[0], c[1], z0], [c[0], c[1], z1]]])
    F = []
    for i in range(n):
        j = (i + 1) % n
        F += [[2 * n, j, i], [2 * n + 1, n + i, n + j], [i, j, n + j], [i, n + j, n + i]]
    return V, np.array(F, dtype=int)


def frustum(r0: float, r1: float, z0: float, z1: float, segments: int = 24) -> Mesh:
    """A truncated cone about +z: radius r0 at z0, r1 at z1 (a tapered knob grip)."""
    a = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    ring = lambda r, z: np.c_[r * np.cos(a), r * np.sin(a), np.full(segments, z)]
    n = segments
    V = np.vstack([ring(r0, z0), ring(r1, z1), [[0, 0, z0], [0, 0, z1]]])
    F = []
    for i in range(n):
        j = (i + 1) % n
        F += [[2 * n, j, i], [2 * n + 1, n + i, n + j], [i, j, n + j], [i, n + j, n + i]]
    return V, np.array(F, dtype=int)
