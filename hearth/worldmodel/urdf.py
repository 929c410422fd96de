"""Import an articulated object from URDF into a ``LargeArticulatedObject``.

Mapping (documented in docs/world-format.md):

- the root link (the one no joint names as child) -> the object's model;
- a ``revolute`` or ``prismatic`` joint -> a ``Part`` named after its child link, with the
  joint's ``origin`` (xyz, rpy: the same fixed-axis convention as Hearth poses), ``axis``,
  ``limit lower/upper`` and state 0 clipped into the limits; part type "door" for revolute,
  "drawer" for prismatic; ``continuous`` joints are revolute with limits -pi..pi;
- a ``fixed`` joint -> the child link's visuals are merged into the parent (moved by the
  origin), except a child link whose name contains "handle", which becomes a ``Handle`` at the
  joint origin (bar length and radius from its cylinder or box visual);
- visuals: box, cylinder (URDF cylinders are along z, as Hearth's), sphere, mesh (filename
  kept relative; ``package://`` prefixes are stripped; ``scale`` x y z kept per axis),
  material rgba -> colour.

The URDF is parsed with the same safe parser as world files (no entities, no network). A
problem (a joint without ``<parent>`` or ``<child>``, a bad number, a link with two parents)
is a ``WorldError`` with the file and the line of the element at fault.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from hearth.util.files import read_limited
from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.io import _TOO_LARGE, MAX_FILE_BYTES, _parse_tree
from hearth.worldmodel.nodes import (
    Handle, Joint, LargeArticulatedObject, Model, ParkingPosition, Part, Visual,
)
from hearth.worldmodel.pose import Pose


class _Bad(ValueError):
    """A bad value at ``el`` (turned into a WorldError with the file and el's line)."""

    def __init__(self, message: str, el):
        super().__init__(message)
        self.line = getattr(el, "sourceline", None)


def _vec(text: Optional[str], n: int, default: float = 0.0, el=None, attr: str = "") -> tuple:
    if not text:
        return tuple([default] * n)
    try:
        vals = tuple(float(v) for v in text.split())
    except ValueError:
        vals = ()
    if len(vals) != n:
        raise _Bad(f"{attr or 'value'}: expected {n} numbers, got {text!r}", el)
    return vals


def _number(el, attr: str, default: Optional[float] = None) -> float:
    text = el.get(attr)
    if text is None and default is not None:
        return default
    try:
        return float(text)
    except (TypeError, ValueError):
        raise _Bad(f"<{el.tag}> needs a number {attr}=, got {text!r}", el) from None


def _link_of(joint, tag: str) -> str:
    """The link named by the joint's ``<parent>`` or ``<child>`` element."""
    el = joint.find(tag)
    if el is None or not el.get("link"):
        raise _Bad(f"joint {joint.get('name')!r} needs <{tag} link=\"...\"/>",
                   joint if el is None else el)
    return el.get("link")


def _origin(el) -> Pose:
    o = el.find("origin") if el is not None else None
    if o is None:
        return Pose()
    x, y, z = _vec(o.get("xyz"), 3, el=o, attr="xyz")
    r, p, yw = _vec(o.get("rpy"), 3, el=o, attr="rpy")
    return Pose(x, y, z, r, p, yw)


def _visuals(link, name: str, materials: dict) -> list[Visual]:
    out = []
    for v in link.findall("visual"):
        pose = _origin(v)
        g = v.find("geometry")
        if g is None or len(g) == 0:
            raise WorldError(f"link {link.get('name')!r}: visual without geometry", file=name,
                             line=v.sourceline)
        shape = g[0]
        color = (0.7, 0.7, 0.7)
        mat = v.find("material")
        if mat is not None:
            c = mat.find("color")
            if c is not None:
                color = tuple(_vec(c.get("rgba"), 4, el=c, attr="rgba")[:3])
            elif mat.get("name") in materials:
                color = materials[mat.get("name")]
        if shape.tag == "box":
            out.append(Visual("box", pose, size=_vec(shape.get("size"), 3, el=shape, attr="size"),
                              color=color))
        elif shape.tag == "cylinder":
            out.append(Visual("cylinder", pose, radius=_number(shape, "radius"),
                              length=_number(shape, "length"), color=color))
        elif shape.tag == "sphere":
            out.append(Visual("sphere", pose, radius=_number(shape, "radius"), color=color))
        elif shape.tag == "mesh":
            fn = shape.get("filename", "")
            if fn.startswith("package://"):
                fn = fn.split("/", 3)[-1]
            scale = _vec(shape.get("scale"), 3, 1.0, el=shape, attr="scale")
            if not all(s > 0 for s in scale):
                raise _Bad(f"scale must be positive, got {shape.get('scale')!r}", shape)
            out.append(Visual("mesh", pose, file=fn, scale=scale, color=color))
        else:
            raise WorldError(f"unsupported geometry {shape.tag!r}", file=name, line=shape.sourceline)
    return out


def import_urdf(source, object_id: str, object_type: str = "cupboard",
                pose: Pose = Pose(), name: str = "",
                parking: Optional[list[ParkingPosition]] = None) -> LargeArticulatedObject:
    """Read URDF (a path or bytes) into a ``LargeArticulatedObject`` with id ``object_id``.

    ``parking`` defaults to one position 0.8 m in front (+x) of the object, facing it.
    """
    if isinstance(source, (bytes, bytearray)):
        data, fname = bytes(source), "<urdf>"
    else:
        fname = str(source)
        # a regular file of at most a world file's size (a FIFO or /dev/zero is refused)
        data = read_limited(source, MAX_FILE_BYTES, WorldError, _TOO_LARGE)
    root = _parse_tree(data, fname).getroot()
    if root.tag != "robot":
        raise WorldError("URDF root element must be <robot>", file=fname, line=root.sourceline)
    try:
        return _convert(root, fname, object_id, object_type, pose, name, parking)
    except _Bad as err:
        raise WorldError(f"bad URDF: {err}", file=fname,
                         line=err.line if err.line is not None else root.sourceline) from None
    except (TypeError, ValueError) as err:
        raise WorldError(f"bad URDF value: {err}", file=fname, line=root.sourceline) from None


def _convert(root, fname, object_id, object_type, pose, name, parking):
    materials = {}
    for m in root.findall("material"):
        c = m.find("color")
        if c is not None:
            materials[m.get("name")] = tuple(_vec(c.get("rgba"), 4, el=c, attr="rgba")[:3])
    links = {l.get("name"): l for l in root.findall("link")}
    joints = root.findall("joint")
    parent_joint: dict[str, object] = {}
    for j in joints:
        child = _link_of(j, "child")
        _link_of(j, "parent")
        if child in parent_joint:
            # Also what stops a cycle of joints: every link but the root has one parent.
            raise _Bad(f"link {child!r} is the child of two joints "
                       f"({parent_joint[child].get('name')!r} and {j.get('name')!r})", j)
        parent_joint[child] = j
    roots = [n for n in links if n not in parent_joint]
    if len(roots) != 1:
        raise WorldError(f"URDF must have exactly one root link, found {roots}", file=fname,
                         line=root.sourceline)
    by_parent: dict[str, list] = {}
    for j in joints:
        parent = _link_of(j, "parent")
        child = _link_of(j, "child")
        if parent not in links or child not in links:
            raise WorldError(f"joint {j.get('name')!r} names an unknown link", file=fname,
                             line=j.sourceline)
        by_parent.setdefault(parent, []).append(j)

    def collect(link_name: str, T_link_acc: np.ndarray, visuals: list, parts: list,
                handles: list) -> None:
        """Walk from a link, merging fixed children into ``visuals`` (in the frame of the
        part being built) and turning moving joints into parts."""
        for j in by_parent.get(link_name, []):
            jtype = j.get("type")
            child = _link_of(j, "child")
            origin = _origin(j)
            T_child = T_link_acc @ origin.matrix()
            if jtype == "fixed":
                if "handle" in child.lower():
                    handles.append(_handle(child, Pose.from_matrix(T_child), links[child], fname,
                                           materials))
                else:
                    for v in _visuals(links[child], fname, materials):
                        visuals.append(_moved(v, T_child))
                    collect(child, T_child, visuals, parts, handles)
                continue
            if jtype not in ("revolute", "prismatic", "continuous"):
                raise WorldError(f"joint {j.get('name')!r}: unsupported type {jtype!r}",
                                 file=fname, line=j.sourceline)
            axis_el = j.find("axis")
            axis = _vec(axis_el.get("xyz") if axis_el is not None else "1 0 0", 3,
                        el=axis_el, attr="axis xyz")
            lim = j.find("limit")
            if jtype == "continuous":
                lower, upper = -math.pi, math.pi
            else:
                if lim is None:
                    raise WorldError(f"joint {j.get('name')!r} needs <limit>", file=fname,
                                     line=j.sourceline)
                lower, upper = _number(lim, "lower", 0.0), _number(lim, "upper", 0.0)
            state = min(max(0.0, lower), upper)
            part_visuals: list[Visual] = list(_visuals(links[child], fname, materials))
            sub_parts: list[Part] = []
            part_handles: list[Handle] = []
            collect(child, np.eye(4), part_visuals, sub_parts, part_handles)
            parts.append(Part(
                id=child, type="door" if jtype != "prismatic" else "drawer",
                joint=Joint("revolute" if jtype == "continuous" else jtype,
                            origin=Pose.from_matrix(T_child), axis=axis, lower=lower,
                            upper=upper, state=state, line=j.sourceline),
                name=child.replace("_", " "), model=Model(part_visuals), handles=part_handles,
                parts=sub_parts, line=j.sourceline))

    base_visuals = list(_visuals(links[roots[0]], fname, materials))
    parts: list[Part] = []
    handles: list[Handle] = []
    collect(roots[0], np.eye(4), base_visuals, parts, handles)
    if parking is None:
        parking = [ParkingPosition(f"{object_id}_front", Pose(0.8, 0, 0, 0, 0, math.pi))]
    return LargeArticulatedObject(
        id=object_id, type=object_type, pose=pose, name=name or root.get("name", ""),
        model=Model(base_visuals), parking=parking, default_parking=parking[0].id,
        affordances=["openable"], parts=parts, handles=handles)


def _moved(v: Visual, T: np.ndarray) -> Visual:
    from dataclasses import replace
    return replace(v, pose=Pose.from_matrix(T @ v.pose.matrix()))


def _handle(link_name, pose: Pose, link, fname, materials) -> Handle:
    vis = _visuals(link, fname, materials)
    radius, length = 0.01, 0.2
    for v in vis:
        if v.shape == "cylinder":
            radius, length = v.radius, v.length
            pose = Pose.from_matrix(pose.matrix() @ v.pose.matrix())
            break
        if v.shape == "box":
            length = max(v.size)
            radius = min(v.size) / 2
            pose = Pose.from_matrix(pose.matrix() @ v.pose.matrix())
            break
    return Handle(link_name, pose, radius=radius, length=length)
