"""Generated homes: valid world files that differ the way real homes do.

``generate_home(seed, config)`` builds a home in memory (a ``World``); ``make_home(seed,
out_dir, config)`` writes it as ``out_dir/world.xml`` with its meshes in ``out_dir/meshes/``.
The same seed and configuration give byte-identical files (one numpy Generator from the seed
drives every choice). docs/world-format.md ("Generated homes") lists what varies.

How a home is made:

1. Rooms (2-5, a kitchen always) of several kinds and sizes; each room's bounds are in its
   own frame, offset from its origin, and the room pose puts it in the world, turned by any
   angle for some rooms; rooms are placed next to each other without overlapping.
2. Furniture, one builder per kind (``table``, ``bookshelf``, ``cupboard``, ``drawer_unit``,
   ``fridge``, ``appliance`` (oven, cooker, hob), ``chair``). A builder makes the object in a
   canonical frame (origin on the floor under its footprint's centre, front towards +x) with
   candidate parking positions, the views every parking position must give (its front, its
   top surface, its shelves, its knob panel) and the points the arm must reach.
3. Layout: each piece is placed with its back to a wall (facing into the room) or free-standing
   at any angle. Its footprint is the convex hull of its meshes (hearth.worldmodel.geometry); it
   must not overlap another footprint, must leave every parking position placed so far free,
   and keeps only the parking positions of its own that are inside the room by the robot
   radius and clear of every footprint.
4. Small objects of several kinds and colours (some close in hue) on, in and under furniture:
   on tables, on lower shelves, inside closed cupboards and fridges, under tables.
5. Some objects are then turned inside their own frame (their front becomes local +y, -x or
   -y) with the pose compensating, so nothing may assume that objects face their local +x.

Meshes (door panels, table tops, shelf sides) are small ASCII PLY files named after their
content. ``generate_home`` writes them into ``mesh_dir`` (default: the cache directory
``$HEARTH_HOMEGEN_DIR``, else ``~/.cache/hearth/homegen``) and sets the world's ``base_dir``
there, so the world can be rendered at once; ``make_home`` writes them next to world.xml.
"""
from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.frames import planar_T, transform_xy
from hearth.worldmodel.homegen_geometry import (
    box_mesh, convex_hull_xy, disc_clear, extrude, fan_prism, frustum, merge, ply_bytes,
    polygon_inside_rect, polygons_overlap, rounded_rect, transform_polygon, transformed,
)
from hearth.worldmodel.nodes import (
    Apartment, DefaultPosition, GraspPoint, Handle, Joint, Knob, KnobState, LargeArticulatedObject,
    LargeObject, Model, ParkingPosition, Part, Room, SmallObject, Surface, Switch, Visual,
)
from hearth.worldmodel.pose import Pose, wrap_angle

TAU = 2 * math.pi


class HomeGenError(WorldError):
    """A configuration the generator cannot use (one line naming the setting)."""


# -- configuration ------------------------------------------------------------------------------

