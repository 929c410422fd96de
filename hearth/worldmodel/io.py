"""Safe loading, validation and atomic saving of world files (XML, schema in schema/world.xsd).

The parser never resolves entities, never loads a DTD and never touches the network; a file
with a DOCTYPE at all is rejected, which stops external-entity and billion-laughs files before
any expansion. Size, length, count and depth limits (below; docs/world-format.md, "Limits")
bound the work a file can ask for. Problems are reported as ``WorldError`` with file and line.

``save_world`` writes only what ``load_world`` would read back: it checks the map in memory
(naming nodes), then parses what it is about to write with the loader itself.
"""
from __future__ import annotations

import fcntl
import itertools
import os
import re
import secrets
import stat
from functools import lru_cache
from pathlib import Path
from typing import Optional

from lxml import etree

from hearth.util.files import read_limited
from hearth.worldmodel.errors import WorldError, WorldValidationError
from hearth.worldmodel.nodes import (
    Apartment, DefaultPosition, Doorway, GraspPoint, Handle, HistoryEntry, Joint, Knob, KnobState,
    LargeArticulatedObject, LargeObject, Model, ParkingPosition, Part, Room, SearchStat,
    SmallObject, Surface, Switch, Visual, Charger,
)
from hearth.worldmodel.pose import Pose
from hearth.worldmodel.validate import MAX_ROOMS, MAX_TEXT_CHARS, semantic_problems

SCHEMA_PATH = Path(__file__).with_name("schema") / "world.xsd"
FORMAT_VERSION = "1"

# Limits (docs/world-format.md, "Limits"); the length of strings and the bounds of numbers
# are the schema's, the number of rooms and of nodes hearth.worldmodel.validate's. The map with
# 10,000 small objects of `hearth bench worldmodel` is 5 MB, about 80,000 elements and 11
# levels deep.
#: Largest world file.
MAX_FILE_BYTES = 32 * 1024 * 1024
_TOO_LARGE = f"file is larger than {MAX_FILE_BYTES} bytes"
#: Most XML elements in a file (history entries included).
MAX_ELEMENTS = 1_000_000
#: Deepest element nesting (the apartment is level 1; each nested part adds one).
MAX_DEPTH = 32
#: Most attributes on one element (the schema's elements have at most about 20). libxml2
#: compares each attribute of an element with the others while it parses: one element of
#: 100,000 attributes (1.1 MB) took minutes, so this is checked on the bytes, before parsing.
MAX_ATTRIBUTES = 256


def _parser() -> etree.XMLParser:
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                           dtd_validation=False, huge_tree=False, remove_comments=True,
                           remove_pis=True)


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(SCHEMA_PATH), _parser()))


# --------------------------------------------------------------------------------------
# reading

# A start tag long enough to hold more than MAX_ATTRIBUTES attributes (each at least ` a=""`).
_LONG_TAG = re.compile(rb"<[^>]{%d,}" % (5 * MAX_ATTRIBUTES))


def _check_attribute_counts(data: bytes, name: str) -> None:
    """One WorldError at the first start tag with more than MAX_ATTRIBUTES attributes."""
    for m in _LONG_TAG.finditer(data):
        tag = m.group()
        if tag.count(b'="') + tag.count(b"='") > MAX_ATTRIBUTES:
            raise WorldError(f"an element with more than {MAX_ATTRIBUTES} attributes", file=name,
                             line=data.count(b"\n", 0, m.start()) + 1)


