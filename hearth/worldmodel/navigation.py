"""Paths on the floor: an occupancy grid built from the map, and shortest paths on it
(docs/navigation.md).

The grid covers the home in cells of ``NavConfig.resolution`` (5 cm). A cell is floor when
its centre lies on a room's floor (its outline or bounds) or in a doorway's passage; the
walls are everything else. The footprint of every large object (the convex hull of its
meshes, doors and drawers closed) is taken out of the floor. The robot, a disc of
``robot_radius``, may stand where the floor reaches at least that far around it (the grid's
distance transform, scipy.ndimage). Cells where it may stand are joined to their 8
neighbours (a diagonal step only where both side cells are free, so no corner is cut), and
shortest paths are Dijkstra's on that graph: ``scipy.sparse.csgraph.dijkstra``.

Why scipy's csgraph: scipy is already one of Hearth's dependencies (nothing new to install
or pin); its Dijkstra is compiled and, from one start, gives the distance to every cell at
once with the predecessors for the path, which is what the search planner needs (the path
length to every candidate place's parking positions from one call). scikit-image's
``MCP_Geometric`` does the same on a cost array but would be a new dependency of tens of
megabytes for one function; networkx is pure Python, about two orders of magnitude slower on
a grid of 100,000 cells.

Grid distances move in steps of 0 and 45 degrees, up to 8 % longer than the straight
segment they approximate; a path the robot drives is shortened afterwards by pulling it
tight (each point joined to the furthest later point it sees across free cells), so its
``length`` is close to the true shortest path. ``Path.grid_length`` keeps the grid's figure.

A map that declares no doorway at all (a format-1 map of several rooms) says nothing about
where its walls open: the grid then covers the whole extent of its rooms, and the robot plans
around furniture only (``NavGrid.walls_known`` is False), as it drove before there were
doorways. A home of one room needs no doorway.

Frames: world x, y on the floor, metres.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hearth.worldmodel.frames import T_world_room, transform_xy
from hearth.worldmodel.outline import doorway_rect, room_outline


@dataclass(frozen=True)
class NavConfig:
    """How the floor is gridded (metres)."""
    resolution: float = 0.05
    #: The robot's footprint radius (the generator's parking positions keep it clear).
    robot_radius: float = 0.3
    #: A start or goal off the free cells (a localisation error put the robot a little too
    #: near a wall, a parking pose on the edge of a cell) is joined by a straight move to
    #: the nearest free cell within this distance, if that move crosses no obstacle.
    snap_m: float = 0.25
    #: Grid border around the rooms' extent.
    margin_m: float = 0.3


@dataclass(frozen=True)
class Path:
    """A path the robot can drive: ``points`` (N, 2) world x, y from start to goal,
    ``length`` (m, the tightened polyline), ``straight`` (m, start to goal as the crow
    flies), ``grid_length`` (m, Dijkstra's figure on the grid)."""
    points: np.ndarray
    length: float
    straight: float
    grid_length: float


class NoPath(Exception):
    """No path: ``reason`` says why in words a person reads (what blocks the goal, or that no
    doorway joins the two places)."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


class NavGrid:
    """The occupancy grid of one map. ``floor[r, c]``: the cell's centre is on a floor (or
    in a doorway) and outside every piece of furniture; ``free``: the robot may stand there
    (``clearance`` >= robot radius); ``clearance`` (m): from the cell's centre to the nearest
    cell that is not floor, less half a cell (about the distance to the obstacle's edge);
    ``label``: 0 floor, -1 wall, k > 0 the large object ``names[k]``. Cell (r, c) has its
    lower corner at ``origin + (c, r) * resolution``."""

    def __init__(self, origin, resolution: float, floor: np.ndarray, label: np.ndarray,
                 names: list[str], config: NavConfig, walls_known: bool):
        from scipy import ndimage
        self.origin = (float(origin[0]), float(origin[1]))
        self.resolution = float(resolution)
        self.floor = floor
        self.label = label
        self.names = names
        self.config = config
        self.walls_known = walls_known
        dist, idx = ndimage.distance_transform_edt(floor, return_indices=True)
        self._nearest_blocked = idx
        self.clearance = dist * self.resolution - self.resolution / 2
        self.free = floor & (self.clearance >= config.robot_radius - 1e-9)
        self._build_graph()
        self._fields: dict = {}
        #: What callers work out once per grid (the search's longest path, ...).
        self.memo: dict = {}

    # -- cells -----------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return self.floor.shape

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding world (x, y) (may lie outside the grid)."""
        return (int(math.floor((y - self.origin[1]) / self.resolution)),
                int(math.floor((x - self.origin[0]) / self.resolution)))

    def centre(self, r, c) -> np.ndarray:
        """World x, y of cell centres (arrays or scalars)."""
        return np.stack([self.origin[0] + (np.asarray(c) + 0.5) * self.resolution,
                         self.origin[1] + (np.asarray(r) + 0.5) * self.resolution], axis=-1)

    def inside(self, r: int, c: int) -> bool:
        return 0 <= r < self.shape[0] and 0 <= c < self.shape[1]

    def is_free(self, x: float, y: float) -> bool:
        r, c = self.cell(x, y)
        return self.inside(r, c) and bool(self.free[r, c])

    def blocked_by(self, x: float, y: float) -> str:
        """What keeps the robot from standing at (x, y): "a wall" or a large object's id."""
        r, c = self.cell(x, y)
        if not self.inside(r, c):
            return "a wall"
        if self.floor[r, c]:
            r, c = self._nearest_blocked[0][r, c], self._nearest_blocked[1][r, c]
        k = int(self.label[r, c])
        return "a wall" if k <= 0 else self.names[k]

    def _line_clear(self, a, b, grid: np.ndarray) -> bool:
        """Whether every cell the segment a-b passes over is True in ``grid``."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(2, int(math.ceil(np.linalg.norm(b - a) / (self.resolution * 0.5))) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        p = a + t * (b - a)
        rows = np.floor((p[:, 1] - self.origin[1]) / self.resolution).astype(int)
        cols = np.floor((p[:, 0] - self.origin[0]) / self.resolution).astype(int)
        if rows.min() < 0 or cols.min() < 0 or rows.max() >= self.shape[0] or cols.max() >= self.shape[1]:
            return False
        return bool(grid[rows, cols].all())

    # -- the graph -------------------------------------------------------------------
    def _build_graph(self) -> None:
        from scipy.sparse import coo_matrix
        H, W = self.shape
        node = np.full((H, W), -1, dtype=np.int64)
        fr, fc = np.nonzero(self.free)
        node[fr, fc] = np.arange(len(fr))
        self._node = node
        self._cells = np.stack([fr, fc], axis=1)
        rows, cols, weights = [], [], []
        f = self.free
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
            c0, c1 = max(0, -dc), W - max(0, dc)     # source columns that have the neighbour
            ok = f[:H - dr, c0:c1] & f[dr:, c0 + dc:c1 + dc]
            if dr and dc:   # a diagonal step needs both side cells free (no corner cut)
                ok &= f[dr:, c0:c1] & f[:H - dr, c0 + dc:c1 + dc]
            rr, cc = np.nonzero(ok)
            cc = cc + c0
            rows.append(node[rr, cc])
            cols.append(node[rr + dr, cc + dc])
            weights.append(np.full(len(rr), self.resolution * math.hypot(dr, dc)))
        n = len(fr)
        self._graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows),
                                                            np.concatenate(cols))),
                                 shape=(n, n)).tocsr()

    def _snap(self, x: float, y: float) -> Optional[tuple[int, int]]:
        """The free cell nearest (x, y) within ``snap_m`` that a straight move from (x, y)
        reaches across floor, or None."""
        r, c = self.cell(x, y)
        if self.inside(r, c) and self.free[r, c]:
            return (r, c)
        n = int(math.ceil(self.config.snap_m / self.resolution))
        r0, r1 = max(r - n, 0), min(r + n + 1, self.shape[0])
        c0, c1 = max(c - n, 0), min(c + n + 1, self.shape[1])
        if r0 >= r1 or c0 >= c1:
            return None
        rr, cc = np.nonzero(self.free[r0:r1, c0:c1])
        if len(rr) == 0:
            return None
        rr, cc = rr + r0, cc + c0
        d = np.hypot(*(self.centre(rr, cc) - (x, y)).T)
        for i in np.argsort(d):
            if d[i] > self.config.snap_m:
                break
            if self._line_clear((x, y), self.centre(rr[i], cc[i]), self.floor):
                return (int(rr[i]), int(cc[i]))
        return None

    def region_at(self, x: float, y: float) -> int:
        """A label of the free floor's connected region the robot at (x, y) is in (joined to
        the grid as a path's start is), 0 when it cannot stand there: two places with the
        same label are joined by a path. Labelled 4-connected, which is the graph's
        connectivity (a diagonal step needs both side cells free)."""
        if "regions" not in self.memo:
            from scipy import ndimage
            self.memo["regions"] = ndimage.label(self.free)[0]
        s = self._snap(x, y)
        return 0 if s is None else int(self.memo["regions"][s])

    def _why_not(self, x: float, y: float, what: str) -> str:
        r, c = self.cell(x, y)
        where = f"the {what} ({x:.2f}, {y:.2f})"
        if not self.inside(r, c) or self.label[r, c] < 0:
            return f"{where} is outside every room and doorway"
        if self.label[r, c] > 0:
            return f"{where} is inside {self.names[self.label[r, c]]}"
        return (f"{where} is {max(float(self.clearance[r, c]), 0.0):.2f} m from "
                f"{self.blocked_by(x, y)}, too close for the robot "
                f"({self.config.robot_radius:.2f} m)")

    # -- distances and paths -----------------------------------------------------------
    def distances_from(self, x: float, y: float) -> "DistanceField":
        """Grid distances from (x, y) to every free cell (one Dijkstra). NoPath when the
        start is off the free floor beyond ``snap_m``."""
        from scipy.sparse.csgraph import dijkstra
        s = self._snap(x, y)
        if s is None:
            raise NoPath(self._why_not(x, y, "start"))
        key = s
        hit = self._fields.get(key)
        if hit is None:
            dist, pred = dijkstra(self._graph, directed=False, indices=int(self._node[s]),
                                  return_predecessors=True)
            hit = (dist, pred)
            if len(self._fields) > 8:
                self._fields.pop(next(iter(self._fields)))
            self._fields[key] = hit
        return DistanceField(self, (float(x), float(y)), s, hit[0], hit[1])

    def path(self, start, goal) -> Path:
        """The shortest path from ``start`` to ``goal`` (world x, y); NoPath when there is
        none (``reason`` says why)."""
        return self.distances_from(*start[:2]).path_to(*goal[:2])


class DistanceField:
    """Distances from one start over a NavGrid (``NavGrid.distances_from``)."""

    def __init__(self, grid: NavGrid, start, start_cell, dist, pred):
        self.grid, self.start, self.start_cell = grid, start, start_cell
        self._dist, self._pred = dist, pred
        self._lead = float(np.linalg.norm(grid.centre(*start_cell) - start))

    def _goal(self, x: float, y: float):
        g = self.grid._snap(x, y)
        if g is None:
            raise NoPath(self.grid._why_not(x, y, "goal"))
        d = self._dist[self.grid._node[g]]
        if not np.isfinite(d):
            sx, sy = self.start
            raise NoPath(f"no way from ({sx:.2f}, {sy:.2f}) to ({x:.2f}, {y:.2f}): no doorway "
                         "or gap the robot fits through joins them")
        return g, float(d)

    def length_to(self, x: float, y: float) -> float:
        """Grid path length (m) to (x, y), the moves off and onto the grid included; inf
        when it cannot be reached."""
        try:
            g, d = self._goal(x, y)
        except NoPath:
            return math.inf
        return self._lead + d + float(np.linalg.norm(self.grid.centre(*g) - (x, y)))

    def path_to(self, x: float, y: float) -> Path:
        g, d = self._goal(x, y)
        grid = self.grid
        nodes = []
        n = int(grid._node[g])
        s = int(grid._node[self.start_cell])
        while n != s and n >= 0:
            nodes.append(n)
            n = int(self._pred[n])
        nodes.append(s)
        cells = grid._cells[np.array(nodes[::-1])]
        pts = np.vstack([np.asarray(self.start)[None], grid.centre(cells[:, 0], cells[:, 1]),
                         np.array([[x, y]])])
        tight = _pull_tight(grid, pts)
        length = float(np.sum(np.linalg.norm(np.diff(tight, axis=0), axis=1)))
        grid_length = self._lead + d + float(np.linalg.norm(grid.centre(*g) - (x, y)))
        return Path(tight, length, float(math.dist(self.start, (x, y))), grid_length)


def _pull_tight(grid: NavGrid, pts: np.ndarray) -> np.ndarray:
    """Greedy string pulling: from each kept point, the furthest later point reachable by a
    straight move over free cells (the first and last legs, on and off the grid, kept)."""
    if len(pts) <= 2:
        return pts
    out = [pts[0], pts[1]]
    i, last = 1, len(pts) - 2
    while i < last:
        j = last
        while j > i + 1 and not grid._line_clear(pts[i], pts[j], grid.free):
            j -= 1
        out.append(pts[j])
        i = j
    out.append(pts[-1])
    # drop repeated points (a start or goal on a cell centre)
    keep = [out[0]]
    for p in out[1:]:
        if np.linalg.norm(p - keep[-1]) > 1e-9:
            keep.append(p)
    return np.array(keep)


# -- building the grid from a map -----------------------------------------------------------

def _footprints(world) -> list[tuple[str, np.ndarray]]:
    """(object id, (K, 2) world convex hull) of every large object, doors and drawers
    closed (the furniture as it stands; an open door is the robot's own doing)."""
    from scipy.spatial import ConvexHull
    from hearth.worldmodel.geometry import object_meshes
    from hearth.worldmodel.nodes import LargeArticulatedObject
    out = []
    for obj in world.large_objects():
        states = {}
        if isinstance(obj, LargeArticulatedObject):
            stack = list(obj.parts)
            while stack:
                p = stack.pop()
                states[p.id] = p.joint.lower
                stack += p.parts
        pts = [np.asarray(m.mesh.vertices)[:, :2] for m in
               object_meshes(world, obj, states=states, children=False)]
        pts = [p for p in pts if len(p)]
        if not pts:
            continue
        P = np.vstack(pts)
        try:
            hull = P[ConvexHull(P).vertices]
        except Exception:       # degenerate (flat or one point): its bounding box
            lo, hi = P.min(0) - 0.01, P.max(0) + 0.01
            hull = np.array([lo, (hi[0], lo[1]), hi, (lo[0], hi[1])])
        out.append((obj.id, hull))
    return out


def _fill(mask: np.ndarray, poly_world: np.ndarray, origin, res: float, value: int) -> None:
    import cv2
    shift = 4
    px = (np.asarray(poly_world, float) - origin) / res - 0.5     # cell centres at integers
    pts = np.round(px * (1 << shift)).astype(np.int32).reshape(-1, 1, 2)
    cv2.fillPoly(mask, [pts], int(value), lineType=cv2.LINE_8, shift=shift)


def build_grid(world, config: NavConfig = NavConfig()) -> Optional[NavGrid]:
    """The occupancy grid of ``world`` (None for a map with no room bounds or outlines)."""
    rooms = [r for r in world.rooms if room_outline(r)]
    if not rooms:
        return None
    floors = [transform_xy(T_world_room(r), room_outline(r)) for r in rooms]
    doors = [transform_xy(T_world_room(r), doorway_rect(d)) for r in rooms for d in r.doorways]
    walls_known = bool(doors) or len(rooms) == 1
    return grid_from_polygons(floors + doors, _footprints(world), config, walls_known)


def grid_from_polygons(floors, obstacles=(), config: NavConfig = NavConfig(),
                       walls_known: bool = True) -> NavGrid:
    """The occupancy grid of floor polygons (``floors``: (K, 2) arrays, any one frame, the
    grid's) less ``obstacles`` ((name, (K, 2) polygon) pairs). With ``walls_known`` False
    the whole extent of the floors is floor. The home generator grids a room this way while
    it places the furniture, from the footprints it keeps."""
    floors = [np.asarray(f, float) for f in floors]
    pts = np.vstack(floors)
    res = config.resolution
    lo = pts.min(0) - config.margin_m
    hi = pts.max(0) + config.margin_m
    W, H = int(math.ceil((hi[0] - lo[0]) / res)), int(math.ceil((hi[1] - lo[1]) / res))
    label = np.full((H, W), -1, dtype=np.int32)
    if walls_known:
        for poly in floors:
            _fill(label, poly, lo, res, 0)
    else:
        label[1:-1, 1:-1] = 0
    names = [""]
    for oid, hull in obstacles:
        names.append(oid)
        _fill(label, np.asarray(hull, float), lo, res, len(names) - 1)
    return NavGrid(lo, res, label == 0, label, names, config, walls_known)


def _key(world, config: NavConfig):
    objs = tuple((o.id, tuple(round(v, 6) for v in o.pose.as_dict().values()))
                 for o in world.large_objects())
    rooms = tuple((r.id, tuple(round(v, 6) for v in r.pose.as_dict().values()), r.bounds,
                   tuple(r.outline or ()), tuple((d.id, d.pose, d.width, d.depth)
                                                 for d in r.doorways))
                  for r in world.rooms)
    return (config, objs, rooms)


#: id(world) -> (weak reference, key, grid).
_CACHE: dict = {}


def nav_grid(world, config: NavConfig = NavConfig()) -> Optional[NavGrid]:
    """``build_grid(world)``, kept per world while its rooms, doorways and large objects'
    poses stay as they were (moving small objects, opening doors and turning knobs do not
    change it)."""
    key = _key(world, config)
    hit = _CACHE.get(id(world))
    if hit is not None and hit[0]() is world and hit[1] == key:
        return hit[2]
    grid = build_grid(world, config)
    wid = id(world)
    _CACHE[wid] = (weakref.ref(world, lambda _r, wid=wid: _CACHE.pop(wid, None)), key, grid)
    return grid