@dataclass(frozen=True)
class HomeConfig:
    """Ranges the generator draws from (metres, radians, counts as (min, max) inclusive).

    The camera and reach values describe the robot that must see and reach the furniture from
    its parking positions; they match hearth/robot/sim.py ``HeadMount`` and the simulated
    robot's reach (a test checks they agree)."""
    rooms: tuple[int, int] = (2, 5)
    turned_room_probability: float = 0.5        #: room yaw anywhere, else a multiple of 90 deg
    room_gap: float = 0.3                       #: between rooms' bounds (walls are 0.1 thick)
    table_height: tuple[float, float] = (0.4, 1.1)
    round_table_probability: float = 0.35
    mesh_probability: float = 0.35              #: furniture parts drawn as PLY meshes
    free_standing_probability: float = 0.2      #: shelves, cupboards, drawers away from walls
    tall_cupboard_probability: float = 0.3
    wall_cabinet_probability: float = 0.3
    two_door_probability: float = 0.5
    drawers: tuple[int, int] = (1, 4)
    shelf_levels: tuple[int, int] = (2, 6)
    knobs_per_appliance: tuple[int, int] = (2, 6)
    max_knobs: int = 8                          #: per home (knob models train per home)
    knob_states: tuple[int, int] = (2, 12)
    flush_front_probability: float = 0.5
    top_knobs_probability: float = 0.5          #: a hob's knobs on its top, not its front
    second_appliance_probability: float = 0.35
    knob_on_probability: float = 0.1            #: a knob left on in the map
    plain_knob_probability: float = 0.1         #: a row of format-1 plain knobs (else the design space)
    off_mid_travel_probability: float = 0.2     #: a knob whose off lies between its settings
    low_panel_probability: float = 0.2          #: an oven's knob panel below its door
    raised_oven_probability: float = 0.25       #: an oven raised on a cabinet (knobs up to 1.4 m)
    small_objects: tuple[int, int] = (7, 14)
    close_hue_probability: float = 0.6          #: a pair of objects close in hue (blue, navy)
    under_table_probability: float = 0.4
    front_turn_probability: float = 0.25        #: object turned inside its own frame
    robot_radius: float = 0.3
    parking_distance: tuple[float, float] = (0.6, 0.9)   #: robot centre to the front face
    camera_height: float = 1.30
    camera_ahead: float = 0.15                  #: camera ahead of the base centre
    tilt_limits: tuple[float, float] = (-math.radians(45), math.radians(75))
    min_range: float = 0.45                     #: depth sensor
    reach: float = 1.45                         #: base centre to a handle, knob or surface
    max_object_height: float = 1.25             #: small objects only on surfaces up to here
    placement_tries: int = 40

    def check(self) -> None:
        """HomeGenError naming the first setting out of range."""
        for name in ("rooms", "table_height", "drawers", "shelf_levels", "knobs_per_appliance",
                     "knob_states", "small_objects", "parking_distance"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise HomeGenError(f"home config: {name} must be (min, max) with min <= max, "
                                   f"not {(lo, hi)}")
        if not 1 <= self.rooms[0] <= self.rooms[1] <= 6:
            raise HomeGenError(f"home config: rooms must be within 1..6, not {self.rooms}")
        if self.knob_states[0] < 2 or self.knob_states[1] > 12:
            raise HomeGenError(f"home config: knob_states must be within 2..12, not "
                               f"{self.knob_states}")
        if self.knobs_per_appliance[0] < 1 or self.max_knobs < self.knobs_per_appliance[0]:
            raise HomeGenError("home config: max_knobs must be at least knobs_per_appliance[0] "
                               "(every kitchen has an appliance with knobs)")
        if not (0.35 <= self.table_height[0] and self.table_height[1] <= 1.15):
            raise HomeGenError(f"home config: table_height must be within 0.35..1.15 m (the "
                               f"camera must see the top), not {self.table_height}")
        for name, v in self.__dict__.items():
            if name.endswith("_probability") and not 0.0 <= v <= 1.0:
                raise HomeGenError(f"home config: {name} must be within 0..1, not {v}")


# -- colours, materials and words ---------------------------------------------------------------

WOODS = [(0.55, 0.38, 0.22), (0.45, 0.3, 0.2), (0.72, 0.58, 0.4), (0.33, 0.22, 0.14),
         (0.82, 0.7, 0.52)]
PAINTS = [(0.92, 0.92, 0.9), (0.85, 0.86, 0.88), (0.93, 0.89, 0.78), (0.55, 0.62, 0.66),
          (0.3, 0.36, 0.42), (0.64, 0.7, 0.58)]
STEEL = (0.72, 0.73, 0.75)
WHITE = (0.93, 0.93, 0.92)
DARK = (0.12, 0.12, 0.13)
BLACK = (0.06, 0.06, 0.07)

#: Small-object colours by name. Pairs close in hue have different words, so "blue cup" and
#: "navy cup" are both unambiguous.
COLOURS = {
    "red": (0.8, 0.1, 0.1), "crimson": (0.62, 0.05, 0.16), "orange": (0.95, 0.5, 0.1),
    "amber": (0.9, 0.64, 0.1), "yellow": (0.95, 0.85, 0.2), "green": (0.15, 0.6, 0.2),
    "olive": (0.45, 0.52, 0.14), "teal": (0.05, 0.5, 0.5), "blue": (0.1, 0.25, 0.8),
    "navy": (0.08, 0.12, 0.45), "purple": (0.5, 0.2, 0.65), "pink": (0.95, 0.55, 0.7),
    "white": (0.95, 0.95, 0.95), "black": (0.1, 0.1, 0.1), "grey": (0.5, 0.5, 0.52),
    "brown": (0.45, 0.28, 0.15),
}
CLOSE_HUES = [("blue", "navy"), ("red", "crimson"), ("orange", "amber"), ("green", "olive"),
              ("blue", "teal")]

#: Knob designs: body colour, marker colour, radius range, depth range.
#: Bump when a seed's home changes (hearth/executive/scenarios.py keeps generated homes per version):
#: 2 = knob designs varied (KNOB_FAMILIES); 3 = a tip or dot stands out from the grip it sits on;
#: 4 = a skirt knob's dot stands 1 mm proud of its cap as built (not level with it on some homes).
#: 5 = knobs drawn from a design space (base, grip, marker, materials, stand-off), off anywhere in the travel;
#: 6 = a low-contrast or dark-on-dark line or dot stands 1.5-3 mm proud (a printed pointer stands out in colour);
#: 7 = a marker sits on its grip's top as built (rounded), not half a millimetre inside it;
#: 8 = the knob panel's place and off mid-travel drawn from the designs' generator (the rest
#:     of a seed's home as in version 4).
#: 9 = a chest's top drawer has a floor (a part surface) that may hold a small object (drawn
#:     from a generator of its own); half the bedroom wardrobes have two sliding doors on one
#:     track with recessed pulls (issue 43).
GENERATOR_VERSION = 9

KNOB_DESIGNS = [
    ("white", (0.9, 0.9, 0.88), (0.05, 0.05, 0.05), (0.018, 0.026), (0.018, 0.026)),
    ("black", (0.08, 0.08, 0.09), (0.92, 0.92, 0.9), (0.017, 0.024), (0.015, 0.024)),
    ("steel", (0.74, 0.75, 0.77), (0.05, 0.05, 0.05), (0.022, 0.03), (0.02, 0.032)),
    ("cream", (0.93, 0.88, 0.75), (0.35, 0.2, 0.1), (0.013, 0.018), (0.012, 0.02)),
    ("red marker", (0.15, 0.15, 0.16), (0.85, 0.1, 0.1), (0.02, 0.028), (0.02, 0.03)),
]
OFF_NAMES = ["off", "0", "aus", "OFF", "min", "Off", "O", "stop", "standby", "zero", "Aus"]

# The knob frame's axes in its parent's frame: on a front face whose outward normal is +x
# (knob x = parent y, marker at angle 0 = parent z, axis = parent x), and on a top face
# (axis up, marker at angle 0 pointing away from the front, -x).
_R_FRONT = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


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
    #: objects in drawers are drawn from a generator of their own too
    drawer_rng: Optional[np.random.Generator] = None

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


# -- furniture builders (canonical frame: origin on the floor, front towards +x) ----------------

def table(ctx: _Ctx, kind: str = "table") -> Piece:
    """A table: rectangular, long and narrow, or round (cylinder top); legs or a pedestal;
    sometimes a mesh top (rounded corners) or mesh legs. ``kind``: table, coffee, side,
    dining, desk, counter, bedside."""
    cfg = ctx.cfg
    heights = {"coffee": (0.4, 0.5), "side": (0.5, 0.72), "bedside": (0.45, 0.65),
               "dining": (0.72, 0.78), "desk": (0.72, 0.77), "counter": (0.85, 0.95),
               "table": (0.72, 0.8), "bar": (0.95, 1.1)}[kind]
    lo, hi = max(cfg.table_height[0], heights[0]), min(cfg.table_height[1], heights[1])
    h = _mm(ctx.u(lo, hi) if lo <= hi else ctx.u(*cfg.table_height))
    color = ctx.pick(WOODS + PAINTS[:2])
    word = kind if kind in ("counter", "desk", "table") else f"{kind} table"
    oid = ctx.ids.new(word.replace(" ", "_"))
    name = ctx.ids.name(f"{ctx.room_name} {word}")
    round_top = kind in ("coffee", "side", "bar", "table", "dining") and ctx.chance(cfg.round_table_probability)
    t = _mm(ctx.u(0.02, 0.04))
    visuals: list[Visual] = []
    if round_top:
        r = _mm({"coffee": ctx.u(0.3, 0.5), "side": ctx.u(0.22, 0.35), "bar": ctx.u(0.3, 0.4),
                 "table": ctx.u(0.4, 0.6), "dining": ctx.u(0.45, 0.6)}[kind])
        sx = sy = 2 * r
        visuals.append(cyl(r, t, z=h - t / 2, color=color, name="top"))
        if ctx.chance(0.5):     # pedestal and foot
            visuals += [cyl(_mm(ctx.u(0.03, 0.06)), h - t - 0.02, z=(h - t) / 2 + 0.01, color=color,
                            name="leg"),
                        cyl(_mm(r * ctx.u(0.45, 0.7)), 0.02, z=0.01, color=color, name="foot")]
        else:
            lr, n_legs = r * 0.62, ctx.pick([3, 4])
            for k in range(n_legs):
                a = TAU * k / n_legs + math.pi / 4
                visuals.append(box(0.04, 0.04, h - t, lr * math.cos(a), lr * math.sin(a),
                                   (h - t) / 2, color=color, name="leg"))
        surface = Surface("top", Pose(0, 0, h), _mm(2 * r * 0.68), _mm(2 * r * 0.68))
    else:
        if kind in ("desk", "counter") or (kind in ("table", "dining", "side") and ctx.chance(0.2)):
            # long and narrow
            sx, sy = _mm(ctx.u(1.2, 1.9)), _mm(ctx.u(0.4, 0.6))
        elif kind in ("side", "bedside"):
            sx, sy = _mm(ctx.u(0.4, 0.7)), _mm(ctx.u(0.35, 0.55))
        elif kind == "coffee":
            sx, sy = _mm(ctx.u(0.8, 1.3)), _mm(ctx.u(0.5, 0.75))
        else:
            sx, sy = _mm(ctx.u(0.9, 1.6)), _mm(ctx.u(0.7, 1.0))
        if ctx.chance(cfg.mesh_probability):
            top = extrude(rounded_rect(sx, sy, ctx.u(0.02, 0.12)), h - t, h)
            visuals.append(Visual("mesh", file=ctx.meshes.add("table-top", top), color=color,
                                  name="top"))
        else:
            visuals.append(box(sx, sy, t, z=h - t / 2, color=color, name="top"))
        ls = _mm(ctx.u(0.035, 0.06))
        inset = ls / 2 + _mm(ctx.u(0.02, 0.06))
        corners = [(sxs * (sx / 2 - inset), sys_ * (sy / 2 - inset))
                   for sxs in (-1, 1) for sys_ in (-1, 1)]
        if ctx.chance(cfg.mesh_probability / 2):
            legs = merge(*[box_mesh((x, y, (h - t) / 2), (ls, ls, h - t)) for x, y in corners])
            visuals.append(Visual("mesh", file=ctx.meshes.add("table-legs", legs), color=color,
                                  name="legs"))
        else:
            visuals += [box(ls, ls, h - t, x, y, (h - t) / 2, color=color, name="leg")
                        for x, y in corners]
        surface = Surface("top", Pose(0, 0, h), _mm(sx - 0.04), _mm(sy - 0.04))
    obj = LargeObject(id=oid, type="table", name=name, pose=Pose(), model=Model(visuals),
                      affordances=["supporting_surface"], surfaces=[surface],
                      description=f"{'round ' if round_top else ''}{word}")
    mount = "wall" if kind in ("counter", "desk", "bedside", "side") and ctx.chance(0.7) else "free"
    return Piece(obj, mount, around_parking(ctx, oid, sx, sy), views=[View("top", (0.0, 0.0, h))],
                 reach=[(0.0, 0.0, h)], headroom={"top": math.inf})


def _carcass(depth, width, height, color, t=0.018, plinth=0.06, shelves=(), name_shelf="shelf"):
    """An open-fronted box (back, sides, top, bottom board over a plinth, shelves) with its
    bottom centre at the origin and its open front at x = depth/2."""
    v = [box(t, width, height, -depth / 2 + t / 2, 0, height / 2, color=color, name="back"),
         box(depth, t, height, 0, width / 2 - t / 2, height / 2, color=color, name="side"),
         box(depth, t, height, 0, -width / 2 + t / 2, height / 2, color=color, name="side"),
         box(depth, width, t, 0, 0, height - t / 2, color=color, name="top"),
         box(depth, width - 2 * t, t, 0, 0, plinth + t / 2, color=color, name="bottom")]
    if plinth > 0:
        v.append(box(depth - 0.03, width - 2 * t, plinth, -0.015, 0, plinth / 2, color=DARK,
                     name="plinth"))
    for z in shelves:
        v.append(box(depth - t - 0.01, width - 2 * t, t, -0.005 + t / 2, 0, z - t / 2, color=color,
                     name=name_shelf))
    return v


def _shelf_levels(ctx: _Ctx, bottom: float, top: float, n: int, min_gap: float = 0.22) -> list[float]:
    """Heights of ``n`` shelf tops between ``bottom`` and ``top`` (the highest at least
    ``min_gap`` under ``top``), gaps of at least ``min_gap``, unevenly spaced."""
    n = max(0, min(n, int((top - bottom) / min_gap) - 1))
    if n == 0:
        return []
    w = ctx.rng.uniform(0.7, 1.3, n + 1)
    span = top - bottom - (n + 1) * min_gap
    gaps = min_gap + span * w / w.sum()
    return [_mm(bottom + g) for g in np.cumsum(gaps)[:-1]]


def bookshelf(ctx: _Ctx) -> Piece:
    """Open shelving: 2-6 shelf levels (the bottom board 5-15 cm up, so some shelves are
    low), each a surface; sometimes mesh side panels (tapered)."""
    cfg = ctx.cfg
    D, W = _mm(ctx.u(0.25, 0.4)), _mm(ctx.u(0.5, 1.2))
    H = _mm(ctx.u(0.8, 2.0))
    t = _mm(ctx.u(0.018, 0.025))
    color = ctx.pick(WOODS + PAINTS)
    oid = ctx.ids.new("bookshelf")
    plinth = _mm(ctx.u(0.03, 0.12))
    n = ctx.i(*cfg.shelf_levels)
    levels = [_mm(plinth + t)] + _shelf_levels(ctx, plinth + t, H - t, n - 1, 0.24)
    v = _carcass(D, W, H, color, t, plinth, shelves=levels[1:])
    if ctx.chance(cfg.mesh_probability):        # tapered sides as one mesh
        v = [x for x in v if x.name != "side"]
        top_d = D * ctx.u(0.6, 1.0)
        prof = np.array([[-D / 2, 0.0], [D / 2, 0.0], [-D / 2 + top_d, H], [-D / 2, H]])
        sides = []
        for s in (1, -1):
            m = transformed(extrude(prof, -t / 2, t / 2), _Rx90(0.0, s * (W / 2 - t / 2)))
            sides.append(m)
        v.append(Visual("mesh", file=ctx.meshes.add("shelf-sides", merge(*sides)), color=color,
                        name="side"))
    surfaces, headroom = [], {}
    tops = levels + [H]
    for i, z in enumerate(levels):
        sid = "shelf_bottom" if i == 0 else f"shelf_{i}"
        surfaces.append(Surface(sid, Pose(_mm(t / 2), 0, z), _mm(D - t - 0.03), _mm(W - 2 * t - 0.02)))
        headroom[sid] = _mm(tops[i + 1] - t - z)
    open_above = set()
    if H <= 1.2:
        surfaces.append(Surface("top", Pose(0, 0, H), _mm(D - 0.02), _mm(W - 0.02)))
        headroom["top"] = math.inf
        open_above.add("top")
    obj = LargeObject(id=oid, type="bookshelf", name=ctx.ids.name(f"{ctx.room_name} bookshelf"),
                      pose=Pose(), model=Model(v), affordances=["supporting_surface"],
                      surfaces=surfaces, description=f"open shelving, {len(levels)} shelves")
    views = [View("face", (D / 2, 0.0, min(H / 2, 1.0)))]
    views += _surface_views(surfaces, headroom, D / 2, cfg, open_above)
    return Piece(obj, "free" if ctx.chance(cfg.free_standing_probability) else "wall",
                 front_parking(ctx, oid, D / 2, W), views=views,
                 reach=[(s.pose.x, s.pose.y, s.pose.z) for s in surfaces
                        if s.pose.z <= cfg.max_object_height],
                 headroom=headroom)


def _Rx90(x: float, y: float) -> np.ndarray:
    """A profile drawn in (x, z) and extruded along z, stood up: rotation about x by +90 deg
    (profile y -> up, extrusion -> -y), then moved to (x, y)."""
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    T[:3, 3] = (x, y, 0.0)
    return T


def _door_mesh(t: float, width: float, height: float, sign: int, inset: float) -> tuple:
    """A door panel with a raised frame, in the door's part frame: thickness along x centred
    on 0, from the hinge (y = 0) towards ``sign`` * y, from z = 0 up."""
    yc = sign * width / 2
    panel = box_mesh((0.0, yc, height / 2), (t, width, height))
    b, r = inset, 0.008
    frame = [box_mesh((t / 2 + r / 2, yc, b / 2), (r, width, b)),
             box_mesh((t / 2 + r / 2, yc, height - b / 2), (r, width, b)),
             box_mesh((t / 2 + r / 2, sign * b / 2, height / 2), (r, b, height - 2 * b)),
             box_mesh((t / 2 + r / 2, sign * (width - b / 2), height / 2), (r, b, height - 2 * b))]
    return merge(panel, *frame)


def _hinged_door(ctx: _Ctx, pid: str, name: str, front_x: float, hinge_y: float, width: float,
                 height: float, z0: float, side: int, color, t: float, handle_z: float,
                 vertical_handle: bool = True) -> Part:
    """A door on the front (x = ``front_x``) hinged at y = ``hinge_y`` on its ``side`` edge
    (+1: the hinge on the door's +y edge, the door reaching towards -y; -1 the other way).
    Positive joint states open it outwards; the handle is near the edge away from the hinge."""
    sign = -side
    joint = Joint("revolute", origin=Pose(_mm(front_x + t / 2 + 0.002), _mm(hinge_y), _mm(z0)),
                  axis=(0.0, 0.0, float(side)), lower=0.0,
                  upper=_deg(math.radians(ctx.u(95, 115))), state=0.0)
    if ctx.chance(ctx.cfg.mesh_probability):
        face = Visual("mesh", file=ctx.meshes.add("door", _door_mesh(t, width, height, sign,
                                                                     ctx.u(0.04, 0.08))),
                      color=color, name="face")
    else:
        face = box(t, width, height, 0, sign * width / 2, height / 2, color=color, name="face")
    standoff = _mm(ctx.u(0.025, 0.045))
    hy = sign * (width - ctx.u(0.04, 0.07))
    if vertical_handle:
        handle = Handle(f"{pid}_handle", Pose(_mm(t / 2 + standoff), _mm(hy), _mm(handle_z)),
                        radius=_mm(ctx.u(0.006, 0.012)), length=_mm(ctx.u(0.1, min(0.35, height * 0.4))),
                        standoff=standoff)
    else:
        hy = sign * (width - 0.05 - 0.06)
        handle = Handle(f"{pid}_handle", Pose(_mm(t / 2 + standoff), _mm(hy), _mm(handle_z),
                                              -math.pi / 2, 0, 0),
                        radius=_mm(ctx.u(0.006, 0.01)), length=0.1, standoff=standoff)
    return Part(pid, "door", joint, name=name, model=Model([face]), handles=[handle])


def _sliding_doors(ctx: _Ctx, oid: str, D: float, W: float, height: float, z0: float, color,
                   t: float, handle_z: float) -> list[Part]:
    """Two sliding doors on one track (a bypass wardrobe): each covers one half of the front
    (overlapping 4 cm in the middle), the left one (+y) on the outer runner, the right one on
    the inner; each slides towards the other half, over or behind the other door, so opening
    one uncovers its own half and covers nothing new (they exclude each other:
    ``Part.track``). A recessed pull near each door's outer edge. No random draw: the rest of
    the home as a hinged wardrobe's."""
    dw = _mm(W / 2 + 0.02)
    travel = _mm(W / 2 - 0.02)
    track = f"{oid}_track"
    pull = (0.12, 0.12, 0.13)
    out = []
    for side, name, x in ((+1, "left", D / 2 + 1.5 * t + 0.006), (-1, "right", D / 2 + t / 2 + 0.002)):
        pid = f"{oid}_door_{name}"
        joint = Joint("prismatic", origin=Pose(_mm(x), _mm(side * W / 4), _mm(z0)),
                      axis=(0.0, float(-side), 0.0), lower=0.0, upper=travel, state=0.0)
        face = box(t, dw, height, 0, 0, height / 2, color=color, name="face")
        handle = Handle(f"{pid}_pull", Pose(_mm(t / 2), _mm(side * (dw / 2 - 0.05)), _mm(handle_z)),
                        radius=0.015, length=0.14, standoff=0.01, color=pull, material="matte",
                        handle_kind="recessed")
        out.append(Part(pid, "door", joint, name=f"{name} sliding door", model=Model([face]),
                        handles=[handle], track=track))
    return out


def cupboard(ctx: _Ctx, kind: str = "cupboard", sliding: bool = False) -> Piece:
    """A cupboard with one door (hinged left or right) or two (hinged at the outer edges),
    1-3 shelves inside; ``kind``: cupboard (low, or tall with some probability), wardrobe
    (tall), sideboard (low, wide), cabinet (wall-mounted). ``sliding``: two sliding doors on
    one track instead (``_sliding_doors``)."""
    cfg = ctx.cfg
    wall = kind == "cabinet"
    tall = kind == "wardrobe" or (kind == "cupboard" and ctx.chance(cfg.tall_cupboard_probability))
    two = kind in ("wardrobe", "sideboard") or (not wall and ctx.chance(cfg.two_door_probability))
    D = _mm(ctx.u(0.3, 0.4) if wall else ctx.u(0.4, 0.6))
    W = _mm(ctx.u(0.8, 1.2) if two else ctx.u(0.4, 0.6))
    H = _mm(ctx.u(0.5, 0.75) if wall else ctx.u(1.6, 2.1) if tall else ctx.u(0.7, 1.0))
    lift = _mm(ctx.u(0.9, 1.1)) if wall else 0.0
    t, dt = 0.018, _mm(ctx.u(0.018, 0.025))
    plinth = 0.0 if wall else _mm(ctx.u(0.04, 0.1))
    color = ctx.pick(PAINTS + WOODS[:3])
    oid = ctx.ids.new(kind)
    n_shelves = ctx.i(1, 3 if tall else 2) if H - plinth > 0.5 else 0
    shelves = _shelf_levels(ctx, plinth + t, H - t, n_shelves, 0.22)
    v = _carcass(D, W, H, color, t, plinth, shelves=shelves)
    # The interior, as seen by a camera: absolute heights for the small objects' surfaces.
    levels = [plinth + t] + shelves
    tops = levels + [H - t]
    surfaces, headroom = [], {}
    for i, z in enumerate(levels):
        sid = "inside_bottom" if i == 0 else f"shelf_{i}"
        surfaces.append(Surface(sid, Pose(_mm(t / 2), 0, _mm(z)), _mm(D - t - 0.04),
                                _mm(W - 2 * t - 0.04), "in"))
        headroom[sid] = _mm(tops[i + 1] - (t if i + 1 < len(levels) else 0) - z)
    open_above = set()
    if not wall and not tall:
        surfaces.append(Surface("top", Pose(0, 0, H), _mm(D - 0.04), _mm(W - 0.04)))
        headroom["top"] = math.inf
        open_above.add("top")
    door_h = _mm(H - plinth - 0.01)
    handle_z = _mm(min(door_h * ctx.u(0.55, 0.8), 1.05 - plinth) if not wall else door_h * ctx.u(0.12, 0.3))
    door_color = color if ctx.chance(0.7) else ctx.pick(PAINTS)
    vertical = ctx.chance(0.8)
    parts = []
    if sliding:
        parts = _sliding_doors(ctx, oid, D, W, door_h, plinth + 0.005, door_color, dt, handle_z)
    elif two:
        dw = _mm(W / 2 - 0.004)
        parts.append(_hinged_door(ctx, f"{oid}_door_left", "left door", D / 2, W / 2, dw, door_h,
                                  plinth + 0.005, +1, door_color, dt, handle_z, vertical))
        parts.append(_hinged_door(ctx, f"{oid}_door_right", "right door", D / 2, -W / 2, dw,
                                  door_h, plinth + 0.005, -1, door_color, dt, handle_z, vertical))
    else:
        side = ctx.pick([+1, -1])
        parts.append(_hinged_door(ctx, f"{oid}_door", "door", D / 2, side * W / 2, _mm(W - 0.006),
                                  door_h, plinth + 0.005, side, door_color, dt, handle_z, vertical))
    names = {"cupboard": "cupboard", "wardrobe": "wardrobe", "sideboard": "sideboard",
             "cabinet": "wall cabinet"}
    obj = LargeArticulatedObject(
        id=oid, type=kind, name=ctx.ids.name(f"{ctx.room_name} {names[kind]}"), pose=Pose(),
        model=Model(v), affordances=["container", "openable"], surfaces=surfaces, parts=parts,
        description=f"{'tall ' if tall else ''}{names[kind]}, {len(parts)} "
                    f"{'sliding ' if sliding else ''}door{'s' if two else ''}")
    front = D / 2 + dt + 0.002 + (dt + 0.004 if sliding else 0.0)
    views = [View("face", (front, 0.0, lift + min(H / 2, 1.0)))]
    views += _surface_views(_lifted(surfaces, lift), headroom, D / 2, cfg, open_above)
    reach = [tuple(_handle_point(p, lift)) for p in parts]
    piece = Piece(obj, "free" if not wall and ctx.chance(cfg.free_standing_probability) else "wall",
                  front_parking(ctx, oid, front, W), views=views, reach=reach, headroom=headroom,
                  lift=lift)
    return piece


def _lifted(surfaces: list[Surface], lift: float) -> list[Surface]:
    return [replace(s, pose=replace(s.pose, z=s.pose.z + lift)) for s in surfaces]


def _handle_point(part: Part, lift: float = 0.0) -> np.ndarray:
    o = part.joint.origin
    h = part.handles[0].pose
    return np.array([o.x + h.x, o.y + h.y, lift + o.z + h.z])


#: A top drawer gets a floor that may hold small objects when its floor is at most this high
#: (m): the head camera (1.3 m up) looks into it from the parking position once it is open.
DRAWER_FLOOR_MAX = 0.95


def drawer_unit(ctx: _Ctx, kind: str = "drawers") -> Piece:
    """1-4 drawers of different heights (prismatic parts sliding out along +x, a bar handle
    each); a surface on top when the unit is low; the top drawer's floor a surface of its
    part (``DRAWER_FLOOR_MAX``)."""
    cfg = ctx.cfg
    D, W = _mm(ctx.u(0.4, 0.55)), _mm(ctx.u(0.4, 0.9))
    n = ctx.i(*cfg.drawers)
    H = _mm(ctx.u(max(0.45, 0.18 * n + 0.2), 1.1))
    plinth, t = _mm(ctx.u(0.03, 0.08)), 0.018
    color = ctx.pick(PAINTS + WOODS)
    oid = ctx.ids.new("drawers" if kind == "drawers" else kind)
    v = _carcass(D, W, H, color, t, plinth)
    room = H - plinth - t - 0.01
    w = ctx.rng.uniform(0.6, 1.6, n)
    heights = [_mm(x) for x in room * w / w.sum()]
    parts, z = [], plinth + 0.005
    drawer_headroom: dict[str, float] = {}
    front_t = _mm(ctx.u(0.018, 0.025))
    hcolor = ctx.pick([(0.75, 0.75, 0.78), (0.2, 0.2, 0.2), (0.8, 0.65, 0.3)])
    for i, dh in enumerate(heights):
        pid = f"{oid}_drawer_{i + 1}"
        fh = dh - 0.006
        tray_d = D - 0.06
        model = [box(front_t, W - 0.008, fh, 0, 0, fh / 2, color=color, name="face"),
                 box(tray_d, W - 0.06, 0.012, -tray_d / 2 - front_t / 2, 0, 0.03, color=color),
                 box(tray_d, 0.012, fh * 0.6, -tray_d / 2 - front_t / 2, W / 2 - 0.04, fh * 0.3 + 0.03, color=color),
                 box(tray_d, 0.012, fh * 0.6, -tray_d / 2 - front_t / 2, -W / 2 + 0.04, fh * 0.3 + 0.03, color=color)]
        standoff = _mm(ctx.u(0.025, 0.04))
        handle = Handle(f"{pid}_handle", Pose(_mm(front_t / 2 + standoff), 0.0,
                                              _mm(fh * ctx.u(0.5, 0.8)), -math.pi / 2, 0, 0),
                        radius=_mm(ctx.u(0.006, 0.01)), length=_mm(min(W * ctx.u(0.2, 0.6), fh * 3 + 0.1)),
                        standoff=standoff, color=hcolor)
        joint = Joint("prismatic", origin=Pose(_mm(D / 2 + front_t / 2 + 0.002), 0.0, _mm(z)),
                      axis=(1.0, 0.0, 0.0), lower=0.0, upper=_mm(D * 0.75), state=0.0)
        floor = []
        if i == n - 1 and z + 0.036 <= DRAWER_FLOOR_MAX:
            # the top drawer: looked into from above once open, so it may hold small objects
            # (its floor, part frame: moves with the drawer; no random draw, the rest of the
            # home as before)
            floor = [Surface(f"drawer_{i + 1}_floor", Pose(_mm(-tray_d / 2 - front_t / 2), 0.0, 0.036),
                             _mm(tray_d - 0.03), _mm(W - 0.09), "in")]
            drawer_headroom[floor[0].id] = _mm(fh - 0.036 - 0.01)
        parts.append(Part(pid, "drawer", joint, name=f"drawer {i + 1} from the bottom",
                          model=Model(model), handles=[handle], surfaces=floor))
        z += dh
    surfaces, headroom, open_above = [], dict(drawer_headroom), set()
    if H <= 1.1:
        surfaces.append(Surface("top", Pose(0, 0, H), _mm(D - 0.04), _mm(W - 0.04)))
        headroom["top"], open_above = math.inf, {"top"}
    names = {"drawers": "chest of drawers", "bedside": "bedside drawers"}
    obj = LargeArticulatedObject(
        id=oid, type="drawers", name=ctx.ids.name(f"{ctx.room_name} {names.get(kind, kind)}"),
        pose=Pose(), model=Model(v), affordances=["container", "openable"], surfaces=surfaces,
        parts=parts, description=f"{n} drawer{'s' if n > 1 else ''}")
    front = D / 2 + front_t + 0.002
    views = [View("face", (front, 0.0, min(H / 2, 1.0)))]
    views += _surface_views(surfaces, headroom, D / 2, cfg, open_above)
    return Piece(obj, "free" if ctx.chance(cfg.free_standing_probability) else "wall",
                 front_parking(ctx, oid, front, W), views=views,
                 reach=[tuple(_handle_point(p)) for p in parts], headroom=headroom)


def fridge(ctx: _Ctx) -> Piece:
    """A fridge: one full-height door or a fridge door over a freezer door, hinged on the
    same side (left or right), shelves inside."""
    cfg = ctx.cfg
    D, W, H = _mm(ctx.u(0.58, 0.7)), _mm(ctx.u(0.55, 0.75)), _mm(ctx.u(1.4, 1.9))
    color, material = ctx.pick([(STEEL, "matte"), (WHITE, "matte"), (STEEL, "shiny"),
                                ((0.2, 0.2, 0.22), "matte"), ((0.85, 0.2, 0.18), "matte")])
    oid = ctx.ids.new("fridge")
    plinth, t = 0.04, 0.02
    two = ctx.chance(0.5)
    split = _mm(ctx.u(0.55, 0.8)) if two else plinth
    shelves = _shelf_levels(ctx, split + t, H - t, ctx.i(2, 3), 0.22)
    v = _carcass(D, W, H, color, t, plinth, shelves=shelves)
    if two:
        v.append(box(D - t - 0.01, W - 2 * t, t, -0.005 + t / 2, 0, split - t / 2, color=color,
                     name="divider"))
    levels = [split if two else plinth + t] + shelves     # the divider's top, or the bottom board's
    tops = levels + [H - t]
    surfaces, headroom = [], {}
    for i, z in enumerate(levels):
        sid = f"shelf_{i + 1}"
        surfaces.append(Surface(sid, Pose(_mm(t / 2), 0, _mm(z)), _mm(D - t - 0.06),
                                _mm(W - 2 * t - 0.04), "in"))
        headroom[sid] = _mm(tops[i + 1] - t - z)
    side = ctx.pick([+1, -1])
    dt = _mm(ctx.u(0.03, 0.05))
    parts = []
    main_h = _mm(H - split - 0.01)
    parts.append(_hinged_door(ctx, f"{oid}_door", "fridge door", D / 2, side * W / 2, _mm(W - 0.006),
                              main_h, split + 0.005, side, color, dt, _mm(min(main_h * 0.5, 1.05 - split)), True))
    if two:
        parts.append(_hinged_door(ctx, f"{oid}_freezer_door", "freezer door", D / 2, side * W / 2,
                                  _mm(W - 0.006), _mm(split - plinth - 0.01), plinth + 0.005, side,
                                  color, dt, _mm((split - plinth) * 0.75), True))
    for p in parts:
        p.model.visuals[0].material = material
    obj = LargeArticulatedObject(
        id=oid, type="fridge", name=ctx.ids.name(f"{ctx.room_name} fridge"), pose=Pose(),
        model=Model(v), affordances=["container", "openable"], surfaces=surfaces, parts=parts,
        description="fridge-freezer" if two else "fridge")
    front = D / 2 + dt + 0.002
    views = [View("face", (front, 0.0, 1.0))]
    views += _surface_views(surfaces, headroom, D / 2, cfg, set())
    return Piece(obj, "wall", front_parking(ctx, oid, front, W), views=views,
                 reach=[tuple(_handle_point(p)) for p in parts], headroom=headroom)


def _knob_states(ctx: _Ctx, symmetry: int = 1) -> tuple[list[KnobState], str, bool, float]:
    """2-12 discrete states turning either way; the off state named one of OFF_NAMES, at
    angle 0 or not, listed first, last or in the middle. A knob whose shape repeats every
    360/``symmetry`` degrees keeps all its states within that (so no two look the same).
    Returns (states in file order, off state name, whether the off state must be named
    explicitly, the direction it turns: -1 clockwise, +1 counter-clockwise)."""
    n = ctx.i(*ctx.cfg.knob_states)
    off = ctx.pick(OFF_NAMES)
    style = ctx.pick(["digits", "temperatures", "words", "digits max"])
    if style == "words" and n <= 4:
        others = ["low", "medium", "high"][:n - 1]
    elif style == "temperatures" and n <= 10:
        start = ctx.pick([50, 80, 100])
        others = [str(start + 25 * i) for i in range(n - 1)]
    elif style == "digits max" and n >= 3:
        others = [str(i) for i in range(1, n - 1)] + ["max"]
    else:
        others = [str(i) for i in range(1, n)]
    if off in others:
        off = "off"
    if off == "min":                          # "min" cannot sit beside "max" as its opposite
        others = [o for o in others if o != "max"] + (["high"] if "max" in others else [])
        if len(set(others)) < len(others):
            others = [str(i) for i in range(1, n)]
    direction = ctx.pick([-1.0, 1.0])
    step = math.radians(ctx.u(20, 45))
    step = min(step, math.radians(300) / max(n - 1, 1))
    if symmetry > 1:
        step = min(step, math.radians(340 / symmetry) / n)
    a0 = 0.0 if ctx.chance(0.75) else ctx.pick([-1.0, 1.0]) * math.radians(ctx.pick([30, 45, 90]))
    if abs(a0) > 0 and abs(a0) + step * (n - 1) > math.radians(320):
        a0 = 0.0
    off_state = KnobState(off, _deg(a0))
    drng = ctx.design_rng or ctx.rng     # knob design draws: the rest of the home unchanged
    if len(others) >= 2 and drng.random() < ctx.cfg.off_mid_travel_probability:
        # off in the middle of the travel (a selector: settings either side of off); such a
        # knob turns either way (``direction`` 0)
        k = int(drng.integers(1, len(others)))
        states = ([KnobState(nm, _deg(a0 - direction * step * (k - i))) for i, nm in enumerate(others[:k])]
                  + [KnobState(nm, _deg(a0 + direction * step * (i + 1))) for i, nm in enumerate(others[k:])])
        return states[:k] + [off_state] + states[k:], off, True, 0.0
    states = [KnobState(nm, _deg(a0 + direction * step * (i + 1))) for i, nm in enumerate(others)]
    order = ctx.rng.random()
    if order < 0.6:
        listed = [off_state] + states
    elif order < 0.85:
        listed = states + [off_state]
    else:
        k = ctx.i(1, max(1, len(states) - 1)) if len(states) > 1 else 1
        listed = states[:k] + [off_state] + states[k:]
    explicit = not (off == "off" and listed[0] is off_state and ctx.chance(0.5))
    return listed, off, explicit, direction


#: The knob design space ``_knob_design`` draws from (docs/world-format.md, "Knobs"): a knob is
#: a base (BASE_TYPES: none, a disc or a skirt turning with it, a bezel fixed on the panel) at a
#: stand-off from the panel (flush to a few mm), a grip (GRIP_TYPES) and a marker
#: (MARKER_TYPES: a line, a dot, a tip at the end of a bar or fin, a printed pointer, or none
#: of its own: a fixed printed dial ring with ticks around a grip whose shape shows its angle,
#: or the shape alone), in materials (MATERIAL_STYLES: a marker that stands out, low
#: contrast, dark on dark, metallic). ``plain_probability`` of knobs are the format-1 knob.
#: Until generator version 4 the knobs came in five families (plain, bar, tip, pointer, skirt).
KNOB_FAMILIES = ("plain", "bar", "tip", "pointer", "skirt")
BASE_TYPES = ("none", "disc", "skirt", "bezel")
GRIP_TYPES = ("cylinder", "bar", "fin", "d-shape", "knurled", "tapered")
MARKER_TYPES = ("line", "dot", "tip", "printed", "dial", "none")
MATERIAL_STYLES = ("contrast", "low-contrast", "dark-on-dark", "metallic")
#: markers each grip can carry: a round grip needs a marker of its own; a bar or fin alone
#: reads modulo half a turn (symmetry 2); a D shows its angle by its flat
_MARKERS_OF = {"cylinder": ("line", "dot", "printed"), "knurled": ("line", "dot", "printed"),
               "tapered": ("line", "dot", "printed"), "bar": ("tip", "line", "printed", "dial", "none"),
               "fin": ("tip", "line", "dial", "none"), "d-shape": ("line", "dot", "printed", "dial", "none")}
_KNOB_COLOURS = [(0.9, 0.9, 0.88), (0.08, 0.08, 0.09), (0.74, 0.75, 0.77), (0.93, 0.88, 0.75),
                 (0.15, 0.15, 0.16), (0.55, 0.56, 0.6)]
_MARKER_COLOURS = [(0.85, 0.1, 0.1), (0.95, 0.55, 0.05), (0.1, 0.35, 0.85), (0.05, 0.05, 0.05),
                   (0.95, 0.95, 0.92)]
_METALLIC = [(0.74, 0.75, 0.77), (0.82, 0.82, 0.84), (0.62, 0.6, 0.55)]


def _distinct(a, b, by: float = 0.6) -> bool:
    """Colours the eye tells apart (L1 distance of RGB over ``by``)."""
    return sum(abs(x - y) for x, y in zip(a, b)) > by


def _contrast(drng, body, palette):
    """A colour of ``palette`` that differs from ``body`` (a marker the eye can tell)."""
    ok = [c for c in palette if _distinct(c, body)] or palette
    return ok[int(drng.integers(len(ok)))]


def _near_colour(drng, body, lo: float = 0.3, hi: float = 0.45):
    """A colour of low contrast with ``body``: every channel moved the same way (lighter on a
    dark body, darker on a light one), L1 distance ``lo``-``hi`` in all."""
    d = float(drng.uniform(lo, hi)) / 3
    sign = 1.0 if sum(body) < 1.5 else -1.0
    return tuple(round(min(1.0, max(0.0, c + sign * d)), 3) for c in body)


def _colours(drng, style: str):
    """(body, grip, marker, material) of a material style (MATERIAL_STYLES)."""
    if style == "metallic":
        body = _METALLIC[int(drng.integers(len(_METALLIC)))]
        mark = _contrast(drng, body, _MARKER_COLOURS) if drng.random() < 0.6 else _near_colour(drng, body, 0.35, 0.5)
        return body, body, mark, "shiny"
    if style == "dark-on-dark":
        body = (0.08, 0.08, 0.09) if drng.random() < 0.5 else (0.15, 0.15, 0.16)
        return body, body, _near_colour(drng, body, 0.3, 0.45), "matte"
    body = _KNOB_COLOURS[int(drng.integers(len(_KNOB_COLOURS)))]
    if style == "low-contrast":
        return body, body, _near_colour(drng, body), "matte"
    grip = body if drng.random() < 0.6 else _contrast(drng, body, _KNOB_COLOURS)
    mark = _contrast(drng, body, _MARKER_COLOURS)
    if not _distinct(mark, grip):
        mark = next(c for c in _MARKER_COLOURS if _distinct(c, body) and _distinct(c, grip))
    return body, grip, mark, "matte"


def _grip_mesh(ctx: _Ctx, kind: str, rg: float, z0: float, z1: float, drng):
    """The grip of ``kind`` (mesh grips) of radius ``rg`` from z0 to z1 (knob frame)."""
    rg = rg - 0.0002            # within rg once the vertices are rounded to 0.1 mm
    if kind == "d-shape":
        cut = rg * float(drng.uniform(0.45, 0.7))       # the flat, towards -y (the back of the D)
        t0 = -math.asin(cut / rg)
        ts = np.linspace(t0, math.pi - t0, 16)          # the round part through +y
        rq = rg
        poly = [(round(rq * math.cos(t), 4), round(rq * math.sin(t), 4)) for t in ts]
        poly += [(round(-rq * math.cos(t0), 4), round(-cut, 4)), (round(rq * math.cos(t0), 4), round(-cut, 4))]
        return ctx.meshes.add("knob-d", extrude(_ccw(poly), z0, z1))
    if kind == "knurled":
        n = int(drng.integers(16, 31))
        a = np.linspace(0, TAU, 2 * n, endpoint=False)
        rr = np.where(np.arange(2 * n) % 2 == 0, rg, rg * 0.93)
        poly = np.c_[rr * np.cos(a), rr * np.sin(a)]
        return ctx.meshes.add("knob-knurled", fan_prism(np.round(poly, 4), z0, z1))
    top = rg * float(drng.uniform(0.6, 0.8))           # tapered: narrower at its front
    return ctx.meshes.add("knob-tapered", frustum(rg, top, z0, z1))


def _knob_design(ctx: _Ctx, r: float, depth: float) -> dict:
    """The shape fields of a ``Knob`` drawn from the design space (above) with outline radius
    ``r`` and front ``depth`` (m): base, grip and marker models in the knob frame at angle 0
    (+y: the pointer), base_fixed, symmetry; and ``design`` (what was drawn, for the docs and
    the bench). Everything comes from ``design_rng``."""
    drng = ctx.design_rng or ctx.rng
    u = lambda lo, hi: float(drng.uniform(lo, hi))
    pick = lambda seq: seq[int(drng.integers(len(seq)))]
    grip_kind = pick(GRIP_TYPES)
    marker_kind = pick(_MARKERS_OF[grip_kind])
    base_kind = pick(BASE_TYPES)
    if marker_kind == "dial":
        base_kind = "bezel"                              # the printed ring stays on the panel
    style = pick(MATERIAL_STYLES)
    if marker_kind in ("tip", "printed") and style in ("low-contrast", "dark-on-dark"):
        # a tip is the bar's own end and a printed pointer has no relief: only their colour
        # tells them
        style = "contrast"
    body, grip_c, mark, material = _colours(drng, style)
    standoff = 0.0 if drng.random() < 0.5 else _mm(u(0.0005, 0.003))   # flush .. 3 mm off
    # the base: how thick it is (a flat disc down to 1 mm) and how wide the grip on it is
    hb = {"none": 0.0, "disc": _mm(max(0.001, depth * u(0.05, 0.4))),
          "skirt": _mm(depth * u(0.25, 0.45)), "bezel": _mm(u(0.001, 0.004))}[base_kind]
    rg = r if base_kind == "none" else r * (u(0.55, 0.75) if base_kind in ("skirt", "bezel") else u(0.7, 0.95))
    if grip_kind in ("bar", "fin") and base_kind in ("disc", "none"):
        rg = 0.95 * r                                    # a bar across its disc
    z_base0 = 0.0 if base_kind == "bezel" else standoff  # a bezel sits on the panel
    z_grip0 = standoff + (hb if base_kind in ("disc", "skirt") else 0.0)
    z_grip0 = max(z_grip0, hb if base_kind == "bezel" else 0.0)
    z1 = max(depth, z_grip0 + 0.004)
    hg = z1 - z_grip0
    zc = z_grip0 + hg / 2
    sym = 1
    out: dict = dict(design=dict(base=base_kind, grip=grip_kind, marker=marker_kind, material=style,
                                 standoff_mm=round(standoff * 1000, 1)))
    base_vis = []
    if base_kind != "none":
        ring_c = body if base_kind != "bezel" else _contrast(drng, body, _KNOB_COLOURS)
        base_vis.append(cyl(r, hb, z=z_base0 + hb / 2, color=ring_c, material=material, name=base_kind))
        if marker_kind == "dial":
            # ticks printed on the fixed ring between the grip and its rim, every 30 degrees
            # or at 8-12 evenly spaced places; numbers are ticks of another length here
            n_ticks = int(drng.integers(8, 13))
            tick_c = _contrast(drng, ring_c, _MARKER_COLOURS)
            tl = (r - rg) * 0.6
            for i in range(n_ticks):
                a = TAU * i / n_ticks
                ym = rg + (r - rg) * 0.5
                base_vis.append(Visual("box", Pose(_mm(-ym * math.sin(a)), _mm(ym * math.cos(a)),
                                                   _mm(z_base0 + hb + 0.00015), 0, 0, round(a, 4)),
                                       size=(_mm(max(0.0008, r * 0.05)), _mm(max(tl, 0.002)), 0.0003),
                                       color=tick_c, name="tick"))
    if grip_kind == "cylinder":
        grip = cyl(rg, hg, z=zc, color=grip_c, material=material, name="cylinder")
        top_r = rg
    elif grip_kind in ("bar", "fin"):
        w = r * (u(0.28, 0.4) if grip_kind == "bar" else u(0.1, 0.18))
        length = 2 * rg
        if marker_kind == "tip":
            tl = r * u(0.25, 0.4)
            grip = box(w, length - tl, hg, y=-tl / 2, z=zc, color=grip_c, material=material, name=grip_kind)
        else:
            grip = box(w, length, hg, z=zc, color=grip_c, material=material, name=grip_kind)
        top_r = w / 2
        if marker_kind in ("dial", "none"):
            sym = 2
    else:
        grip = Visual("mesh", file=_grip_mesh(ctx, grip_kind, rg, z_grip0, z1, drng), color=grip_c,
                      material=material, name=grip_kind)
        top_r = rg * (0.6 if grip_kind == "tapered" else 0.95)
    # the grip's top as built (a primitive's centre and size are rounded to the millimetre:
    # a marker put on the unrounded top was buried half a millimetre inside the grip on
    # some knobs, generator versions 5 and 6)
    if grip.shape == "cylinder":
        z1 = grip.pose.z + grip.length / 2
    elif grip.shape == "box":
        z1 = grip.pose.z + grip.size[2] / 2
    marker = None
    # a marker of little contrast stands proud of the grip (a raised ridge or bump: what
    # makes a dark-on-dark knob readable to a person, by its shading and its relief); one
    # that stands out in colour is printed or inlaid, half a millimetre proud
    proud = _mm(u(0.0015, 0.003)) if style in ("low-contrast", "dark-on-dark") else 0.0005
    zt = z1 + proud / 2
    if marker_kind == "line":
        if grip_kind in ("bar", "fin"):
            lw = min(w * 0.5, r * 0.12)
            marker = box(lw, rg * 0.7, proud, y=rg * 0.5, z=zt, color=mark, name="line")
        else:
            marker = box(max(0.0015, top_r * 0.14), top_r * 0.6, proud, y=top_r * 0.5, z=zt,
                         color=mark, name="line")
    elif marker_kind == "dot":
        rd = max(0.002, top_r * u(0.15, 0.25))
        marker = cyl(rd, proud, y=top_r - 1.4 * rd, z=zt, color=mark, name="dot")
    if marker_kind in ("line", "dot"):
        marker = replace(marker, pose=replace(marker.pose, z=round(zt, 5)))
    elif marker_kind == "tip":
        marker = box(w, tl, hg, y=rg - tl / 2, z=zc, color=mark, material=material, name="tip")
    elif marker_kind == "printed":
        half = max(0.001, top_r * 0.18)
        tri = [(-half, 0.0), (half, 0.0), (0.0, 0.9 * top_r if grip_kind not in ("bar", "fin") else 0.9 * rg)]
        marker = Visual("mesh", file=ctx.meshes.add("knob-printed", extrude(_ccw(tri), z1, z1 + 0.0003)),
                        color=mark, name="printed")
    out.update(base=Model(base_vis) if base_vis else None, grip=Model([grip]),
               marker=Model([marker]) if marker is not None else None,
               base_fixed=base_kind == "bezel", symmetry=sym)
    return out


def _ccw(poly):
    """The polygon's points ordered counter-clockwise about their centroid (a convex one)."""
    P = np.asarray(poly, dtype=float)
    c = P.mean(axis=0)
    order = np.argsort(np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0]))
    return [tuple(P[i]) for i in order]