def _parse_tree(data: bytes, name: str) -> etree._ElementTree:
    # Refuse DTDs before libxml2 sees them: no entity is ever declared, let alone expanded.
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise WorldError("DOCTYPE declarations (DTDs and entities) are not allowed",
                         file=name, line=_doctype_line(data))
    _check_attribute_counts(data, name)
    try:
        tree = etree.ElementTree(etree.fromstring(data, _parser()))
    except etree.XMLSyntaxError as err:
        line = err.lineno if getattr(err, "lineno", None) else 0
        msg = err.msg if hasattr(err, "msg") else str(err)
        msg = re.sub(r", line \d+, column \d+$", "", msg)
        # libxml2 quotes the document after some messages ("CData section not finished"
        # and the text that follows, newlines and all): the first line says what is wrong.
        msg = (msg.strip().splitlines() or ["unreadable XML"])[0].strip()
        raise WorldError(f"XML syntax error: {msg}", file=name, line=line) from None
    docinfo = tree.docinfo
    if docinfo.doctype or docinfo.internalDTD is not None or docinfo.externalDTD is not None:
        line = _doctype_line(data)
        raise WorldError("DOCTYPE declarations (DTDs and entities) are not allowed in world "
                         "files", file=name, line=line)
    _check_limits(tree.getroot(), name)
    _check_lengths(data, tree.getroot(), name)
    return tree


# Counted by libxml2 (a Python walk over the 80,000 elements of a 10,000-object map cost
# more than the schema).
_COUNT_ELEMENTS = etree.XPath("count(//*)")
_TOO_DEEP = etree.XPath("/*" + "/*" * MAX_DEPTH)


def _check_limits(root, name: str) -> None:
    """One WorldError at the first element past the element count or the nesting depth."""
    if _COUNT_ELEMENTS(root) > MAX_ELEMENTS:
        raise WorldError(f"more than {MAX_ELEMENTS} elements", file=name,
                         line=root.xpath(f"(//*)[{MAX_ELEMENTS + 1}]")[0].sourceline)
    deep = _TOO_DEEP(root)
    if deep:
        raise WorldError(f"elements nest more than {MAX_DEPTH} levels deep", file=name,
                         line=deep[0].sourceline)


def _check_lengths(data: bytes, root, name: str) -> None:
    """One WorldError at the first attribute value or text longer than MAX_TEXT_CHARS.

    The schema's types say the same, but libxml2 quotes a 10 MB value whole (and cuts the
    message); this says it in one short line. Neither an attribute value nor text holds a
    '<', so a file without a run of more than MAX_TEXT_CHARS bytes between two '<' has none
    (the common case: checked in C, without looking at every element).
    """
    if max(map(len, data.split(b"<"))) <= MAX_TEXT_CHARS:
        return
    for el in root.iter():
        for attr, value in el.attrib.items():
            if len(value) > MAX_TEXT_CHARS:
                raise WorldError(f"attribute {attr} is {len(value)} characters long (at most "
                                 f"{MAX_TEXT_CHARS})", file=name, line=el.sourceline)
        for text in (el.text, el.tail):
            if text is not None and len(text) > MAX_TEXT_CHARS and text.strip():
                raise WorldError(f"<{el.tag}> holds {len(text)} characters of text (at most "
                                 f"{MAX_TEXT_CHARS})", file=name, line=el.sourceline)


def _doctype_line(data: bytes) -> int:
    idx = data.find(b"<!DOCTYPE")
    if idx < 0:
        idx = data.find(b"<!ENTITY")
    return data.count(b"\n", 0, idx) + 1 if idx >= 0 else 1


def _floats(text: str, n: int, el, name: str, attr: str) -> tuple:
    parts = text.split()
    if len(parts) != n:
        raise WorldError(f"{attr} needs {n} numbers, got {text!r}", file=name, line=el.sourceline)
    return tuple(float(p) for p in parts)


def _scale(text: Optional[str], el, name: str) -> tuple:
    """A mesh's ``scale``: one factor for every axis, or three (x y z); all positive."""
    if text is None:
        return (1.0, 1.0, 1.0)
    parts = text.split()
    if len(parts) not in (1, 3):
        raise WorldError(f"scale needs 1 or 3 numbers, got {text!r}", file=name, line=el.sourceline)
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise WorldError(f"scale needs numbers, got {text!r}", file=name, line=el.sourceline) from None
    if not all(0 < v < float("inf") for v in values):
        raise WorldError(f"scale must be positive, got {text!r}", file=name, line=el.sourceline)
    return values * 3 if len(values) == 1 else values


def _b(v: Optional[str], default: bool) -> bool:
    if v is None:
        return default
    return v.strip() in ("true", "1")


