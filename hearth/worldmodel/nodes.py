"""Typed nodes of the hierarchical semantic map (RAMCIP D3.1 section 3.2).

apartment -> room (switches, chargers) -> LargeObject / LargeArticulatedObject (parts with joints,
handles, knobs) -> SmallObject. Every pose is relative to its parent node's frame; lengths
are metres, angles radians. ``line`` fields remember where a node stood in its file and do
not take part in equality.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Union

from hearth.worldmodel.pose import Pose

RGB = tuple[float, float, float]

SHAPES = ("box", "cylinder", "sphere", "mesh")
MATERIALS = ("matte", "dark", "shiny", "glass")
JOINT_TYPES = ("revolute", "prismatic", "fixed")
RELATIONS = ("on", "in", "under")
SWITCH_TYPES = ("rotational", "prismatic")


def _line():
    return field(default=None, compare=False, repr=False)


@dataclass
class Visual:
    """One primitive or mesh of a model, in its node's frame.

    box: ``size`` (x, y, z) centred on ``pose``; cylinder: ``radius``, ``length`` along the
    local z axis, centred; sphere: ``radius``; mesh: ``file`` (relative to the world file)
    scaled by ``scale`` (x, y, z factors in the mesh's own frame; one number given here or in
    a file means the same factor on every axis). ``material`` drives the simulated sensor
    (dark and shiny surfaces drop depth readings). ``name`` tags special parts ("marker" on a
    knob face, "face" of a door).
    """
    shape: str
    pose: Pose = field(default_factory=Pose)
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0
    file: Optional[str] = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: RGB = (0.7, 0.7, 0.7)
    material: str = "matte"
    name: str = ""
    line: Optional[int] = _line()

    def __post_init__(self) -> None:
        if isinstance(self.scale, (int, float)):
            self.scale = (float(self.scale),) * 3
        else:
            self.scale = tuple(float(s) for s in self.scale)


@dataclass
class Model:
    """A node's geometry: visuals inline, or ``ref`` to a model of the apartment's library."""
    visuals: list[Visual] = field(default_factory=list)
    ref: Optional[str] = None
    line: Optional[int] = _line()


@dataclass
class ParkingPosition:
    """A robot base pose (x, y, yaw used) relative to its large object."""
    id: str
    pose: Pose
    line: Optional[int] = _line()


@dataclass
class Surface:
    """A supporting surface (table top, shelf): centre of its top face and its extent."""
    id: str
    pose: Pose
    size_x: float
    size_y: float
    relation: str = "on"
    line: Optional[int] = _line()


@dataclass
class GraspPoint:
    pose: Pose
    line: Optional[int] = _line()


@dataclass
class DefaultPosition:
    """A place where a small object is usually found."""
    parent: str
    relation: str
    pose: Pose
    line: Optional[int] = _line()


@dataclass
class SmallObject:
    """A small object. Its parent is a large object (the place a search plans over); with
    ``part`` its pose is in the frame of that part of its parent (a drawer), so it moves
    with the part's joint (docs/world-format.md, "Objects inside parts")."""
    id: str
    type: str
    pose: Pose
    relation: str = "on"
    name: str = ""
    description: str = ""
    color: str = ""
    graspable: bool = True
    grasp_points: list[GraspPoint] = field(default_factory=list)
    default_positions: list[DefaultPosition] = field(default_factory=list)
    model: Model = field(default_factory=Model)
    part: str = ""
    line: Optional[int] = _line()

    kind = "SmallObject"

    @property
    def words(self) -> list[str]:
        return [self.type, self.name, self.description, self.color, self.id]


@dataclass
class Joint:
    """How a part moves relative to its parent: ``origin`` places the joint frame in the
    parent frame; the part moves about/along ``axis`` (joint frame) by ``state`` (radians for
    revolute, metres for prismatic), within [lower, upper]."""
    type: str
    origin: Pose = field(default_factory=Pose)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    lower: float = 0.0
    upper: float = 0.0
    state: float = 0.0
    line: Optional[int] = _line()


#: What a hand pulls a door or drawer by: a ``bar`` standing off the face, or a ``recessed``
#: pull (a finger hollow in a sliding door, flush with its face).
HANDLE_KINDS = ("bar", "recessed")