def _knobs(ctx: _Ctx, oid: str, count: int, place: Callable[[int], Pose],
           max_radius: float, pitch: Optional[float] = None) -> list[Knob]:
    """``count`` knobs of one design (radius at most ``max_radius``); ``place(i)`` gives the
    i-th knob's pose, ``pitch`` (m, given for a row along y) the distance between neighbours.
    The design's family (KNOB_FAMILIES), colours and proportions, and whether a row is
    packed (closed up to 2-2.2 radii apart, centred) come from ``ctx.design_rng``. Each knob has its own
    states; most are off."""
    _, body, marker, rr, dr = ctx.pick(KNOB_DESIGNS)
    r, depth = _mm(min(ctx.u(*rr), max_radius)), _mm(ctx.u(*dr))
    drng = ctx.design_rng
    design, turn_stop, packed = {}, False, None
    if drng is not None:
        turn_stop = bool(drng.random() < 0.5)
        if pitch is not None and drng.random() < 0.3:
            packed = r * float(drng.uniform(2.0, 2.2))      # the row closed up, centred
        if drng.random() >= ctx.cfg.plain_knob_probability:
            design = _knob_design(ctx, r, depth)
    design.pop("design", None)

    def pose(i: int) -> Pose:
        p = place(i)
        return p if packed is None else replace(p, y=_mm(((count - 1) / 2 - i) * packed))
    sym = design.get("symmetry", 1)
    out = []
    for i in range(count):
        states, off, explicit, direction = _knob_states(ctx, sym)
        on = ctx.chance(ctx.cfg.knob_on_probability)
        choices = [s for s in states if (s.name != off) == on] or states
        st = choices[int(ctx.rng.integers(len(choices)))]
        turns = ("clockwise" if direction < 0 else "counterclockwise") if turn_stop and direction else "either"
        out.append(Knob(f"{oid}_knob_{i + 1}", pose(i), states, st.name, angle=st.angle,
                        radius=r, depth=depth, color=body, marker_color=marker,
                        off_state=off if explicit else "", turns=turns, **design))
    return out