def _pose_of(el, child: str = "pose") -> Pose:
    p = el.find(child)
    return _pose_attrs(p) if p is not None else Pose()


def _pose_attrs(el) -> Pose:
    g = el.get
    return Pose(float(g("x", 0)), float(g("y", 0)), float(g("z", 0)), float(g("roll", 0)),
                float(g("pitch", 0)), float(g("yaw", 0)))


class _Reader:
    def __init__(self, name: str):
        self.name = name

    def rgb(self, el, attr: str, default):
        v = el.get(attr)
        return default if v is None else _floats(v, 3, el, self.name, attr)

    def model(self, el) -> Model:
        if el is None:
            return Model()
        visuals = []
        for v in el:
            if not isinstance(v.tag, str):
                continue
            visuals.append(Visual(
                shape=v.tag, pose=_pose_of(v),
                size=_floats(v.get("size"), 3, v, self.name, "size") if v.get("size") else (0.0, 0.0, 0.0),
                radius=float(v.get("radius", 0)), length=float(v.get("length", 0)),
                file=v.get("file"), scale=_scale(v.get("scale"), v, self.name),
                color=self.rgb(v, "color", (0.7, 0.7, 0.7)), material=v.get("material", "matte"),
                name=v.get("name", ""), line=v.sourceline))
        return Model(visuals=visuals, ref=el.get("ref"), line=el.sourceline)

    def handle(self, el) -> Handle:
        return Handle(id=el.get("id"), pose=_pose_of(el), radius=float(el.get("radius", 0.01)),
                      length=float(el.get("length", 0.2)), standoff=float(el.get("standoff", 0.04)),
                      color=self.rgb(el, "color", (0.75, 0.75, 0.78)),
                      material=el.get("material", "shiny"), handle_kind=el.get("kind", "bar"),
                      line=el.sourceline)

    def knob(self, el) -> Knob:
        states = [KnobState(s.get("name"), float(s.get("angle")), line=s.sourceline)
                  for s in el.findall("state")]
        state = el.get("state")
        angle = el.get("angle")
        if angle is None:
            angle = next((s.angle for s in states if s.name == state), 0.0)
        shape = {role: (self.model(el.find(role)) if el.find(role) is not None else None)
                 for role in ("base", "grip", "marker")}
        base_el = el.find("base")
        return Knob(id=el.get("id"), pose=_pose_of(el), states=states, state=state,
                    angle=float(angle), radius=float(el.get("radius", 0.02)),
                    depth=float(el.get("depth", 0.025)),
                    color=self.rgb(el, "color", (0.85, 0.85, 0.85)),
                    marker_color=self.rgb(el, "markerColor", (0.05, 0.05, 0.05)),
                    off_state=el.get("off", ""), **shape,
                    base_fixed=base_el is not None and _b(base_el.get("fixed"), False),
                    symmetry=int(el.get("symmetry", 1)), turns=el.get("turns", "either"),
                    line=el.sourceline)

    def joint(self, el) -> Joint:
        return Joint(type=el.get("type"), origin=_pose_of(el, "origin"),
                     axis=_floats(el.get("axis", "0 0 1"), 3, el, self.name, "axis"),
                     lower=float(el.get("lower", 0)), upper=float(el.get("upper", 0)),
                     state=float(el.get("state", 0)), line=el.sourceline)

    def part(self, el) -> Part:
        return Part(id=el.get("id"), type=el.get("type"), name=el.get("name", ""),
                    joint=self.joint(el.find("joint")), model=self.model(el.find("model")),
                    handles=[self.handle(h) for h in el.findall("handle")],
                    knobs=[self.knob(k) for k in el.findall("knob")],
                    parts=[self.part(p) for p in el.findall("part")],
                    surfaces=[self.surface(s) for s in el.findall("surface")],
                    track=el.get("track", ""), line=el.sourceline)

    @staticmethod
    def surface(s) -> Surface:
        return Surface(s.get("id"), _pose_of(s), float(s.get("sizeX")), float(s.get("sizeY")),
                       s.get("relation", "on"), line=s.sourceline)

    def small(self, el) -> SmallObject:
        return SmallObject(
            id=el.get("id"), type=el.get("type"), pose=_pose_of(el),
            relation=el.get("relation", "on"), name=el.get("name", ""),
            description=(el.findtext("description") or "").strip(), color=el.get("color", ""),
            graspable=_b(el.get("graspable"), True),
            grasp_points=[GraspPoint(_pose_attrs(g), line=g.sourceline) for g in el.findall("graspPoint")],
            default_positions=[DefaultPosition(d.get("parent"), d.get("relation", "on"),
                                               _pose_attrs(d), line=d.sourceline)
                               for d in el.findall("defaultPosition")],
            model=self.model(el.find("model")), part=el.get("part", ""), line=el.sourceline)

    def large(self, el):
        parking_el = el.find("parking")
        kw = dict(
            id=el.get("id"), type=el.get("type"), pose=_pose_of(el), name=el.get("name", ""),
            description=(el.findtext("description") or "").strip(),
            model=self.model(el.find("model")),
            parking=[ParkingPosition(p.get("id"), Pose(float(p.get("x")), float(p.get("y")), 0.0,
                                                       0.0, 0.0, float(p.get("yaw", 0))),
                                     line=p.sourceline)
                     for p in parking_el.findall("position")],
            default_parking=parking_el.get("default"),
            graspable=_b(el.get("graspable"), False), static=_b(el.get("static"), True),
            affordances=(el.get("affordances") or "").split(),
            surfaces=[self.surface(s) for s in el.findall("surface")],
            children=[self.small(s) for s in el.findall("SmallObject")], line=el.sourceline)
        if el.tag == "LargeArticulatedObject":
            return LargeArticulatedObject(
                **kw, parts=[self.part(p) for p in el.findall("part")],
                handles=[self.handle(h) for h in el.findall("handle")],
                knobs=[self.knob(k) for k in el.findall("knob")])
        return LargeObject(**kw)

    @staticmethod
    def dock(el) -> Pose:
        d = el.find("dock")
        return Pose.planar(float(d.get("x")), float(d.get("y")), float(d.get("yaw", 0)))

    def room(self, el) -> Room:
        b = el.get("bounds")
        outline_el = el.find("outline")
        if outline_el is not None and b is not None:
            raise WorldError(f"room {el.get('id')!r}: give bounds or an outline, not both",
                             file=self.name, line=el.sourceline)
        outline = None if outline_el is None else [
            (float(c.get("x")), float(c.get("y"))) for c in outline_el.findall("corner")]
        return Room(id=el.get("id"), name=el.get("name"), pose=_pose_of(el),
                    pointcloud=el.get("pointcloud"),
                    bounds=_floats(b, 4, el, self.name, "bounds") if b else None,
                    outline=outline,
                    doorways=[Doorway(d.get("id"), _pose_of(d), float(d.get("width")),
                                      float(d.get("depth", 0.5)), d.get("to", ""),
                                      line=d.sourceline)
                              for d in el.findall("doorway")],
                    switches=[Switch(s.get("id"), s.get("type"), _pose_of(s), s.get("name", ""),
                                     _b(s.get("on"), False), line=s.sourceline)
                              for s in el.findall("switch")],
                    chargers=[Charger(c.get("id"), _pose_of(c), self.dock(c), c.get("name", ""),
                                      line=c.sourceline)
                              for c in el.findall("charger")],
                    objects=[self.large(o) for o in el
                             if o.tag in ("LargeObject", "LargeArticulatedObject")],
                    line=el.sourceline)

    def apartment(self, root) -> Apartment:
        lib = {}
        lib_el = root.find("library")
        if lib_el is not None:
            for m in lib_el.findall("model"):
                lib[m.get("id")] = self.model(m)
                lib[m.get("id")].ref = None
        hist = [HistoryEntry(float(c.get("time")), c.get("node"), c.get("field"), c.get("old"),
                             c.get("new"), c.get("source", ""))
                for c in root.findall("history/change")]
        stats = [SearchStat(s.get("object"), s.get("place"), int(s.get("searched", 0)),
                            int(s.get("found", 0)), line=s.sourceline)
                 for s in root.findall("searchStats/stat")]
        return Apartment(id=root.get("id"), name=root.get("name", ""),
                         rooms=[self.room(r) for r in root.findall("room")], library=lib,
                         history=hist, search_stats=stats, version=root.get("version"),
                         line=root.sourceline)


