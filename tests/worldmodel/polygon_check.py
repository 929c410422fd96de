"""An independent point-in-polygon test for the generator's tests (written here, not taken
from hearth.worldmodel.outline, so that the tests do not check the code with itself)."""
from __future__ import annotations

import numpy as np


def inside_and_distance(points: np.ndarray, poly: np.ndarray):
    """For (M, 2) points: inside the polygon (even-odd) and distance to its sides."""
    a = poly
    b = np.roll(poly, -1, axis=0)
    P = points[:, None, :]
    d = b - a
    t = np.clip(np.einsum("mkj,kj->mk", P - a, d) / np.maximum((d * d).sum(1), 1e-12), 0, 1)
    dist = np.linalg.norm(P - (a + t[..., None] * d), axis=2).min(1)
    y = points[:, 1:2]
    cross = (a[:, 1] > y) != (b[:, 1] > y)
    xc = a[:, 0] + (y - a[:, 1]) * d[:, 0] / np.where(d[:, 1] == 0, 1e-12, d[:, 1])
    inside = (cross & (points[:, 0:1] < xc)).sum(1) % 2 == 1
    return inside, dist