@dataclass
class Handle:
    """A handle. Frame: origin at the handle's centre, +x out of the face it is mounted on,
    +z along it. A ``bar``: ``standoff`` is the distance from the face to the bar axis. A
    ``recessed`` pull: a hollow ``length`` long and ``2 * radius`` wide in the face, its
    frame origin on the face (``standoff`` unused)."""
    id: str
    pose: Pose
    radius: float = 0.01
    length: float = 0.2
    standoff: float = 0.04
    color: RGB = (0.75, 0.75, 0.78)
    material: str = "shiny"
    handle_kind: str = "bar"
    line: Optional[int] = _line()

    kind = "Handle"


@dataclass
class KnobState:
    name: str
    angle: float
    line: Optional[int] = _line()


#: Which way a knob turns from off through its settings, seen from the front (looking at its
#: face, against +z): "either" (no end stop, or not said), "clockwise" (towards negative
#: angles), "counterclockwise" (towards positive angles).
KNOB_TURNS = ("either", "clockwise", "counterclockwise")


@dataclass
class Knob:
    """A rotary knob with discrete states. Frame: origin at the centre of its back face on the
    panel, +z out of the panel (the rotation axis), +y up at angle 0; angles are
    counter-clockwise about +z (seen from the front). The knob's shape turns with it: at angle
    ``a`` its ``base``, ``grip`` and ``marker`` are its frame's geometry turned by ``a`` about
    +z (a base with ``base_fixed`` stays put: a bezel on the panel).

    Shape: a knob that gives none of ``base``, ``grip`` and ``marker`` is the plain knob of
    format 1, a cylinder of ``radius`` and ``depth`` in ``color`` with a marker bar of
    ``marker_color`` on its face from the centre towards +y (hearth.worldmodel.geometry
    ``knob_visuals``). A knob that gives any of them is exactly what they describe (models:
    primitives or meshes, in the knob frame at angle 0); ``radius`` and ``depth`` then name
    its outline's radius and how far its front stands out of the panel, and ``color`` /
    ``marker_color`` are not used. ``marker`` is the pointer a reader looks for (its colour
    and material tell it from the grip).

    ``symmetry``: the shape looks the same turned by 360/symmetry degrees (2 for a plain bar
    grip), so an angle is only seen modulo that; the states must then differ modulo it.
    ``turns``: which way the knob turns from its off state through its settings
    (``KNOB_TURNS``); a knob with an end stop never stands outside that travel."""
    id: str
    pose: Pose
    states: list[KnobState]
    state: str
    angle: float = 0.0
    radius: float = 0.02
    depth: float = 0.025
    color: RGB = (0.85, 0.85, 0.85)
    marker_color: RGB = (0.05, 0.05, 0.05)
    off_state: str = ""
    base: Optional[Model] = None
    grip: Optional[Model] = None
    marker: Optional[Model] = None
    base_fixed: bool = False
    symmetry: int = 1
    turns: str = "either"
    line: Optional[int] = _line()

    kind = "Knob"

    def state_angle(self, name: str) -> float:
        for s in self.states:
            if s.name == name:
                return s.angle
        raise KeyError(name)

    @property
    def off(self) -> str:
        """Name of the state that means off (``off_state``, else a state named "off", else the
        first state)."""
        if self.off_state:
            return self.off_state
        for s in self.states:
            if s.name == "off":
                return s.name
        return self.states[0].name

    @property
    def described(self) -> bool:
        """Whether the knob describes its own shape (base, grip or marker), or is the plain
        knob drawn from ``radius``, ``depth`` and its colours."""
        return any(m is not None for m in (self.base, self.grip, self.marker))


@dataclass
class Part:
    """A moving (or fixed) part of an articulated object: a door, a drawer, a panel.

    ``surfaces`` (part frame) hold small objects that move with the part (a drawer's floor).
    ``track``: parts of one object with the same track are sliding doors on one track: they
    exclude each other (sliding one open slides it over the other; docs/world-format.md,
    "Sliding doors")."""
    id: str
    type: str
    joint: Joint
    name: str = ""
    model: Model = field(default_factory=Model)
    handles: list[Handle] = field(default_factory=list)
    knobs: list[Knob] = field(default_factory=list)
    parts: list["Part"] = field(default_factory=list)
    surfaces: list[Surface] = field(default_factory=list)
    track: str = ""
    line: Optional[int] = _line()

    kind = "Part"


