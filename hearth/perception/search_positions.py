"""Search positions proposed from semantic segmentation ("Where to look first?", HOBBIT D3.2,
section on search positions, Fig. 6).

Points labelled table are clustered (Euclidean, scikit-learn's DBSCAN); a cluster whose top
lies in a plausible height range is a table top. Its points projected on the floor give two
principal axes (the sides of their minimum-area rectangle, see ``table_tops``); the robot
stands on the *second* principal axis (across the table's short side, so it sees the long
side), on both sides, at the safety distance ``d`` from the table's edge, facing the table
centre. A position is kept only when it and the table lie inside the room's bounds (the
robot and the table in the same room; nothing behind a wall) and its footprint (robot
radius) is free in the occupancy grid (the map's static objects and what the view shows as
obstacles).

Frames: world, z up, floor z = 0; lengths in metres; yaw in radians.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from sklearn.cluster import DBSCAN


@dataclass(frozen=True)
class SearchConfig:
    safety_distance_m: float = 0.45      # d: from the table edge to the robot base centre
    robot_radius_m: float = 0.3
    table_height_m: tuple[float, float] = (0.45, 1.2)  # range of a table top's height
    top_band_m: float = 0.06             # points this far below the top count as the top
    voxel_m: float = 0.03                # thinning before clustering
    cluster_eps_m: float = 0.1
    min_top_points: int = 15             # (after thinning) smaller clusters are noise
    min_side_m: float = 0.15             # table tops narrower than this are not tables


@dataclass
class TableTop:
    """A table top from segmentation: ``center`` (x, y), ``height`` (m), unit principal axes
    ``axes`` (2, 2) (row 0 the first), ``half_extents`` along them (m)."""
    center: np.ndarray
    height: float
    axes: np.ndarray
    half_extents: np.ndarray
    n_points: int


@dataclass
class SearchPosition:
    """A base pose (world x, y, yaw facing the table) and the table top it looks at."""
    x: float
    y: float
    yaw: float
    table: TableTop = field(repr=False)
    distance_to_robot: float = math.nan


@dataclass
class OccupancyGrid:
    """A 2-D grid over the floor: ``occupied[row, col]`` covers the cell with lower corner
    (origin_x + col * resolution, origin_y + row * resolution)."""
    origin: tuple[float, float]
    resolution: float
    occupied: np.ndarray

    @staticmethod
    def empty(bounds, resolution: float = 0.05) -> "OccupancyGrid":
        """A free grid covering ``bounds`` (xmin, ymin, xmax, ymax)."""
        x0, y0, x1, y1 = bounds
        W = max(1, int(math.ceil((x1 - x0) / resolution)))
        H = max(1, int(math.ceil((y1 - y0) / resolution)))
        return OccupancyGrid((float(x0), float(y0)), resolution, np.zeros((H, W), dtype=bool))

    def _cells(self, xy: np.ndarray):
        c = np.floor((np.asarray(xy, dtype=float).reshape(-1, 2) - self.origin) / self.resolution)
        return c[:, 1].astype(int), c[:, 0].astype(int)

    def mark_points(self, points_world: np.ndarray, z_range=(0.05, 1.8)) -> "OccupancyGrid":
        """Mark the cells under obstacle points whose height is in ``z_range``."""
        p = np.asarray(points_world, dtype=float).reshape(-1, 3)
        p = p[(p[:, 2] >= z_range[0]) & (p[:, 2] <= z_range[1])]
        r, c = self._cells(p[:, :2])
        ok = (r >= 0) & (r < self.occupied.shape[0]) & (c >= 0) & (c < self.occupied.shape[1])
        self.occupied[r[ok], c[ok]] = True
        return self

    def mark_boxes(self, boxes) -> "OccupancyGrid":
        """Mark axis-aligned boxes, each (2, 2) or (2, 3) [min, max] in the world frame."""
        for b in boxes:
            b = np.asarray(b, dtype=float)
            (r0, r1), (c0, c1) = [(int(math.floor((b[0, k] - self.origin[k]) / self.resolution)),
                                   int(math.floor((b[1, k] - self.origin[k]) / self.resolution)))
                                  for k in (1, 0)]
            r0, c0 = max(r0, 0), max(c0, 0)
            self.occupied[r0:max(r1 + 1, r0), c0:max(c1 + 1, c0)] = True
        return self

    def mark_footprints(self, points_xy_list) -> "OccupancyGrid":
        """Mark the convex hull of each (N, 2) array of floor points (e.g. an object's mesh
        vertices): unlike an axis-aligned box this keeps a rotated table's corners free."""
        import cv2
        from scipy.spatial import ConvexHull
        for xy in points_xy_list:
            xy = np.asarray(xy, dtype=float).reshape(-1, 2)
            if len(xy) < 3:
                continue
            try:
                hull = xy[ConvexHull(xy).vertices]
            except Exception:   # degenerate (collinear) footprint
                hull = xy
            cells = np.round((hull - self.origin) / self.resolution - 0.5).astype(np.int32)
            mask = self.occupied.view(np.uint8)
            cv2.fillConvexPoly(mask, cells.reshape(-1, 1, 2), 1)
        return self

    def is_free(self, x: float, y: float, radius: float) -> bool:
        """No occupied cell within ``radius`` of (x, y); outside the grid counts as free."""
        n = int(math.ceil(radius / self.resolution))
        r, c = self._cells([[x, y]])
        r, c = int(r[0]), int(c[0])
        H, W = self.occupied.shape
        rr, cc = np.mgrid[max(r - n, 0):min(r + n + 1, H), max(c - n, 0):min(c + n + 1, W)]
        if rr.size == 0:
            return True
        cx = self.origin[0] + (cc + 0.5) * self.resolution
        cy = self.origin[1] + (rr + 0.5) * self.resolution
        near = (cx - x) ** 2 + (cy - y) ** 2 <= (radius + self.resolution * 0.71) ** 2
        return not bool(self.occupied[rr, cc][near].any())