def appliance(ctx: _Ctx, kind: str, n_knobs: int) -> Piece:
    """An oven (a door hinged at the bottom, a knob panel above it), a cooker (an oven with a
    hob on top) or a hob (a counter unit with a hob on top and a side-hinged door; its knobs
    on the top or on a front panel).

    The front is flush (body, door and panel in one plane: the door and the panel sit in a
    recess of the body as deep as the door is thick) or stepped (the door stands out of the
    body and panel, or the panel stands out further than the door)."""
    cfg = ctx.cfg
    D, W, H = _mm(ctx.u(0.55, 0.65)), _mm(ctx.u(0.5, 0.9)), _mm(ctx.u(0.85, 0.95))
    oid = ctx.ids.new(kind)
    color, material = ctx.pick([(STEEL, "matte"), (WHITE, "matte"), (DARK, "matte"),
                                (STEEL, "shiny"), ((0.85, 0.84, 0.8), "matte")])
    flush = ctx.chance(cfg.flush_front_probability)
    top_knobs = kind == "hob" and ctx.chance(cfg.top_knobs_probability)
    t = _mm(ctx.u(0.02, 0.035))                 # door (and flush panel) thickness
    panel_h = 0.0 if top_knobs else _mm(ctx.u(0.1, 0.16))
    z0 = _mm(ctx.u(0.06, 0.12))                 # the door's bottom edge
    # an oven whose knob panel is below its door, knobs at 0.25-0.35 m (z0: the panel's
    # bottom edge then), or one raised in a tall unit, knobs up to 1.4 m
    # (drawn from the knob designs' generator: the rest of the home stays as it was)
    drng = ctx.design_rng or ctx.rng
    panel_low = kind == "oven" and bool(panel_h) and drng.random() < cfg.low_panel_probability
    if panel_low:
        z0 = _mm(float(drng.uniform(0.18, 0.26)))
    lift = (_mm(float(drng.uniform(0.3, 0.5))) if kind == "oven" and not panel_low
            and drng.random() < cfg.raised_oven_probability else 0.0)
    panel_zc = z0 + panel_h / 2 if panel_low else H - panel_h / 2
    door_z0 = _mm(z0 + panel_h + 0.01) if panel_low else z0
    front = D / 2
    panel_color = ctx.pick([DARK, color, BLACK])
    v: list[Visual] = []
    if flush:
        v.append(box(D - t, W, H, -t / 2, 0, H / 2, color=color, material=material, name="body"))
        v.append(box(t, W, z0, front - t / 2, 0, z0 / 2, color=color, material=material,
                     name="plinth"))
        if panel_h:
            v.append(box(t, W, panel_h, front - t / 2, 0, panel_zc, color=panel_color,
                         name="panel"))
        knob_x, door_x, face_x = front, front - t / 2, front
    else:
        v.append(box(D, W, H, 0, 0, H / 2, color=color, material=material, name="body"))
        door_x = front + 0.002 + t / 2
        if ctx.chance(0.5) and panel_h:         # the panel stands out further than the door
            out = _mm(t + ctx.u(0.015, 0.04))
        else:                                   # the door stands out; a thin panel plate
            out = 0.004
        if panel_h:
            v.append(box(out, W, panel_h, front + out / 2, 0, panel_zc, color=panel_color,
                         name="panel"))
        knob_x = front + (out if panel_h else 0.0)
        face_x = max(front + 0.002 + t, knob_x)
    hob_h = 0.0
    if kind in ("cooker", "hob"):
        hob_h = 0.008
        v.append(box(D - 0.02, W - 0.02, hob_h, 0, 0, H + hob_h / 2, color=BLACK, name="hob"))
        for x, y in [(x, y) for x in (-0.14, 0.06) for y in (-W / 4, W / 4)][:ctx.i(2, 4)]:
            v.append(cyl(_mm(ctx.u(0.06, 0.09)), 0.003, x, y, H + hob_h + 0.0015,
                         color=(0.3, 0.3, 0.32), name="burner"))
    door_top = H - 0.01 if panel_low else H - panel_h - 0.01
    if kind in ("oven", "cooker"):
        door_h = _mm(door_top - door_z0)
        door_color, door_mat = ctx.pick([(DARK, "shiny"), (BLACK, "glass"), (color, material),
                                         (DARK, "matte")])
        if ctx.chance(cfg.mesh_probability):
            face = Visual("mesh", file=ctx.meshes.add("oven-door", _oven_door_mesh(t, W - 0.01, door_h)),
                          color=door_color, material=door_mat, name="face")
        else:
            face = box(t, W - 0.01, door_h, 0, 0, door_h / 2, color=door_color, material=door_mat,
                       name="face")
        standoff = _mm(ctx.u(0.025, 0.045))
        handle = Handle(f"{oid}_door_handle",
                        Pose(_mm(t / 2 + standoff), 0.0, _mm(door_h - ctx.u(0.04, 0.08)), -math.pi / 2, 0, 0),
                        radius=_mm(ctx.u(0.008, 0.012)), length=_mm(W * ctx.u(0.5, 0.8)),
                        standoff=standoff)
        door = Part(f"{oid}_door", "door",
                    Joint("revolute", origin=Pose(_mm(door_x), 0.0, door_z0), axis=(0.0, 1.0, 0.0),
                          lower=0.0, upper=_deg(math.radians(ctx.u(85, 95))), state=0.0),
                    name="oven door", model=Model([face]), handles=[handle])
    else:
        side = ctx.pick([+1, -1])
        door = _hinged_door(ctx, f"{oid}_door", "door", door_x - t / 2 - 0.002, side * W / 2,
                            _mm(W - 0.006), _mm(door_top - door_z0), door_z0, side, color, t,
                            _mm((door_top - door_z0) * 0.8))
        door.model.visuals[0].material = material
    # Knobs in a row, centred: on the front panel, or on the top near the front edge.
    span = W - 0.12
    ky = [_mm(span / 2 - span * (i + 0.5) / n_knobs) for i in range(n_knobs)]
    pitch = span / n_knobs
    max_r = min(pitch / 2.4, (panel_h / 2 - 0.01) if panel_h else 0.03)
    if top_knobs:
        kx, kz = _mm(front - ctx.u(0.05, 0.08)), _mm(H + hob_h)
        knobs = _knobs(ctx, oid, n_knobs, lambda i: Pose(kx, ky[i], kz, 0, 0, math.pi / 2), max_r,
                       pitch)
        knob_view = View("knobs", (kx, 0.0, kz), (0.0, 0.0, 1.0), max_angle=math.radians(62))
    else:
        kx, kz = _mm(knob_x), _mm(panel_zc)
        knobs = _knobs(ctx, oid, n_knobs, lambda i: _rot_pose(_R_FRONT, kx, ky[i], kz), max_r,
                       pitch)
        knob_view = View("knobs", (kx, 0.0, kz), (1.0, 0.0, 0.0), max_angle=math.radians(55))
    if lift:
        # the whole oven on a cabinet of ``lift``
        v = [replace(x, pose=replace(x.pose, z=_mm(x.pose.z + lift))) for x in v]
        v.append(box(D, W, lift, 0, 0, lift / 2, color=color, material=material, name="cabinet"))
        door.joint.origin = replace(door.joint.origin, z=_mm(door.joint.origin.z + lift))
        for k in knobs:
            k.pose = replace(k.pose, z=_mm(k.pose.z + lift))
        knob_view = replace(knob_view, point=(knob_view.point[0], 0.0, _mm(knob_view.point[2] + lift)))
    names = {"oven": "oven", "cooker": "cooker", "hob": "hob"}
    obj = LargeArticulatedObject(
        id=oid, type=kind, name=ctx.ids.name(f"{ctx.room_name} {names[kind]}"), pose=Pose(),
        model=Model(v), affordances=["appliance", "openable"], parts=[door], knobs=knobs,
        description=f"{'flush' if flush else 'stepped'} front, {n_knobs} knobs "
                    f"{'on top' if top_knobs else 'on the front panel'}"
                    f"{' below the door' if panel_low else ''}{' raised on a cabinet' if lift else ''}")
    views = [View("face", (face_x, 0.0, lift + H / 2)), knob_view]
    reach = [(k.pose.x, k.pose.y, k.pose.z) for k in knobs] + [tuple(_handle_point(door))]
    return Piece(obj, "wall", front_parking(ctx, oid, face_x, W), views=views, reach=reach)