def parse_world(data: bytes, name: str = "<world>", base_dir: Optional[Path] = None,
                clock=None):
    """Parse, schema-validate and semantically check world XML; return a ``World``.

    Raises ``WorldValidationError`` listing every problem (each with file and line). Mesh and
    point-cloud files are looked for in ``base_dir`` (the world file's folder); without one, a
    map that names such a file is refused (nothing tells where to look).
    """
    from hearth.worldmodel.world import World

    if len(data) > MAX_FILE_BYTES:
        raise WorldError(_TOO_LARGE, file=name, line=0)
    tree = _parse_tree(data, name)
    root = tree.getroot()
    # The room limit is checked on the bare tree too, before the schema and the nodes are built:
    # a 30 MB file of 1,200 rooms is refused in a second instead of after every node is read.
    extra = next(itertools.islice(root.iter("room"), MAX_ROOMS, None), None)
    if extra is not None:
        raise WorldError(f"more than {MAX_ROOMS} rooms", file=name, line=extra.sourceline or 0)
    schema = _schema()
    if not schema.validate(tree):
        problems = [WorldError(_clean_schema_message(e.message), file=name, line=e.line)
                    for e in schema.error_log]
        raise WorldValidationError(problems)
    if root.get("version") != FORMAT_VERSION:
        raise WorldError(f"unsupported world format version {root.get('version')!r} "
                         f"(this Hearth reads version {FORMAT_VERSION})", file=name,
                         line=root.sourceline)
    try:
        apartment = _Reader(name).apartment(root)
    except WorldError:
        raise
    except (TypeError, ValueError) as err:  # pragma: no cover - the schema catches these
        raise WorldError(f"bad value: {err}", file=name, line=root.sourceline) from None
    problems = semantic_problems(apartment, name, base_dir)
    if problems:
        raise WorldValidationError(problems)
    return World(apartment, path=None, base_dir=base_dir, clock=clock)


