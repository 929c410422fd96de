"""The worlds a benchmark runs on, what it picks from their maps, and per-world figures.

Every perception benchmark runs on any world: the demo home, generated homes
(hearth.worldmodel.homegen) and the user's own world files. Nothing here knows one home: surfaces,
objects and viewpoints come from each map.

Worlds (options and loading)::

    add_arguments(parser, homes=2)  # --world W (repeatable), --homes N, --no-demo
    specs = world_specs(args, homes=2)
    world = load(spec)              # a fresh World each call (cached file, parsed once)

``world_specs``: ``"demo"`` first (unless ``--no-demo``), then ``--world`` files when given,
else ``"home:SEED"`` for ``--homes`` generated homes, seeds ``--seed`` .. ``--seed + N - 1``
(written once per machine, see hearth/executive/scenarios.py ``world_path``). The same spellings as
``hearth bench missions``.

Figures per world and pooled::

    out = report(records, summarise, specs)

``records`` are the benchmark's per-scene dicts, each with a ``"world"`` key; ``summarise``
turns a list of them into figures. ``out`` holds the figures over every record at the top
level (the benchmark's keys), ``worlds`` (the specs), ``per_world`` ({spec: figures}) and,
when generated homes and other worlds were both run, ``generated`` (the figures over the
generated homes alone). A world without what the benchmark needs is listed under
``skipped`` with the reason; when no world is left, the benchmark raises ``NoScenes``.

Picking from the map::

    ps = places(world)              # supporting surfaces with the views that see them
    ps[0].views[0].T_world_camera   # the robot's head camera at one parking position
    head_camera(base_pose, point)   # T_world_camera of the simulated robot looking at point
    opened(world, object_id)        # the furniture's doors and drawers open (in place)
    extent(world, object_id)        # (radius, height) of a small object's model
    spots = visible_spots(world, place, T_world_camera, K, heights)  # surface xy seen
    fitting_objects(world, place)   # small objects of the map that fit on it
    depth, color, rendering = observe(truth, T_world_camera, rng, K)  # Kinect-class noise

A :class:`Place` is one surface small objects stand on (a table top, a shelf, the inside of a
cupboard) with its free height (``headroom``, ray-cast up through the furniture) and one
:class:`View` per parking position of its furniture from which the head camera sees enough of
it. Views of surfaces inside closed furniture assume its doors open (``opened``).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable, Optional, Sequence

import numpy as np

from hearth.util.errors import HearthError

#: Free height above a surface is measured up to this (m).
MAX_HEADROOM = 0.6


class NoScenes(HearthError):
    """None of the worlds given has what a benchmark needs (one line: which and why)."""


# -- worlds ---------------------------------------------------------------------------------

def add_arguments(parser, homes: int = 2) -> None:
    """The options every benchmark on worlds takes (``homes``: the default count)."""
    parser.add_argument("--world", action="append", default=None, metavar="WORLD",
                        help="a world file to run on instead of generated homes (repeatable)")
    parser.add_argument("--homes", type=int, default=None, metavar="N",
                        help=f"generated homes to run on, seeds --seed .. --seed + N - 1 "
                             + (f"(default {homes}; 1 with --quick)" if homes else "(default none)"))
    parser.add_argument("--no-demo", action="store_true", help="leave the demo home out")


def world_specs(args, homes: int = 2) -> list[str]:
    """``demo`` (unless ``--no-demo``), then the ``--world`` files or ``home:SEED`` specs."""
    out = [] if getattr(args, "no_demo", False) else ["demo"]
    if getattr(args, "world", None):
        return out + [str(w) for w in args.world]
    n = getattr(args, "homes", None)
    if n is None:
        n = min(1, homes) if getattr(args, "quick", False) else homes
    seed = int(getattr(args, "seed", 0) or 0)
    return out + [f"home:{seed + i}" for i in range(max(0, int(n)))]


def is_generated(spec: str) -> bool:
    return str(spec).startswith("home:")


@lru_cache(maxsize=None)
def _path(spec: str):
    from hearth.executive.scenarios import world_path
    return world_path(spec)


@lru_cache(maxsize=8)
def _loaded(spec: str):
    from hearth.worldmodel import load_world
    return load_world(_path(spec))


def load(spec: str):
    """A fresh copy of the world of ``spec`` (``demo``, ``home:SEED`` or a file): callers may
    change it."""
    return _loaded(str(spec)).copy()


def report(records: list[dict], summarise: Callable[[list[dict]], dict],
           specs: Sequence[str]) -> dict:
    """Pooled figures at the top level, ``per_world`` and ``generated`` (module docstring)."""
    out = dict(summarise(records))
    out["worlds"] = list(specs)
    out["per_world"] = {s: summarise([r for r in records if r["world"] == s]) for s in specs}
    gen = [r for r in records if is_generated(r["world"])]
    if gen and len(gen) < len(records):
        out["generated"] = summarise(gen)
    return out


def run_worlds(name: str, specs: Sequence[str], run_one: Callable[[int, str], tuple],
               summarise: Callable[[list[dict]], dict]) -> dict:
    """Run a benchmark world by world and pool it: ``run_one(i, spec)`` gives (records, why
    the world was skipped or None). ``report`` of the worlds that gave records, with
    ``skipped`` (spec: why) and ``load_average_1min``; NoScenes when no world gave any."""
    records, skipped = [], {}
    for i, spec in enumerate(specs):
        recs, why = run_one(i, spec)
        records += recs
        if why or not recs:
            skipped[spec] = why or "no scene"
    used = [s for s in specs if s not in skipped]
    if not used:
        raise NoScenes(f"{name}: {'; '.join(f'{s}: {w}' for s, w in skipped.items())}")
    out = report(records, summarise, used)
    try:
        load = round(os.getloadavg()[0], 2)
    except OSError:  # pragma: no cover
        load = None
    out.update(skipped=skipped, load_average_1min=load)
    return out


# -- the robot's head camera -----------------------------------------------------------------

def head_camera(base_pose, point) -> np.ndarray:
    """``T_world_camera`` of the simulated robot's head camera at ``base_pose`` (x, y, yaw or
    a Pose) with the head turned to look at the world ``point`` (within its limits)."""
    from hearth.robot.sim import camera_pose, pan_tilt_to
    from hearth.worldmodel.frames import as_base_pose
    base = as_base_pose(base_pose)
    return camera_pose(base, *pan_tilt_to(base, point))


# -- small objects and furniture -------------------------------------------------------------

def extent(world, object_id: str) -> tuple[float, float]:
    """(radius, height) of a small object's model in its own frame (m): the largest distance
    of its vertices from its vertical axis, and its top above its origin."""
    return extent_of_model(world, world.get(object_id))


def extent_of_model(world, obj) -> tuple[float, float]:
    """``extent`` of a SmallObject ``obj`` that need not be in ``world`` (whose folder its
    mesh files are found from)."""
    from hearth.worldmodel.geometry import small_object_meshes
    meshes = small_object_meshes(world, obj, T_world_object=np.eye(4))
    v = np.vstack([np.asarray(lm.mesh.vertices) for lm in meshes]) if meshes else np.zeros((1, 3))
    return float(np.hypot(v[:, 0], v[:, 1]).max()), float(v[:, 2].max())


def opened(world, object_id: str) -> dict[str, float]:
    """Open every door and drawer of a large object in the map (revolute joints to the limit
    farthest from closed, prismatic ones to their upper limit); returns {part: state}."""
    out = {}
    obj = world.get(object_id)
    for part in getattr(obj, "parts", []):
        j = part.joint
        if j.type == "revolute":
            value = j.upper if abs(j.upper) >= abs(j.lower) else j.lower
        elif j.type == "prismatic":
            value = j.upper
        else:
            continue
        world.set_joint_state(part.id, float(value), source="benchmark")
        out[part.id] = float(value)
    return out


def _furniture_scene(world, object_id: str):
    """An open3d ray-casting scene of one large object without its small objects."""
    import open3d as o3d
    from hearth.worldmodel.geometry import object_meshes
    scene = o3d.t.geometry.RaycastingScene()
    for lm in object_meshes(world, world.get(object_id), children=False):
        if len(lm.mesh.triangles):
            scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
    return scene


def _headroom(scene, T_world_surface: np.ndarray, sx: float, sy: float) -> float:
    """Free height above a surface: the lowest hit of rays cast straight up from a grid on it
    through its furniture (``scene``); inf when nothing is above."""
    import open3d as o3d
    g = np.linspace(-0.35, 0.35, 5)
    gx, gy = np.meshgrid(g * sx, g * sy)
    local = np.c_[gx.ravel(), gy.ravel(), np.full(gx.size, 0.005)]
    origins = local @ T_world_surface[:3, :3].T + T_world_surface[:3, 3]
    rays = np.c_[origins, np.tile(T_world_surface[:3, 2], (len(origins), 1))].astype(np.float32)
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    return float(np.min(t) + 0.005)


# -- places and views -------------------------------------------------------------------------

@dataclass
class View:
    """The head camera at one parking position of the furniture, looking at ``aim`` (world,
    the middle of what it sees of the surface, a little above it). ``seen``: the share of the
    surface's grid points the camera sees (unblocked, in view)."""
    parking: str
    base_pose: tuple[float, float, float]
    T_world_camera: np.ndarray
    aim: np.ndarray
    seen: float