def _oven_door_mesh(t: float, width: float, height: float):
    """An oven door: a slab with a window frame standing 5 mm proud around the glass."""
    slab = box_mesh((0.0, 0.0, height / 2), (t, width, height))
    b = 0.06
    r = 0.005
    frame = [box_mesh((t / 2 + r / 2, 0.0, b / 2 + 0.04), (r, width - 0.02, b)),
             box_mesh((t / 2 + r / 2, 0.0, height - b / 2 - 0.1), (r, width - 0.02, b)),
             box_mesh((t / 2 + r / 2, width / 2 - b / 2 - 0.01, height / 2 - 0.03), (r, b, height - 0.26)),
             box_mesh((t / 2 + r / 2, -width / 2 + b / 2 + 0.01, height / 2 - 0.03), (r, b, height - 0.26))]
    return merge(slab, *frame)


def chair(ctx: _Ctx) -> Piece:
    """A chair (not static: never a landmark), its model from the home's library."""
    design = f"chair_design_{ctx.i(1, 3)}"
    if design not in ctx.library:
        c = ctx.pick(WOODS + PAINTS)
        s, hseat = _mm(ctx.u(0.4, 0.48)), _mm(ctx.u(0.42, 0.48))
        ctx.library[design] = Model([
            box(s, s, 0.03, 0, 0, hseat, color=c, name="seat"),
            box(0.03, s, _mm(ctx.u(0.35, 0.5)), -s / 2 + 0.015, 0, hseat + 0.2, color=c, name="back"),
            *[box(0.03, 0.03, hseat - 0.015, sx * (s / 2 - 0.03), sy * (s / 2 - 0.03),
                  (hseat - 0.015) / 2, color=c, name="leg") for sx in (-1, 1) for sy in (-1, 1)]])
    oid = ctx.ids.new("chair")
    obj = LargeObject(id=oid, type="chair", name=ctx.ids.name(f"{ctx.room_name} chair"), pose=Pose(),
                      model=Model(ref=design), static=False, affordances=["seat"])
    d = _mm(ctx.u(0.6, 0.8))
    return Piece(obj, "free", [ParkingPosition(f"{oid}_back", Pose.planar(-d, 0.0, 0.0)),
                               ParkingPosition(f"{oid}_front", Pose.planar(d, 0.0, math.pi))])


