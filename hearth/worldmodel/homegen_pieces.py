"""What a furniture builder of the home generator works with and returns: rounded poses and
primitives (``box``, ``cyl``), ``View`` and ``Piece``, the build context (``_Ctx``: random
draws, ids, meshes) and parking candidates with the views they must give (``sees``).

The underscored names here are shared by the homegen_* modules only."""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from hearth.worldmodel.homegen_config import HomeConfig
from hearth.worldmodel.homegen_geometry import ply_bytes
from hearth.worldmodel.homegen_palette import WHITE
from hearth.worldmodel.nodes import LargeObject, ParkingPosition, Surface, Visual
from hearth.worldmodel.pose import Pose, wrap_angle

TAU = 2 * math.pi


def _rot_pose(R: np.ndarray, x: float, y: float, z: float) -> Pose:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = (x, y, z)
    return _clean(Pose.from_matrix(T))


def _clean(p: Pose) -> Pose:
    """A pose with lengths rounded to 1 um and angles to 1e-9 rad (exact quarter turns and
    round numbers in the file instead of 6.1e-17)."""
    return Pose(*(round(v, 6) + 0.0 for v in (p.x, p.y, p.z)),
                *(round(wrap_angle(a) if abs(abs(a) - math.pi) > 1e-9 else math.pi, 9) + 0.0
                  for a in (p.roll, p.pitch, p.yaw)))


def _level_compose(a: Pose, b: Pose) -> Pose:
    """``a * b`` for a pose ``a`` without roll and pitch (a level frame: a room, a surface, a
    quarter turn). With rotations Rz(yaw) Ry(pitch) Rx(roll), turning first by a yaw only adds
    to the yaw, so this is exact without matrices."""
    assert a.roll == 0.0 and a.pitch == 0.0
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    return _clean(Pose(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, a.z + b.z,
                       b.roll, b.pitch, a.yaw + b.yaw))


def _mm(v: float) -> float:
    return round(float(v), 3) + 0.0


def _deg(v: float) -> float:
    """An angle rounded to 1e-4 rad; quarter turns stay exact."""
    q = float(v) / (math.pi / 2)
    if abs(q - round(q)) < 1e-9:
        return round(q) * (math.pi / 2) + 0.0
    return round(float(v), 4) + 0.0


def box(sx, sy, sz, x=0.0, y=0.0, z=0.0, color=WHITE, material="matte", name="") -> Visual:
    return Visual("box", Pose(_mm(x), _mm(y), _mm(z)), size=(_mm(sx), _mm(sy), _mm(sz)),
                  color=color, material=material, name=name)


def cyl(r, h, x=0.0, y=0.0, z=0.0, color=WHITE, material="matte", name="") -> Visual:
    return Visual("cylinder", Pose(_mm(x), _mm(y), _mm(z)), radius=_mm(r), length=_mm(h),
                  color=color, material=material, name=name)


# -- what a builder returns ---------------------------------------------------------------------

@dataclass
class View:
    """What a parking position must let the camera see (object frame, metres).

    kind: ``face`` (a front face: ``normal`` out of it, seen within ``max_angle``), ``top``
    (a surface open above: the camera above it), ``opening`` (a surface inside an opening on
    the front: seen through the front plane ``front_x`` below ``ceiling``), ``knobs`` (a knob
    panel, front or top: ``normal`` along the knobs' axes)."""
    kind: str
    point: tuple[float, float, float]
    normal: tuple[float, float, float] = (1.0, 0.0, 0.0)
    max_angle: float = math.radians(70)
    front_x: float = 0.0
    ceiling: float = math.inf


@dataclass
class Piece:
    """A large object in its canonical frame and what its placement must respect."""
    obj: LargeObject
    mount: str                                   #: "wall" or "free"
    parking: list[ParkingPosition]               #: candidates, best first (object frame)
    views: list[View] = field(default_factory=list)
    reach: list[tuple[float, float, float]] = field(default_factory=list)
    headroom: dict[str, float] = field(default_factory=dict)   #: surface id -> free height
    hull: Optional[np.ndarray] = None            #: convex footprint, object frame
    lift: float = 0.0                            #: height of the object's base (wall cabinets)