@dataclass
class Place:
    """A surface small objects stand on. ``T_world_surface``: origin at the centre of its top
    face, +z up; ``size`` (x, y) its extent in that frame; ``headroom`` the free height above
    it (MAX_HEADROOM: open above); ``inside``: it lies in furniture that has doors or drawers
    (its views assume them open). ``T_parent_surface``: the surface in the furniture's frame."""
    object_id: str
    surface: str
    relation: str
    T_world_surface: np.ndarray
    T_parent_surface: np.ndarray
    size: tuple[float, float]
    headroom: float
    inside: bool
    open_above: bool
    views: list[View] = field(default_factory=list)

    @property
    def name(self) -> str:
        """``object/surface``, as detection names surfaces."""
        return f"{self.object_id}/{self.surface}"

    @property
    def height(self) -> float:
        return float(self.T_world_surface[2, 3])

    @property
    def kind(self) -> str:
        """``top`` (open above), ``shelf`` (open furniture, something above) or ``inside``."""
        if self.inside:
            return "inside"
        return "top" if self.open_above else "shelf"

    def to_parent(self, u: float, v: float, yaw: float = 0.0):
        """The Pose, in the furniture's frame, of a point (u, v) of the surface turned by
        ``yaw`` about the surface's z (what a SmallObject standing there has as its pose)."""
        from hearth.worldmodel.frames import planar_T
        from hearth.worldmodel.pose import Pose
        return Pose.from_matrix(self.T_parent_surface @ planar_T(u, v, yaw))

    def world_xy(self, uv) -> np.ndarray:
        """(N, 2) world x, y of surface points (N, 2)."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        return uv @ self.T_world_surface[:2, :2].T + self.T_world_surface[:2, 3]

    def local_xy(self, xy) -> np.ndarray:
        """(N, 2) surface u, v of world floor points (N, 2)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return (xy - self.T_world_surface[:2, 3]) @ self.T_world_surface[:2, :2]