_FACET = re.compile(r"\[facet '(?:min|max)(?:In|Ex)clusive'\] The value '(NaN|-?INF)' .*$")


_LONG_VALUE = re.compile(r"'([^']{40})[^']{20,}'")


def _clean_schema_message(msg: str) -> str:
    # lxml prefixes "Element 'x', attribute 'y': ..." -- already readable; drop schema URIs,
    # say what is wrong with NaN and INF (libxml2 calls NaN "greater than the maximum"), and
    # shorten quoted values (libxml2 quotes a 10 MB attribute whole).
    msg = _FACET.sub(r"'\1' is not a finite number", msg)
    msg = _LONG_VALUE.sub(r"'\1...'", msg)
    return msg.replace("{http://www.w3.org/2001/XMLSchema}", "xs:")


def load_world(path, clock=None):
    """Load a world file. Raises ``WorldError`` (with file and line) on any problem."""
    path = Path(path)
    data = read_limited(path, MAX_FILE_BYTES, WorldError, _TOO_LARGE)
    world = parse_world(data, str(path), base_dir=path.parent.resolve(), clock=clock)
    world.path = path
    return world


def validate_file(path) -> list[WorldError]:
    """Every problem in a world file (empty when it is valid)."""
    try:
        load_world(path)
    except WorldValidationError as err:
        return list(err.problems)
    except WorldError as err:
        return [err]
    return []


# --------------------------------------------------------------------------------------
# writing

def _num(v: float) -> str:
    r = repr(float(v))
    return r[:-2] if r.endswith(".0") else r


def _set_pose(parent, pose: Pose, tag: str = "pose") -> None:
    if pose == Pose():
        return
    el = etree.SubElement(parent, tag)
    for k, v in pose.as_dict().items():
        if v != 0.0:
            el.set(k, _num(v))