class _Ids:
    """Unique ids and names across the home."""

    def __init__(self):
        self.used: set[str] = set()
        self.names: set[str] = set()

    def new(self, base: str) -> str:
        n = 1
        while f"{base}_{n}" in self.used:
            n += 1
        self.used.add(f"{base}_{n}")
        return f"{base}_{n}"

    def exact(self, oid: str) -> str:
        if oid in self.used:
            return self.new(oid)
        self.used.add(oid)
        return oid

    def name(self, text: str) -> str:
        n, out = 1, text
        while out in self.names:
            n += 1
            out = f"{text} {n}"
        self.names.add(out)
        return out


class _Meshes:
    """PLY meshes of one home, named after their content (``meshes/KIND-HASH.ply``); only
    those the finished home references are written (``write``)."""

    def __init__(self, scratch_dir: Path):
        self.scratch_dir = Path(scratch_dir)     # every mesh, for footprints while laying out
        self.files: dict[str, bytes] = {}

    def add(self, kind: str, mesh) -> str:
        data = ply_bytes(mesh)
        rel = f"meshes/{kind}-{hashlib.sha1(data).hexdigest()[:12]}.ply"
        if rel not in self.files:
            self.files[rel] = data
            (self.scratch_dir / "meshes").mkdir(parents=True, exist_ok=True)
            (self.scratch_dir / rel).write_bytes(data)
        return rel

    def write(self, directory: Path, used: set[str]) -> None:
        from hearth.worldmodel.io import atomic_write
        for rel in sorted(used):
            data = self.files[rel]
            path = Path(directory) / rel
            if path.is_file() and path.stat().st_size == len(data) and path.read_bytes() == data:
                continue
            atomic_write(path, data)


@dataclass
class _Ctx:
    rng: np.random.Generator
    cfg: HomeConfig
    ids: _Ids
    meshes: _Meshes
    library: dict
    room_name: str = ""
    knobs_left: int = 8
    #: knob designs are drawn from a generator of their own, so that varying them leaves the
    #: rest of a seed's home (layout, states, objects) as it was
    design_rng: Optional[np.random.Generator] = None

    def u(self, lo: float, hi: float) -> float:
        return float(self.rng.uniform(lo, hi))

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)

    def pick(self, seq):
        return seq[int(self.rng.integers(len(seq)))]

    def i(self, lo: int, hi: int) -> int:
        return int(self.rng.integers(lo, hi + 1))


# -- parking candidates and views ---------------------------------------------------------------

def _facing(x: float, y: float, tx: float, ty: float) -> Pose:
    """A base pose at (x, y) looking at (tx, ty) (object frame)."""
    return Pose.planar(_mm(x), _mm(y), _deg(math.atan2(ty - y, tx - x)))


def front_parking(ctx: _Ctx, oid: str, front_x: float, width: float) -> list[ParkingPosition]:
    """Front, left and right parking positions facing a front at x = ``front_x`` (object
    frame), looking at its centre: the robot centre ``parking_distance`` from the face, then
    candidates 15, 30 and 45 cm further back and some nearer, all with the same id
    (``_keep_visible`` keeps the first that sees everything)."""
    lo = ctx.cfg.parking_distance[0]
    d = _mm(ctx.u(*ctx.cfg.parking_distance))
    ladder = [d + b for b in (0.0, 0.15, 0.3, 0.45)] + [x for x in (lo + 0.1, lo) if x < d]
    spread = _mm(min(max(width / 2 * ctx.u(0.6, 1.0), 0.25), 0.6))
    return [ParkingPosition(f"{oid}_{name}", _facing(front_x + dist, y, front_x, 0.0))
            for name, y in (("front", 0.0), ("left", spread), ("right", -spread))
            for dist in ladder]