def places(world, min_seen: float = 0.3, max_height: float = 1.3,
           min_size: float = 0.15) -> list[Place]:
    """Every surface of the map's large objects that small objects stand on ("on" or "in",
    up to ``max_height``, both sides at least ``min_size``), each with the views from its
    furniture's parking positions that see at least ``min_seen`` of it (doors and drawers
    open; checked on a quarter-resolution rendering); surfaces no parking position sees are
    left out. Ordered as the map lists them."""
    from hearth.perception.camera import Intrinsics
    K = Intrinsics.kinect().scaled(0.25)
    out = []
    for obj in world.large_objects():
        if not obj.surfaces or not obj.parking:
            continue
        inside = bool(getattr(obj, "parts", None)) and any(
            s.relation == "in" for s in obj.surfaces)
        w = world
        if inside:
            w = world.copy()
            opened(w, obj.id)
        T_obj = w.T_world(obj.id)
        furniture = None
        for s in obj.surfaces:
            if s.relation not in ("on", "in") or min(s.size_x, s.size_y) < min_size:
                continue
            T_ws = T_obj @ s.pose.matrix()
            if T_ws[2, 3] > max_height:
                continue
            furniture = furniture or _furniture_scene(w, obj.id)
            free = _headroom(furniture, T_ws, s.size_x, s.size_y)
            head = min(free, MAX_HEADROOM)
            if head < 0.08:
                continue
            p = Place(obj.id, s.id, s.relation, T_ws, s.pose.matrix(), (s.size_x, s.size_y),
                      head, inside and s.relation == "in", not math.isfinite(free))
            for pk, base in w.parking_positions(obj.id):
                base_xyz = (base.x, base.y, base.yaw)
                T_wc = head_camera(base_xyz, T_ws[:3, 3] + T_ws[:3, 2] * min(0.05, head / 2))
                uv = grid(p, inset=0.03)
                seen = visible_spots(w, p, T_wc, K, (0.02,), uv=uv, margin_px=5)
                share = len(seen) / max(len(uv), 1)
                if share < min_seen:
                    continue
                # Aim at what is seen of the surface, then keep the view if it still sees it.
                c = p.world_xy(seen.mean(0))[0]
                aim = np.array([c[0], c[1], p.height + min(0.05, head / 2)])
                T_wc = head_camera(base_xyz, aim)
                share = len(visible_spots(w, p, T_wc, K, (0.02,), uv=uv, margin_px=5)) \
                    / max(len(uv), 1)
                if share >= min_seen:
                    p.views.append(View(pk.id, base_xyz, T_wc, aim, round(share, 3)))
            if p.views:
                out.append(p)
    return out