@dataclass
class LargeObject:
    id: str
    type: str
    pose: Pose
    name: str = ""
    description: str = ""
    model: Model = field(default_factory=Model)
    parking: list[ParkingPosition] = field(default_factory=list)
    default_parking: str = ""
    graspable: bool = False
    static: bool = True
    affordances: list[str] = field(default_factory=list)
    surfaces: list[Surface] = field(default_factory=list)
    children: list[SmallObject] = field(default_factory=list)
    line: Optional[int] = _line()

    kind = "LargeObject"

    @property
    def words(self) -> list[str]:
        return [self.type, self.name, self.description, self.id]


@dataclass
class LargeArticulatedObject(LargeObject):
    parts: list[Part] = field(default_factory=list)
    handles: list[Handle] = field(default_factory=list)
    knobs: list[Knob] = field(default_factory=list)

    kind = "LargeArticulatedObject"


@dataclass
class Switch:
    id: str
    type: str
    pose: Pose
    name: str = ""
    on: bool = False
    line: Optional[int] = _line()

    kind = "Switch"


@dataclass
class Charger:
    """A charging station on the floor of a room: where it stands (``pose``, room frame) and
    the base pose the robot docks at (``dock``, x/y/yaw in the charger's frame, as a parking
    position is in its object's). Not drawn: a flat plate the camera does not need."""
    id: str
    pose: Pose
    dock: Pose
    name: str = ""
    line: Optional[int] = _line()

    kind = "Charger"

    @property
    def words(self) -> list[str]:
        return ["charger", self.name, self.id]


@dataclass
class Doorway:
    """An opening in a room's walls that the robot can drive through (RAMCIP's rooms joined
    by doorways). ``pose`` (room frame, x, y and yaw used): the centre of the opening on the
    floor, +x pointing through it out of the room. The passage is the rectangle ``depth``
    long along +x (centred on the pose: it cuts this room's wall and any gap to the next
    room's) and ``width`` wide; walls are open there. ``to``: the room it leads to ("" for
    one that leads out of the home)."""
    id: str
    pose: Pose
    width: float
    depth: float = 0.5
    to: str = ""
    line: Optional[int] = _line()

    kind = "Doorway"

    @property
    def words(self) -> list[str]:
        return ["doorway", self.id]


@dataclass
class Room:
    """A room. Its floor is ``outline`` (a simple polygon, room frame, counter-clockwise) when
    given, else the rectangle ``bounds`` (xmin, ymin, xmax, ymax; the format-1 form). A room
    with an outline has ``bounds`` set to the outline's bounding box (for whatever wants an
    extent); the file carries only the outline."""
    id: str
    name: str
    pose: Pose = field(default_factory=Pose)
    pointcloud: Optional[str] = None
    bounds: Optional[tuple[float, float, float, float]] = None   # xmin, ymin, xmax, ymax
    switches: list[Switch] = field(default_factory=list)
    chargers: list[Charger] = field(default_factory=list)
    objects: list[Union[LargeObject, LargeArticulatedObject]] = field(default_factory=list)
    line: Optional[int] = _line()
    outline: Optional[list[tuple[float, float]]] = None
    doorways: list[Doorway] = field(default_factory=list)

    kind = "Room"

    def __post_init__(self) -> None:
        if self.outline is not None:
            self.outline = [(float(x), float(y)) for x, y in self.outline]
            if self.outline and self.bounds is None:
                xs, ys = [p[0] for p in self.outline], [p[1] for p in self.outline]
                self.bounds = (min(xs), min(ys), max(xs), max(ys))

    @property
    def words(self) -> list[str]:
        return [self.name, self.id]


@dataclass
class HistoryEntry:
    """One recorded change: ``field`` of ``node`` went from ``old`` to ``new`` (text)."""
    time: float
    node: str
    field: str
    old: str
    new: str
    source: str = ""


@dataclass
class SearchStat:
    """How often object ``object`` was looked for at ``place`` and found there (HOBBIT's
    learned c_prob). Kept with the map."""
    object: str
    place: str
    searched: int = 0
    found: int = 0
    line: Optional[int] = _line()


@dataclass
class Apartment:
    id: str
    name: str = ""
    rooms: list[Room] = field(default_factory=list)
    library: dict[str, Model] = field(default_factory=dict)
    history: list[HistoryEntry] = field(default_factory=list)
    search_stats: list[SearchStat] = field(default_factory=list)
    version: str = "1"
    line: Optional[int] = _line()

    kind = "Apartment"


AnyNode = Union[Apartment, Room, Doorway, Switch, Charger, LargeObject, LargeArticulatedObject, Part, Handle, Knob,
                SmallObject]