def _set_pose_attrs(el, pose: Pose) -> None:
    for k, v in pose.as_dict().items():
        if v != 0.0:
            el.set(k, _num(v))


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def _write_model(parent, model: Model, tag: str = "model", extra: Optional[dict] = None) -> None:
    if not model.visuals and model.ref is None and extra is None:
        return
    el = etree.SubElement(parent, tag)
    for k, v in (extra or {}).items():
        el.set(k, v)
    if model.ref is not None:
        el.set("ref", model.ref)
    for v in model.visuals:
        ve = etree.SubElement(el, v.shape)
        if v.shape == "box":
            ve.set("size", _vec(v.size))
        if v.shape in ("cylinder", "sphere"):
            ve.set("radius", _num(v.radius))
        if v.shape == "cylinder":
            ve.set("length", _num(v.length))
        if v.shape == "mesh":
            ve.set("file", v.file or "")
            if v.scale != (1.0, 1.0, 1.0):   # uniform: one number, as format 1 always had
                ve.set("scale", _num(v.scale[0]) if len(set(v.scale)) == 1 else _vec(v.scale))
        ve.set("color", _vec(v.color))
        if v.material != "matte":
            ve.set("material", v.material)
        if v.name:
            ve.set("name", v.name)
        _set_pose(ve, v.pose)


def _write_handle(parent, h: Handle) -> None:
    el = etree.SubElement(parent, "handle", id=h.id, radius=_num(h.radius), length=_num(h.length),
                          standoff=_num(h.standoff), color=_vec(h.color), material=h.material)
    if h.handle_kind != "bar":
        el.set("kind", h.handle_kind)
    _set_pose(el, h.pose)


def _write_knob(parent, k: Knob) -> None:
    el = etree.SubElement(parent, "knob", id=k.id, state=k.state, angle=_num(k.angle),
                          radius=_num(k.radius), depth=_num(k.depth), color=_vec(k.color),
                          markerColor=_vec(k.marker_color))
    if k.off_state:
        el.set("off", k.off_state)
    if k.symmetry != 1:
        el.set("symmetry", str(k.symmetry))
    if k.turns != "either":
        el.set("turns", k.turns)
    _set_pose(el, k.pose)
    for role in ("base", "grip", "marker"):
        model = getattr(k, role)
        if model is not None:
            extra = {"fixed": "true"} if role == "base" and k.base_fixed else {}
            _write_model(el, model, role, extra)
    for s in k.states:
        etree.SubElement(el, "state", name=s.name, angle=_num(s.angle))


def _write_part(parent, p: Part) -> None:
    el = etree.SubElement(parent, "part", id=p.id, type=p.type)
    if p.name:
        el.set("name", p.name)
    if p.track:
        el.set("track", p.track)
    j = p.joint
    je = etree.SubElement(el, "joint", type=j.type, axis=_vec(j.axis), lower=_num(j.lower),
                          upper=_num(j.upper), state=_num(j.state))
    _set_pose(je, j.origin, "origin")
    _write_model(el, p.model)
    _write_surfaces(el, p.surfaces)
    _write_fittings(el, p)


def _write_surfaces(el, surfaces) -> None:
    for s in surfaces:
        se = etree.SubElement(el, "surface", id=s.id, sizeX=_num(s.size_x), sizeY=_num(s.size_y),
                              relation=s.relation)
        _set_pose(se, s.pose)


def _write_fittings(el, node) -> None:
    """The handles, knobs and parts of an articulated object or of a part."""
    for h in node.handles:
        _write_handle(el, h)
    for k in node.knobs:
        _write_knob(el, k)
    for c in node.parts:
        _write_part(el, c)


def _write_small(parent, s: SmallObject) -> None:
    el = etree.SubElement(parent, "SmallObject", id=s.id, type=s.type, relation=s.relation,
                          graspable="true" if s.graspable else "false")
    if s.name:
        el.set("name", s.name)
    if s.color:
        el.set("color", s.color)
    if s.part:
        el.set("part", s.part)
    if s.description:
        etree.SubElement(el, "description").text = s.description
    _set_pose(el, s.pose)
    _write_model(el, s.model)
    for g in s.grasp_points:
        _set_pose_attrs(etree.SubElement(el, "graspPoint"), g.pose)
    for d in s.default_positions:
        de = etree.SubElement(el, "defaultPosition", parent=d.parent, relation=d.relation)
        _set_pose_attrs(de, d.pose)