def _thin(points: np.ndarray, voxel: float) -> np.ndarray:
    keys = np.floor(points / voxel).astype(np.int64)
    _, idx = np.unique(keys, axis=0, return_index=True)
    return points[np.sort(idx)]


def table_tops(table_points_world: np.ndarray, config: SearchConfig | None = None) -> list[TableTop]:
    """Table tops among points labelled table (world frame, (N, 3))."""
    c = config or SearchConfig()
    p = np.asarray(table_points_world, dtype=float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) == 0:
        return []
    p = _thin(p, c.voxel_m)
    if len(p) < c.min_top_points:
        return []
    lab = DBSCAN(eps=c.cluster_eps_m, min_samples=4).fit_predict(p)
    out = []
    for k in sorted(set(lab) - {-1}):
        q = p[lab == k]
        h = float(np.percentile(q[:, 2], 95))
        if not c.table_height_m[0] <= h <= c.table_height_m[1]:
            continue
        top = q[q[:, 2] >= h - c.top_band_m][:, :2]
        if len(top) < c.min_top_points:
            continue
        # The table's axes and extent: OpenCV's minimum-area rectangle (rotating calipers
        # over the hull) of the top points, long side first. PCA of the points gives the same
        # axes for an ideal rectangle, but on thinned, aliased samples of a near-square top
        # it was off by up to 7 degrees; the rectangle's sides are not.
        (cx, cy), (w, l), ang = cv2.minAreaRect(np.ascontiguousarray(top, dtype=np.float32))
        a = math.radians(ang)
        u, v = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
        axes = np.stack([u, v] if w >= l else [v, u])   # row 0: first (long) axis
        half = np.array(sorted((w / 2, l / 2), reverse=True), dtype=float)
        centre = np.array([cx, cy], dtype=float)
        if np.min(2 * half) < c.min_side_m:
            continue
        out.append(TableTop(centre, h, axes, half, len(top)))
    return out


def _inside(bounds, x: float, y: float, margin: float) -> bool:
    x0, y0, x1, y1 = bounds
    return x0 + margin <= x <= x1 - margin and y0 + margin <= y <= y1 - margin


def propose_search_positions(table_points_world: np.ndarray, room_bounds=None,
                             occupancy: OccupancyGrid | None = None, robot_xy=None,
                             config: SearchConfig | None = None,
                             T_world_room: np.ndarray | None = None) -> list[SearchPosition]:
    """Search positions for the tables among ``table_points_world`` (see module docstring),
    nearest to ``robot_xy`` (world x, y) first when it is given. ``room_bounds`` (xmin, ymin,
    xmax, ymax) of the robot's room, in the room frame ``T_world_room`` (4x4; default: the
    world frame); None skips the room check. ``occupancy`` is a grid in the room frame. The
    positions and their table tops are returned in the world frame."""
    if T_world_room is not None:
        T = np.asarray(T_world_room, dtype=float)
        Tinv = np.linalg.inv(T)
        P = np.asarray(table_points_world, dtype=float).reshape(-1, 3)
        local_robot = None if robot_xy is None else \
            tuple(Tinv[:2, :2] @ np.asarray(robot_xy, float)[:2] + Tinv[:2, 3])
        local = propose_search_positions(P @ Tinv[:3, :3].T + Tinv[:3, 3], room_bounds,
                                         occupancy, local_robot, config)
        return [_to_world(sp, T) for sp in local]
    c = config or SearchConfig()
    out = []
    for t in table_tops(table_points_world, c):
        if room_bounds is not None and not _inside(room_bounds, *t.center, 0.0):
            continue
        e2 = t.axes[1]
        for s in (1.0, -1.0):
            xy = t.center + s * (t.half_extents[1] + c.safety_distance_m) * e2
            x, y = float(xy[0]), float(xy[1])
            if room_bounds is not None and not _inside(room_bounds, x, y, c.robot_radius_m):
                continue
            if occupancy is not None and not occupancy.is_free(x, y, c.robot_radius_m):
                continue
            yaw = math.atan2(t.center[1] - y, t.center[0] - x)
            d = math.nan if robot_xy is None else math.hypot(x - robot_xy[0], y - robot_xy[1])
            out.append(SearchPosition(x, y, yaw, t, d))
    if robot_xy is not None:
        out.sort(key=lambda sp: sp.distance_to_robot)
    return out


def _to_world(sp: SearchPosition, T: np.ndarray) -> SearchPosition:
    """A search position found in a room frame, in the world frame (``T``: T_world_room)."""
    R = T[:2, :2]
    yaw_room = math.atan2(T[1, 0], T[0, 0])
    t = sp.table
    table = TableTop(R @ t.center + T[:2, 3], t.height + float(T[2, 3]), t.axes @ R.T,
                     t.half_extents, t.n_points)
    x, y = R @ (sp.x, sp.y) + T[:2, 3]
    return SearchPosition(float(x), float(y), sp.yaw + yaw_room, table, sp.distance_to_robot)