def around_parking(ctx: _Ctx, oid: str, sx: float, sy: float) -> list[ParkingPosition]:
    """Parking positions on each side of an sx x sy table (the long sides first) looking at
    its centre; a long table gets one more on each long side, looking straight at it."""
    d = _mm(ctx.u(0.5, 0.75))
    long_x = sx >= sy
    sides = [("south", 0.0, -(sy / 2 + d)), ("north", 0.0, sy / 2 + d),
             ("west", -(sx / 2 + d), 0.0), ("east", sx / 2 + d, 0.0)]
    if not long_x:
        sides = sides[2:] + sides[:2]
    out = [ParkingPosition(f"{oid}_{name}", _facing(x, y, 0.0, 0.0)) for name, x, y in sides]
    if max(sx, sy) > 1.3:
        a = max(sx, sy) / 4
        extra = ([("south_2", a, -(sy / 2 + d), a, 0.0), ("north_2", -a, sy / 2 + d, -a, 0.0)]
                 if long_x else
                 [("west_2", -(sx / 2 + d), a, 0.0, a), ("east_2", sx / 2 + d, -a, 0.0, -a)])
        out += [ParkingPosition(f"{oid}_{name}", _facing(x, y, tx, ty))
                for name, x, y, tx, ty in extra]
    return out


def sees(cfg: HomeConfig, base: Pose, view: View) -> bool:
    """Whether the camera on a robot at ``base`` (object frame) sees ``view`` within its head
    limits and range. The camera is ``camera_height`` above the floor, ``camera_ahead`` from
    the base centre towards the point."""
    p = np.asarray(view.point, dtype=float)
    d = p[:2] - (base.x, base.y)
    h = float(np.hypot(*d))
    if h < 1e-6:
        return False
    cam = np.array([base.x + cfg.camera_ahead * d[0] / h, base.y + cfg.camera_ahead * d[1] / h,
                    cfg.camera_height])
    tilt = math.atan2(cfg.camera_height - p[2], h - cfg.camera_ahead)
    margin = math.radians(6)
    if not cfg.tilt_limits[0] + margin <= tilt <= cfg.tilt_limits[1] - margin:
        return False
    v = cam - p
    dist = float(np.linalg.norm(v))
    if not cfg.min_range + 0.12 <= dist <= 3.5:
        return False
    n = np.asarray(view.normal, dtype=float)
    if view.kind == "top":
        return v[2] >= 0.12
    if float(v @ n) / dist < math.cos(view.max_angle):
        return False
    if view.kind == "opening":
        if cam[0] <= view.front_x + 0.05:
            return False
        s = (view.front_x - p[0]) / (cam[0] - p[0])
        z_front = p[2] + s * (cam[2] - p[2])
        return z_front <= view.ceiling - 0.01
    return True


def _keep_visible(cfg: HomeConfig, piece: Piece) -> None:
    """Keep the parking candidates that see every view of the piece and reach every point it
    must reach; of candidates sharing an id, the first such."""
    keep: dict[str, ParkingPosition] = {}
    for pk in piece.parking:
        if pk.id in keep or not all(sees(cfg, pk.pose, v) for v in piece.views):
            continue
        if any(math.hypot(r[0] - pk.pose.x, r[1] - pk.pose.y) > cfg.reach for r in piece.reach):
            continue
        keep[pk.id] = pk
    piece.parking = list(keep.values())


def _surface_views(surfaces: list[Surface], headroom: dict, front_x: float, cfg: HomeConfig,
                   open_above: set) -> list[View]:
    """Views of the surfaces small objects may go on: the top of those open above, through
    the front opening for the others (a point 6 cm in from the front edge, a little up)."""
    out = []
    for s in surfaces:
        if s.pose.z > cfg.max_object_height or s.relation == "under":
            continue
        if s.id in open_above:
            out.append(View("top", (s.pose.x, s.pose.y, s.pose.z)))
        else:
            x = s.pose.x + s.size_x / 2 - 0.06
            out.append(View("opening", (x, s.pose.y, s.pose.z + min(0.06, headroom[s.id] / 3)),
                            front_x=front_x, ceiling=s.pose.z + headroom[s.id]))
    return out