def _write_large(parent, o) -> None:
    el = etree.SubElement(parent, o.kind, id=o.id, type=o.type)
    if o.name:
        el.set("name", o.name)
    el.set("graspable", "true" if o.graspable else "false")
    el.set("static", "true" if o.static else "false")
    if o.affordances:
        el.set("affordances", " ".join(o.affordances))
    if o.description:
        etree.SubElement(el, "description").text = o.description
    _set_pose(el, o.pose)
    _write_model(el, o.model)
    pk = etree.SubElement(el, "parking", default=o.default_parking)
    for p in o.parking:
        etree.SubElement(pk, "position", id=p.id, x=_num(p.pose.x), y=_num(p.pose.y),
                         yaw=_num(p.pose.yaw))
    _write_surfaces(el, o.surfaces)
    if isinstance(o, LargeArticulatedObject):
        _write_fittings(el, o)
    for c in o.children:
        _write_small(el, c)


def to_xml(apartment: Apartment) -> bytes:
    root = etree.Element("apartment", id=apartment.id, version=apartment.version or FORMAT_VERSION)
    if apartment.name:
        root.set("name", apartment.name)
    if apartment.library:
        lib = etree.SubElement(root, "library")
        for mid, m in apartment.library.items():
            _write_model(lib, m, extra={"id": mid})
    for r in apartment.rooms:
        re_ = etree.SubElement(root, "room", id=r.id, name=r.name)
        if r.pointcloud:
            re_.set("pointcloud", r.pointcloud)
        if r.bounds is not None and r.outline is None:
            re_.set("bounds", _vec(r.bounds))
        _set_pose(re_, r.pose)
        if r.outline is not None:
            oe = etree.SubElement(re_, "outline")
            for x, y in r.outline:
                etree.SubElement(oe, "corner", x=_num(x), y=_num(y))
        for d in r.doorways:
            de = etree.SubElement(re_, "doorway", id=d.id, width=_num(d.width),
                                  depth=_num(d.depth))
            if d.to:
                de.set("to", d.to)
            _set_pose(de, d.pose)
        for s in r.switches:
            se = etree.SubElement(re_, "switch", id=s.id, type=s.type, on="true" if s.on else "false")
            if s.name:
                se.set("name", s.name)
            _set_pose(se, s.pose)
        for c in r.chargers:
            ce = etree.SubElement(re_, "charger", id=c.id)
            if c.name:
                ce.set("name", c.name)
            _set_pose(ce, c.pose)
            etree.SubElement(ce, "dock", x=_num(c.dock.x), y=_num(c.dock.y), yaw=_num(c.dock.yaw))
        for o in r.objects:
            _write_large(re_, o)
    if apartment.search_stats:
        st = etree.SubElement(root, "searchStats")
        for s in apartment.search_stats:
            etree.SubElement(st, "stat", object=s.object, place=s.place, searched=str(s.searched),
                             found=str(s.found))
    if apartment.history:
        h = etree.SubElement(root, "history")
        for c in apartment.history:
            etree.SubElement(h, "change", time=_num(c.time), node=c.node, field=c.field,
                             old=c.old, new=c.new, source=c.source)
    return etree.tostring(root, pretty_print=True, xml_declaration=True, encoding="UTF-8")


def _temporary_names(target: Path) -> tuple[str, str]:
    return f".{target.name}.", ".tmp"