def grid(place: Place, step: float = 0.03, inset: float = 0.0) -> np.ndarray:
    """(N, 2) surface points every ``step`` metres, ``inset`` in from its edges."""
    hx, hy = place.size[0] / 2 - inset, place.size[1] / 2 - inset
    if hx <= 0 or hy <= 0:
        return np.zeros((0, 2))
    u = np.arange(-hx, hx + 1e-9, step) if 2 * hx > step else np.zeros(1)
    v = np.arange(-hy, hy + 1e-9, step) if 2 * hy > step else np.zeros(1)
    gu, gv = np.meshgrid(u - (u.mean() if len(u) else 0), v - (v.mean() if len(v) else 0))
    return np.c_[gu.ravel(), gv.ravel()]


def _static_depth(world, room_id: str, K, T_world_camera: np.ndarray) -> np.ndarray:
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import scene_meshes
    small = tuple(o.id for o in world.small_objects())
    return Scene(scene_meshes(world, room_ids=[room_id], exclude=small)).render(
        K, T_world_camera).depth


def visible_spots(world, place: Place, T_world_camera: np.ndarray, K,
                  heights: Sequence[float] = (0.02,), uv: Optional[np.ndarray] = None,
                  margin_px: float = 20.0, depth: Optional[np.ndarray] = None) -> np.ndarray:
    """The surface points ``uv`` (default ``grid(place)``) that the camera sees at every one
    of ``heights`` above the surface: inside the image by ``margin_px`` and not hidden by the
    room and its furniture (small objects left out; ``depth`` a rendering of them, else
    rendered now)."""
    from hearth.perception.camera import project
    uv = grid(place) if uv is None else np.asarray(uv, dtype=float)
    if not len(uv):
        return uv
    if depth is None:
        depth = _static_depth(world, world.room_of(place.object_id).id, K, T_world_camera)
    T_cw = np.linalg.inv(T_world_camera)
    ok = np.ones(len(uv), bool)
    for h in heights:
        local = np.c_[uv, np.full(len(uv), h), np.ones(len(uv))]
        pw = (place.T_world_surface @ local.T).T[:, :3]
        pc = pw @ T_cw[:3, :3].T + T_cw[:3, 3]
        px, front = project(pc, K)
        inside = front & (px[:, 0] >= margin_px) & (px[:, 0] < K.width - margin_px) & \
            (px[:, 1] >= margin_px) & (px[:, 1] < K.height - margin_px)
        ok &= inside
        iu = np.clip(np.round(px[:, 0]).astype(int), 0, K.width - 1)
        iv = np.clip(np.round(px[:, 1]).astype(int), 0, K.height - 1)
        d = depth[iv, iu]
        ok &= (d <= 0) | (d >= pc[:, 2] - 0.01)
    return uv[ok]


def summary_stats(xs, nd: int = 1, q: Optional[float] = None):
    """Median (or the ``q`` percentile) of the finite values of ``xs``, rounded; None when
    there are none."""
    vals = [float(x) for x in xs if x is not None and math.isfinite(x)]
    if not vals:
        return None
    v = float(np.median(vals)) if q is None else float(np.percentile(vals, q))
    return round(v, nd)


# -- scenes: what fits where, and what the camera sees (hearth.benchmarks.objects and others) --

def fitting_objects(world, place) -> list[str]:
    """Small objects of the map that fit on ``place``: their radius and height within its
    extent and free height."""
    out = []
    for o in world.small_objects():
        r, h = extent(world, o.id)
        if 2 * r + 0.02 <= min(place.size) and h + 0.015 <= place.headroom:
            out.append(o.id)
    return out


def observe(truth, T_world_camera, rng, K=None, scene=None, room=None):
    """(depth m, colour uint8, noise-free Rendering) of the truth from ``T_world_camera``
    (``robot.sim.render_view``: Kinect-class noise on depth and colour); ``room``: render
    that room only (default: the room the camera stands in, else every room)."""
    from hearth.perception.camera import Intrinsics
    from hearth.perception.render import Scene
    from hearth.robot.sim import render_view
    from hearth.worldmodel.frames import room_at
    from hearth.worldmodel.geometry import scene_meshes
    K = K or Intrinsics.kinect()
    if scene is None:
        if room is None:
            r = room_at(truth, float(T_world_camera[0, 3]), float(T_world_camera[1, 3]))
            room = r.id if r is not None else None
        scene = Scene(scene_meshes(truth, room_ids=None if room is None else [room]))
    f = render_view(truth, K, T_world_camera, rng, scene=scene)
    return np.asarray(f.depth, np.float64), f.color, f.rendering