# -- small objects ------------------------------------------------------------------------------

#: kind -> (type words, builder(ctx, rgb) -> (visuals, height, radius), where it goes)
def _cup(ctx, rgb, mug=False):
    r = _mm(ctx.u(0.042, 0.05) if mug else ctx.u(0.034, 0.044))
    h = _mm(ctx.u(0.095, 0.12) if mug else ctx.u(0.075, 0.1))
    return [cyl(r, h, z=h / 2, color=rgb, name="body"),
            box(0.035 if mug else 0.03, 0.012, h * 0.6, r + 0.014, 0, h / 2, color=rgb,
                name="handle")], h, r + 0.03


def _bowl(ctx, rgb):
    r, h = _mm(ctx.u(0.06, 0.09)), _mm(ctx.u(0.045, 0.07))
    return [cyl(r, h, z=h / 2, color=rgb, name="body")], h, r


def _bottle(ctx, rgb):
    r, h = _mm(ctx.u(0.028, 0.038)), _mm(ctx.u(0.15, 0.22))
    return [cyl(r, h, z=h / 2, color=rgb, name="body"),
            cyl(0.013, 0.05, z=h + 0.025, color=rgb, name="neck"),
            cyl(0.015, 0.015, z=h + 0.057, color=(0.9, 0.9, 0.9), name="cap")], h + 0.065, r


def _box(ctx, rgb):
    sx, sy, sz = _mm(ctx.u(0.06, 0.13)), _mm(ctx.u(0.05, 0.1)), _mm(ctx.u(0.05, 0.16))
    return [box(sx, sy, sz, z=sz / 2, color=rgb, name="body")], sz, math.hypot(sx, sy) / 2


def _pill_box(ctx, rgb):
    sx, sy, sz = _mm(ctx.u(0.05, 0.07)), _mm(ctx.u(0.09, 0.13)), _mm(ctx.u(0.025, 0.035))
    label = ctx.pick([c for n, c in COLOURS.items() if c != rgb and n not in ("white", "black")])
    return [box(sx, sy, sz, z=sz / 2, color=rgb, name="body"),
            box(sx + 0.002, sy * 0.4, 0.002, z=sz + 0.001, color=label, name="label")], sz, math.hypot(sx, sy) / 2


def _book(ctx, rgb):
    w, l, th = _mm(ctx.u(0.13, 0.18)), _mm(ctx.u(0.19, 0.25)), _mm(ctx.u(0.02, 0.045))
    if ctx.chance(0.5):        # standing, spine out
        return [box(l * 0.75, th, w * 1.3, z=w * 0.65, color=rgb, name="body")], w * 1.3, math.hypot(l * 0.75, th) / 2
    return [box(w, l, th, z=th / 2, color=rgb, name="body")], th, math.hypot(w, l) / 2


def _can(ctx, rgb):
    r, h = 0.033, _mm(ctx.u(0.1, 0.125))
    return [cyl(r, h, z=h / 2, color=rgb, name="body"),
            cyl(0.03, 0.004, z=h + 0.002, color=STEEL, name="lid")], h + 0.004, r


def _jar(ctx, rgb):
    r, h = _mm(ctx.u(0.04, 0.05)), _mm(ctx.u(0.09, 0.14))
    return [cyl(r, h, z=h / 2, color=(0.8, 0.85, 0.85), material="glass", name="body"),
            cyl(r + 0.003, 0.02, z=h + 0.01, color=rgb, name="lid")], h + 0.02, r


def _remote(ctx, rgb):
    return [box(0.05, 0.17, 0.022, z=0.011, color=rgb, name="body")], 0.022, 0.09


SMALL_KINDS = {
    "cup": (lambda c, rgb: _cup(c, rgb), "ceramic cup"),
    "mug": (lambda c, rgb: _cup(c, rgb, mug=True), "large mug"),
    "bowl": (_bowl, "bowl"),
    "bottle": (_bottle, "plastic bottle"),
    "box": (_box, "cardboard box"),
    "pill box": (_pill_box, "weekly pill box"),
    "book": (_book, "book"),
    "can": (_can, "tin can"),
    "jar": (_jar, "glass jar"),
    "remote": (_remote, "remote control"),
}


def _tokens(text: str) -> set[str]:
    from hearth.worldmodel.world import tokens
    return set(tokens(text))