def clean_stale_temporaries(target: Path) -> list[Path]:
    """Remove the temporary files that killed saves of ``target`` left next to it; returns them.

    A save holds an exclusive ``flock`` on its temporary file while it writes it, and the
    kernel drops the lock when the process dies: a temporary file that no one holds locked is
    stale, one that is held belongs to a save in progress and is left alone.
    """
    prefix, suffix = _temporary_names(target)
    removed = []
    try:
        names = os.listdir(target.parent)
    except OSError:
        return removed
    for n in names:
        if not (n.startswith(prefix) and n.endswith(suffix)):
            continue
        p = target.parent / n
        try:
            fd = os.open(p, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        except OSError:
            continue
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                continue
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                continue
            try:
                if os.stat(p, follow_symlinks=False).st_ino == st.st_ino:
                    os.unlink(p)
                    removed.append(p)
            except FileNotFoundError:
                pass
        finally:
            os.close(fd)
    return removed


def atomic_write(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` so that readers see the old file or the new one, never a
    half-written one: a temporary file in the same directory, fsync, rename, fsync the dir.
    Returns the file written.

    A symbolic link stays a link: the file it names is replaced (its temporary file is made
    next to it). An existing file keeps its permission bits (and owner, where allowed); a new
    one gets the usual ``0666 & ~umask``. Temporary files of killed saves are removed first
    (``clean_stale_temporaries``).
    """
    target = Path(os.path.realpath(path))
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        old = os.stat(target)
    except FileNotFoundError:
        old = None
    clean_stale_temporaries(target)
    prefix, suffix = _temporary_names(target)
    for attempt in range(2):
        tmp = target.parent / f"{prefix}{secrets.token_hex(6)}{suffix}"
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW,
                     0o666 if old is None else 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)   # marks it as in use (clean_stale_temporaries)
            if old is not None:
                os.fchmod(fd, stat.S_IMODE(old.st_mode))
                if (old.st_uid, old.st_gid) != (os.geteuid(), os.getegid()):
                    try:
                        os.fchown(fd, old.st_uid, old.st_gid)
                    except OSError:
                        pass
            with os.fdopen(fd, "wb", closefd=False) as f:
                f.write(data)
                f.flush()
            os.fsync(fd)
            os.replace(tmp, target)
        except FileNotFoundError as err:
            # Another process's clean-up can only take our file in the instant between its
            # creation and the lock: write again once.
            if attempt == 0 and err.filename == str(tmp) and not os.path.lexists(tmp):
                continue
            _unlink_quietly(tmp)
            raise
        except BaseException:
            _unlink_quietly(tmp)
            raise
        finally:
            os.close(fd)
        break
    try:
        dfd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:  # pragma: no cover - some filesystems refuse directory fsync
        pass
    return target


def _unlink_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


def checked_xml(apartment: Apartment, name: str = "<world>",
                base_dir: Optional[Path] = None) -> bytes:
    """``to_xml(apartment)`` after checking that ``load_world`` would read it back: the map in
    memory is checked (problems name their node), then the bytes go through the loader itself
    (schema, limits, semantics, files relative to ``base_dir``). Raises WorldError; nothing
    is written here."""
    problems = semantic_problems(apartment, None, base_dir)
    if problems:
        raise WorldValidationError([WorldError(f"not saved: {p.message.removeprefix(f'{p.node}: ')}",
                                               node=p.node) for p in problems])
    try:
        data = to_xml(apartment)
    except (TypeError, ValueError) as err:
        raise WorldError(f"not saved: the map cannot be written as XML ({err})", file=name,
                         line=0) from None
    try:
        parse_world(data, name, base_dir=base_dir)
    except WorldValidationError as err:
        raise WorldValidationError([_would_not_load(p, name) for p in err.problems]) from None
    except WorldError as err:
        raise _would_not_load(err, name) from None
    return data


def _would_not_load(err: WorldError, name: str) -> WorldError:
    return WorldError(f"not saved, it would not load back: {err.message} (line {err.line} of "
                      "the file it would write)", file=name, line=0)


def save_world(world, path=None) -> Path:
    """Save atomically (see ``atomic_write``); returns the path written (``path``, or the
    world's own path; through a symbolic link, the link).

    Refuses, with WorldError and nothing written, a map that ``load_world`` would refuse
    (``checked_xml``): a NaN pose, a zero radius, a mesh outside the target's folder.
    """
    path = Path(path or world.path)
    base_dir = Path(os.path.realpath(path)).parent
    with world.lock:
        data = checked_xml(world.apartment, str(path), base_dir)
    atomic_write(path, data)
    return path