class _SmallPlacer:
    """Puts small objects on free spots of the home's surfaces."""

    def __init__(self, ctx: _Ctx, pieces: list[Piece]):
        self.ctx = ctx
        self.pieces = pieces
        self.words: list[tuple[set, set]] = []      # (query words, all words) per object
        self.spots: dict[tuple[str, str], list[tuple[float, float, float]]] = {}

    def slots(self, want: str) -> list[tuple[Piece, Surface]]:
        """Surfaces of one kind: table (tops of tables), shelf_low (open shelves up to
        0.5 m), shelf (other open shelves), closed (inside closed doors), top (tops of
        cupboards and drawers), under (tables tall enough to put something under)."""
        cfg = self.ctx.cfg
        out = []
        for pc in self.pieces:
            o = pc.obj
            for s in o.surfaces:
                z = s.pose.z + pc.lift
                if z > cfg.max_object_height or not pc.parking:
                    continue
                if want == "table" and o.type == "table" and s.id == "top":
                    out.append((pc, s))
                elif want == "shelf_low" and o.type == "bookshelf" and s.id != "top" and z <= 0.5:
                    out.append((pc, s))
                elif want == "shelf" and o.type == "bookshelf" and z > 0.5:
                    out.append((pc, s))
                elif want == "closed" and s.relation == "in":
                    out.append((pc, s))
                elif want == "top" and o.type != "table" and s.id == "top":
                    out.append((pc, s))
            if want == "drawer" and pc.parking:
                for part in getattr(o, "parts", ()):
                    out += [(pc, s) for s in part.surfaces]
            if want == "under" and o.type == "table" and o.surfaces[0].pose.z >= 0.6 \
                    and o.surfaces[0].size_x >= 0.5 and o.surfaces[0].size_y >= 0.5:
                s = o.surfaces[0]
                out.append((pc, Surface("under", Pose(0, 0, 0), _mm(s.size_x - 0.2),
                                        _mm(s.size_y - 0.2), "under")))
        return out

    def colour_for(self, kind: str, avoid: Optional[str] = None) -> Optional[str]:
        names = [n for n in COLOURS if n != avoid]
        order = self.ctx.rng.permutation(len(names))
        for i in order:
            if self._unique(names[i], kind):
                return names[i]
        return None

    def _unique(self, colour: str, kind: str) -> bool:
        q = _tokens(f"{colour} {kind}")
        allw = q | _tokens(SMALL_KINDS[kind][1]) | _tokens(f"{colour}_{kind}".replace(" ", "_"))
        for q2, all2 in self.words:
            if q <= all2 or q2 <= allw:
                return False
        return True

    def place(self, kind: str, colour: str, where: str, slots=None) -> Optional[SmallObject]:
        ctx = self.ctx
        slots = self.slots(where) if slots is None else slots
        if not slots:
            return None
        rgb = COLOURS[colour]
        make, desc = SMALL_KINDS[kind]
        visuals, height, radius = make(ctx, rgb)
        for _ in range(30):
            pc, s = slots[int(ctx.rng.integers(len(slots)))]
            head = pc.headroom.get(s.id, pc.obj.surfaces[0].pose.z - 0.05 if s.relation == "under" else math.inf)
            if height > head - 0.03:
                continue
            hx, hy = s.size_x / 2 - radius - 0.02, s.size_y / 2 - radius - 0.02
            if hx <= 0 or hy <= 0:
                continue
            # inside and on shelves, near the front half where a camera sees in
            lo_x = 0.0 if s.relation == "in" or pc.obj.type == "bookshelf" else -hx
            if where == "drawer":              # away from the front panel, seen from above
                lx, ly = ctx.u(-hx, 0.3 * hx), ctx.u(-hy, hy)
            elif s.relation == "under":          # under a table: near an edge, seen from a side
                lx = ctx.u(-hx, hx)
                ly = ctx.pick([-1, 1]) * ctx.u(hy * 0.5, hy)
            else:
                lx, ly = ctx.u(lo_x, hx), ctx.u(-hy, hy)
            key = (pc.obj.id, s.id)
            taken = self.spots.get(key, [])
            if any(math.hypot(lx - x, ly - y) < radius + r + 0.04 for x, y, r in taken):
                continue
            if s.relation == "under":
                pc.obj.surfaces.append(s)
                pc.headroom["under"] = pc.obj.surfaces[0].pose.z - 0.05
            self.spots.setdefault(key, []).append((lx, ly, radius))
            yaw = _deg(ctx.u(-math.pi, math.pi))
            pose = _level_compose(s.pose, Pose(_mm(lx), _mm(ly), 0.0, 0, 0, yaw))
            type_id = kind.replace(" ", "_")
            oid = ctx.ids.exact(f"{colour}_{type_id}")
            grasp = GraspPoint(Pose(0, 0, _mm(min(height * 0.55, 0.1))))
            part = next((p.id for p in getattr(pc.obj, "parts", ()) if s in p.surfaces), "")
            obj = SmallObject(id=oid, type=kind, pose=pose, relation=s.relation, color=colour,
                              description=f"{colour} {desc}", grasp_points=[grasp],
                              default_positions=[DefaultPosition(pc.obj.id, s.relation, pose)],
                              model=Model(visuals), part=part)
            pc.obj.children.append(obj)
            q = _tokens(f"{colour} {kind}")
            self.words.append((q, q | _tokens(desc) | _tokens(oid)))
            return obj
        return None


def small_objects(ctx: _Ctx, pieces: list[Piece]) -> list[SmallObject]:
    """7-14 small objects: one on a table first (every home can fetch from a table), one on a
    low shelf and one inside a closed cupboard where the home has them, sometimes one under a
    table, a pair close in hue, the rest anywhere they fit."""
    cfg = ctx.cfg
    placer = _SmallPlacer(ctx, pieces)
    n = ctx.i(*cfg.small_objects)
    plan: list[tuple[str, Optional[str], str]] = [
        (ctx.pick(["cup", "mug", "bowl", "bottle"]), None, "table")]
    plan.append((ctx.pick(["book", "box", "cup", "bowl"]), None, "shelf_low"))
    plan.append((ctx.pick(["pill box", "jar", "can", "box", "bottle"]), None, "closed"))
    if ctx.chance(cfg.under_table_probability):
        plan.append((ctx.pick(["box", "bowl", "book"]), None, "under"))
    if ctx.chance(cfg.close_hue_probability):
        a, b = ctx.pick(CLOSE_HUES)
        k = ctx.pick(["cup", "mug", "bottle", "box"])
        plan += [(k, a, "table"), (k, b, ctx.pick(["table", "table", "shelf", "top"]))]
    wheres = ["table", "table", "table", "shelf", "shelf_low", "closed", "top", "top"]
    while len(plan) < n:
        plan.append((ctx.pick(list(SMALL_KINDS)), None, ctx.pick(wheres)))
    out = []
    for kind, colour, where in plan[:max(n, 3)]:
        colour = colour if colour and placer._unique(colour, kind) else placer.colour_for(kind)
        if colour is None:
            continue
        obj = placer.place(kind, colour, where)
        if obj is None and where != "table":
            obj = placer.place(kind, colour, ctx.pick(["table", "top", "shelf"]))
        if obj is not None:
            out.append(obj)
    out += drawer_objects(ctx, placer)
    return out


#: What goes in a drawer, and how often a drawer with a floor holds one.
DRAWER_KINDS = ["pill box", "remote", "book", "box"]
DRAWER_PROBABILITY = 0.6


def drawer_objects(ctx: _Ctx, placer: "_SmallPlacer") -> list[SmallObject]:
    """Small objects in the drawers that have a floor (``DRAWER_PROBABILITY`` each), low
    enough to stay inside the closed drawer. Drawn from ``ctx.drawer_rng``, so the rest of a
    seed's home is what it was without them."""
    if ctx.drawer_rng is None:
        return []
    placer.ctx = replace(ctx, rng=ctx.drawer_rng)
    out = []
    try:
        for slot in placer.slots("drawer"):
            if not placer.ctx.chance(DRAWER_PROBABILITY):
                continue
            kind = placer.ctx.pick(DRAWER_KINDS)
            colour = placer.colour_for(kind)
            obj = placer.place(kind, colour, "drawer", slots=[slot]) if colour else None
            if obj is not None:
                out.append(obj)
    finally:
        placer.ctx = ctx
    return out


# -- rooms --------------------------------------------------------------------------------------

#: kind -> (width range, depth range, furniture plan: (builder name, probability, args))
ROOM_KINDS = {
    "kitchen": ((3.4, 5.5), (3.0, 4.6)),
    "living room": ((3.8, 6.5), (3.2, 5.0)),
    "bedroom": ((3.0, 4.6), (2.9, 4.2)),
    "bathroom": ((2.2, 3.2), (2.0, 2.9)),
    "study": ((2.8, 4.2), (2.6, 3.6)),
    "dining room": ((3.2, 4.8), (3.0, 4.2)),
}


def _furniture_plan(ctx: _Ctx, kind: str) -> list[tuple[str, Callable[[], Piece], bool]]:
    """(label, builder, required) for a room, in the order they are placed."""
    c = ctx
    P = []

    def add(label, fn, p=1.0, required=False):
        if required or c.chance(p):
            P.append((label, fn, required))

    if kind == "kitchen":
        main = c.pick(["oven", "cooker", "cooker", "hob"])
        k1 = c.i(c.cfg.knobs_per_appliance[0], min(c.cfg.knobs_per_appliance[1], c.knobs_left))
        c.knobs_left -= k1
        add(main, lambda m=main, k=k1: appliance(c, m, k), required=True)
        second = "hob" if main == "oven" else c.pick(["oven", "hob"])
        if c.knobs_left >= max(2, c.cfg.knobs_per_appliance[0]) and c.chance(c.cfg.second_appliance_probability):
            k2 = c.i(max(2, c.cfg.knobs_per_appliance[0]), min(4, c.knobs_left))
            c.knobs_left -= k2
            add(second, lambda m=second, k=k2: appliance(c, m, k))
        add("fridge", lambda: fridge(c), 0.85)
        add("cupboard", lambda: cupboard(c), 1.0)
        add("cupboard", lambda: cupboard(c), 0.5)
        add("cabinet", lambda: cupboard(c, "cabinet"), c.cfg.wall_cabinet_probability)
        add("drawers", lambda: drawer_unit(c), 0.6)
        add("table", lambda: table(c, c.pick(["table", "table", "bar"])), 0.85)
        add("bookshelf", lambda: bookshelf(c), 0.2)
        add("chair", lambda: chair(c), 0.5)
    elif kind == "living room":
        add("table", lambda: table(c, "coffee"), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.4)
        add("sideboard", lambda: cupboard(c, "sideboard"), 0.6)
        add("table", lambda: table(c, "side"), 0.6)
        add("drawers", lambda: drawer_unit(c), 0.3)
        add("chair", lambda: chair(c), 0.3)
    elif kind == "bedroom":
        add("wardrobe", lambda: cupboard(c, "wardrobe", sliding=c.chance(0.5)), 0.85)
        add("drawers", lambda: drawer_unit(c), 0.7)
        add("table", lambda: table(c, "bedside"), 0.5)
        add("drawers", lambda: drawer_unit(c, "bedside"), 0.4)
        add("bookshelf", lambda: bookshelf(c), 0.5)
    elif kind == "bathroom":
        add("cabinet", lambda: cupboard(c, "cabinet"), 0.9)
        add("table", lambda: table(c, "counter"), 0.8)
        add("drawers", lambda: drawer_unit(c), 0.3)
    elif kind == "study":
        add("table", lambda: table(c, "desk"), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.95)
        add("bookshelf", lambda: bookshelf(c), 0.4)
        add("drawers", lambda: drawer_unit(c), 0.6)
        add("cupboard", lambda: cupboard(c), 0.4)
        add("chair", lambda: chair(c), 0.5)
    elif kind == "dining room":
        add("table", lambda: table(c, "dining"), 1.0)
        add("chair", lambda: chair(c), 0.8)
        add("chair", lambda: chair(c), 0.6)
        add("sideboard", lambda: cupboard(c, "sideboard"), 0.7)
        add("bookshelf", lambda: bookshelf(c), 0.3)
    return P


class _Layout:
    """Free floor of one room while its furniture is placed (room frame, metres)."""

    def __init__(self, ctx: _Ctx, bounds):
        self.ctx = ctx
        self.bounds = bounds
        self.hulls: list[np.ndarray] = []
        self.parkings: list[tuple[float, float]] = []

    def parking_free(self, x: float, y: float, extra: list[np.ndarray] = ()) -> bool:
        r = self.ctx.cfg.robot_radius
        x0, y0, x1, y1 = self.bounds
        if not (x0 + r + 0.01 <= x <= x1 - r - 0.01 and y0 + r + 0.01 <= y <= y1 - r - 0.01):
            return False
        return all(disc_clear((x, y), h, r + 0.02) for h in (*self.hulls, *extra))

    def try_place(self, piece: Piece) -> Optional[tuple[float, float, float]]:
        """A room-frame pose (x, y, yaw) for the piece, or None after the configured tries.
        Keeps the piece's free parking positions."""
        ctx = self.ctx
        x0, y0, x1, y1 = self.bounds
        hull = piece.hull
        back = -hull[:, 0].min()
        half_w = max(-hull[:, 1].min(), hull[:, 1].max())
        reach_r = float(np.max(np.hypot(hull[:, 0], hull[:, 1])))
        for _ in range(ctx.cfg.placement_tries):
            if piece.mount == "wall":
                wall = ctx.i(0, 3)
                # inward normal yaw and the wall line, per wall: x0, x1, y0, y1
                if wall in (0, 1):
                    L, lo = y1 - y0, y0
                else:
                    L, lo = x1 - x0, x0
                if L < 2 * half_w + 0.04:
                    continue
                s = lo + ctx.u(half_w + 0.02, L - half_w - 0.02)
                gap = ctx.u(0.01, 0.04)
                if wall == 0:
                    pose = (x0 + back + gap, s, 0.0)
                elif wall == 1:
                    pose = (x1 - back - gap, s, math.pi)
                elif wall == 2:
                    pose = (s, y0 + back + gap, math.pi / 2)
                else:
                    pose = (s, y1 - back - gap, -math.pi / 2)
            else:
                m = reach_r + 0.05
                if x1 - x0 < 2 * m or y1 - y0 < 2 * m:
                    continue
                pose = (ctx.u(x0 + m, x1 - m), ctx.u(y0 + m, y1 - m), ctx.u(-math.pi, math.pi))
            pose = (_mm(pose[0]), _mm(pose[1]), _deg(pose[2]))
            T = planar_T(*pose)
            poly = transform_polygon(T, hull)
            if not polygon_inside_rect(poly, self.bounds, 0.0):
                continue
            if any(polygons_overlap(poly, h, 0.03) for h in self.hulls):
                continue
            r = ctx.cfg.robot_radius
            if not all(disc_clear(p, poly, r + 0.02) for p in self.parkings):
                continue
            keep = [pk for pk in piece.parking
                    if self.parking_free(*transform_xy(T, [(pk.pose.x, pk.pose.y)])[0], [poly])]
            if not keep:
                continue
            piece.parking = keep
            self.hulls.append(poly)
            self.parkings += [tuple(transform_xy(T, [(pk.pose.x, pk.pose.y)])[0]) for pk in keep]
            return pose
        return None


def _hull(piece: Piece, scratch) -> np.ndarray:
    """The piece's footprint: convex hull of its meshes (hearth.worldmodel.geometry) in its frame."""
    from hearth.worldmodel.geometry import object_meshes
    meshes = object_meshes(scratch, piece.obj, T_world_object=np.eye(4), children=False)
    pts = np.vstack([np.asarray(m.mesh.vertices) for m in meshes])
    return convex_hull_xy(pts)


def _room_polygon(room_bounds, pose: tuple[float, float, float]) -> np.ndarray:
    x0, y0, x1, y1 = room_bounds
    return transform_polygon(planar_T(*pose), np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]))


def _place_room(ctx: _Ctx, bounds, placed: list[np.ndarray]) -> tuple[float, float, float]:
    """A world pose (x, y, yaw) for a room with ``bounds`` (room frame) beside the rooms
    placed so far, ``room_gap`` clear of each; turned by any angle with the configured
    probability, else by a multiple of 90 degrees."""
    cfg = ctx.cfg
    turned = ctx.chance(cfg.turned_room_probability)
    for attempt in range(60):
        yaw = ctx.u(-math.pi, math.pi) if turned else ctx.pick([0.0, 0.5, 1.0, -0.5]) * math.pi
        if not placed:
            return (_mm(ctx.u(-3, 3)), _mm(ctx.u(-3, 3)), _deg(yaw))
        # beside a placed room: its centre plus a direction, far enough to clear it
        other = placed[int(ctx.rng.integers(len(placed)))]
        c = other.mean(0)
        a = ctx.u(-math.pi, math.pi)
        dirv = np.array([math.cos(a), math.sin(a)])
        poly0 = _room_polygon(bounds, (0.0, 0.0, _deg(yaw)))
        centre0 = poly0.mean(0)
        # Closer than half their smaller sides the two rooms overlap whatever the direction.
        start = 0.5 * (min(bounds[2] - bounds[0], bounds[3] - bounds[1])
                       + min(np.ptp(other, axis=0)) * 0.7)
        for dist in np.arange(start, start + 14.0, 0.25):
            cxy = c + dirv * dist
            pose = (_mm(cxy[0] - centre0[0]), _mm(cxy[1] - centre0[1]), _deg(yaw))
            poly = poly0 + (pose[0], pose[1])
            if not any(polygons_overlap(poly, q, cfg.room_gap) for q in placed):
                return pose
    # Nothing beside the others: far to the right of everything.
    x_max = max(q[:, 0].max() for q in placed)
    poly0 = _room_polygon(bounds, (0.0, 0.0, 0.0))
    return (_mm(x_max + cfg.room_gap + 1.0 - poly0[:, 0].min()), 0.0, 0.0)


def _build_and_place(ctx: _Ctx, build: Callable[[], Piece], layout: "_Layout", scratch,
                     tries: int) -> Optional[Piece]:
    """Build a piece (up to ``tries`` designs) until one has a parking position that sees it
    and fits the room; the piece with its room-frame pose set, or None."""
    for _ in range(tries):
        piece = build()
        _keep_visible(ctx.cfg, piece)
        if not piece.parking:
            continue
        piece.hull = _hull(piece, scratch)
        pose = layout.try_place(piece)
        if pose is not None:
            piece.obj.pose = Pose(pose[0], pose[1], piece.lift, 0, 0, pose[2])
            piece.obj.parking = list(piece.parking)
            piece.obj.default_parking = piece.parking[0].id     # candidates come best first
            return piece
    return None


def _room(ctx: _Ctx, kind: str, rid: str, scratch, placed_rooms: list[np.ndarray]):
    """A room of ``kind`` with its furniture: (Room, pieces, layout). A room whose required
    furniture (the kitchen's appliance) does not fit is drawn again, larger."""
    (w0, w1), (d0, d1) = ROOM_KINDS[kind]
    ctx.room_name = kind
    grow = 1.0
    for attempt in range(8):
        w, d = _mm(ctx.u(w0, w1) * grow), _mm(ctx.u(d0, d1) * grow)
        bx = _mm(ctx.pick([0.0, ctx.u(-2.0, 1.0)]))
        by = _mm(ctx.pick([0.0, ctx.u(-2.0, 1.0)]))
        bounds = (bx, by, _mm(bx + w), _mm(by + d))
        layout = _Layout(ctx, bounds)
        pieces, ok = [], True
        knobs_before = ctx.knobs_left
        ids_before = set(ctx.ids.used), set(ctx.ids.names)
        for label, build, required in _furniture_plan(ctx, kind):
            piece = _build_and_place(ctx, build, layout, scratch, 6 if required else 1)
            if piece is not None:
                pieces.append(piece)
            elif required:
                ok = False
                break
        if ok:
            break
        ctx.knobs_left = knobs_before
        ctx.ids.used, ctx.ids.names = ids_before
        grow *= 1.12
    else:  # pragma: no cover - the kitchen grows until its appliance fits
        raise HomeGenError(f"could not lay out the {kind}")
    rpose = _place_room(ctx, bounds, placed_rooms)
    placed_rooms.append(_room_polygon(bounds, rpose))
    sw = Switch(f"{rid}_light", ctx.pick(["rotational", "prismatic"]),
                Pose(_mm(bounds[0] + 0.02), _mm(ctx.u(bounds[1] + 0.2, bounds[1] + 0.6)),
                     _mm(ctx.u(1.05, 1.3))), name=f"{kind} light")
    room = Room(rid, kind, pose=Pose(rpose[0], rpose[1], 0, 0, 0, rpose[2]), bounds=bounds,
                switches=[sw], objects=[p.obj for p in pieces])
    return room, pieces, layout


def _turn_front(ctx: _Ctx, piece: Piece) -> None:
    """Turn an object's contents by a quarter or half turn inside its own frame and its pose
    back by the same, so the object stands where it stood but its front is no longer its
    local +x."""
    obj = piece.obj
    if obj.model.ref is not None:
        return
    c = ctx.pick([math.pi / 2, math.pi, -math.pi / 2])
    R = Pose(0, 0, 0, 0, 0, c)

    def turn(p: Pose) -> Pose:
        return _level_compose(R, p)

    for v in obj.model.visuals:     # mesh vertices are in the visual's frame: turning it turns them
        v.pose = turn(v.pose)
    obj.parking = [ParkingPosition(p.id, Pose.planar(*(lambda q: (q.x, q.y, q.yaw))(turn(p.pose))))
                   for p in obj.parking]
    obj.surfaces = [replace(s, pose=turn(s.pose)) for s in obj.surfaces]
    for ch in obj.children:
        if ch.part:         # in the part's frame, which the joint origin turns
            continue
        ch.pose = turn(ch.pose)
        ch.default_positions = [replace(d, pose=turn(d.pose)) if d.parent == obj.id else d
                                for d in ch.default_positions]
    if isinstance(obj, LargeArticulatedObject):
        for p in obj.parts:
            p.joint.origin = turn(p.joint.origin)
        for k in obj.knobs:
            k.pose = turn(k.pose)
        for h in obj.handles:
            h.pose = turn(h.pose)
    obj.pose = _clean(replace(obj.pose, yaw=obj.pose.yaw - c))    # level: yaws add


# -- the home -----------------------------------------------------------------------------------

def default_mesh_dir() -> Path:
    """Where ``generate_home`` writes meshes when no directory is given."""
    return Path(os.environ.get("HEARTH_HOMEGEN_DIR", Path.home() / ".cache" / "hearth" / "homegen"))


def generate_home(seed: int, config: HomeConfig = HomeConfig(), mesh_dir=None):
    """A generated home as a ``World`` (in memory; the meshes it references are written to
    ``mesh_dir``, default ``default_mesh_dir()``, which becomes the world's ``base_dir``).
    Deterministic per seed and configuration. HomeGenError for a configuration or seed it
    cannot use."""
    import tempfile
    from hearth.worldmodel.world import World
    config.check()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise HomeGenError(f"home seed must be a whole number >= 0, not {seed!r}")
    mesh_dir = Path(mesh_dir) if mesh_dir is not None else default_mesh_dir()
    rng = np.random.default_rng(int(seed))
    library: dict[str, Model] = {}
    with tempfile.TemporaryDirectory(prefix="hearth-homegen-") as tmp:
        ctx = _Ctx(rng, config, _Ids(), _Meshes(Path(tmp)), library, knobs_left=config.max_knobs,
                   design_rng=np.random.default_rng([int(seed), 0x6B6E6F62]),
                   drawer_rng=np.random.default_rng([int(seed), 0x64726177]))
        scratch = World(Apartment(id="scratch", library=library), base_dir=Path(tmp))
        n_rooms = ctx.i(*config.rooms)
        others = [k for k in ROOM_KINDS if k != "kitchen"]
        kinds = ["kitchen"] + [others[i] for i in rng.permutation(len(others))[:n_rooms - 1]]
        rooms, pieces, layouts, placed = [], [], [], []
        for kind in kinds:
            rid = ctx.ids.exact(kind.replace(" ", "_"))
            room, ps, layout = _room(ctx, kind, rid, scratch, placed)
            rooms.append(room)
            pieces += ps
            layouts.append(layout)
        _ensure_table(ctx, rooms, pieces, layouts, scratch)
    small_objects(ctx, pieces)
    for pc in pieces:
        if ctx.chance(config.front_turn_probability):
            _turn_front(ctx, pc)
    used_models = {o.model.ref for r in rooms for o in r.objects if o.model.ref is not None}
    library = {k: m for k, m in library.items() if k in used_models}
    apartment = Apartment(id=f"home_{int(seed)}", name=f"Generated home {int(seed)}",
                          rooms=rooms, library=library)
    world = World(apartment, path=None, base_dir=mesh_dir)
    ctx.meshes.write(mesh_dir, _mesh_files(apartment))
    from hearth.worldmodel.chargers import place_charger
    place_charger(world)
    return world


def _ensure_table(ctx: _Ctx, rooms, pieces, layouts, scratch) -> None:
    """Every home gets a table (fetching from a table is the first mission anyone runs)."""
    if any(p.obj.type == "table" for p in pieces):
        return
    order = sorted(range(len(rooms)), key=lambda i: -(rooms[i].bounds[2] - rooms[i].bounds[0])
                   * (rooms[i].bounds[3] - rooms[i].bounds[1]))
    for i in order:
        ctx.room_name = rooms[i].name
        piece = _build_and_place(ctx, lambda: table(ctx, "side"), layouts[i], scratch, 6)
        if piece is not None:
            rooms[i].objects.append(piece.obj)
            pieces.append(piece)
            return


def _mesh_files(apartment: Apartment) -> set[str]:
    """Every mesh file the apartment references."""
    from hearth.worldmodel.validate import file_references
    return {getattr(h, a) for _, h, a in file_references(apartment) if a == "file"}


def make_home(seed: int, out_dir, config: HomeConfig = HomeConfig()) -> Path:
    """Write the home of ``seed`` as ``out_dir/world.xml`` (meshes in ``out_dir/meshes/``),
    atomically; returns the world file's path. The file is checked (schema and semantics)
    before it is written."""
    from hearth.worldmodel.io import atomic_write, parse_world, to_xml
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise HomeGenError(f"{out}: not a directory")
    world = generate_home(seed, config, mesh_dir=out)
    data = to_xml(world.apartment)
    parse_world(data, str(out / "world.xml"), base_dir=out.resolve())
    path = out / "world.xml"
    atomic_write(path, data)
    return path


def summary(world) -> dict:
    """Counts a person wants on one line: rooms, large and small objects, knobs."""
    return dict(rooms=[r.name for r in world.rooms], large=len(world.large_objects()),
                small=len(world.small_objects()), knobs=len(world.knobs()),
                turned=[r.name for r in world.rooms
                        if abs(math.remainder(r.pose.yaw, math.pi / 2)) > 1e-6])
