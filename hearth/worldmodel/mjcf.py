"""Import an articulated appliance from MJCF (MuJoCo's model format) into a world.

MuJoCo itself reads the file (includes, defaults and classes, mesh files of every format it
knows, compiler options), so what is imported is what MuJoCo would simulate; this module walks
the compiled model (docs/renderers-and-assets.md, "Importing a model"):

- the whole model is one ``LargeArticulatedObject``; bodies without a joint are merged into
  the model of the part (or object) they hang from, moved by their pose at the model's
  reference configuration (``qpos0``);
- a body with a hinge joint whose geometry stays within ``KNOB_MAX_RADIUS`` of the axis and
  ``KNOB_MAX_DEPTH`` along it is a ``Knob``: its frame at the joint, +z along the axis out
  of the appliance (away from its parent's geometry), its angle the joint's position (sign
  kept when +z is the axis); its states: ``off`` at the position nearest 0 within the joint's
  range, and ``KNOB_SETTINGS`` settings spread over the longer side of the travel (named
  "1", "2", ...); its shape: the geoms of its subtree, those of a colour far from the largest
  geom's (and smaller than it) its ``marker``, the rest its ``grip``; ``radius`` and ``depth``
  from that shape;
- the front (towards the room, the object's +x): where the horizontal knob axes point, else
  the model's -x (``--front`` to say);
- any other hinge is a door, a slide joint a drawer (a ``Part`` with the joint's range and
  the part's state at ``qpos0`` clipped into it); a body or geom whose name says "handle"
  on a part becomes that part's ``Handle`` (bar along its longest side);
- visual geoms only: those of MuJoCo's visual groups 1-2 when the model has any (robosuite,
  LIBERO and Meta-World keep collision geoms in other groups), else every geom that is not
  transparent; boxes, cylinders and spheres stay primitives, capsules become a cylinder and
  two spheres, meshes (and ellipsoids) are written as PLY files beside the world;
  colour: the geom's rgba, else its material's; textures are not carried.

``import_model(path, out_dir)`` writes a world (``world.xml`` and ``meshes/``) with the
appliance in a kitchen, on a counter when it is shorter than a counter (a cooktop), its
front towards the room, parking positions in front of it. Problems are ``WorldError`` with
the file (MuJoCo's own message, which names the line where it has one).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional

import numpy as np

from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.nodes import (
    Apartment, Handle, Joint, Knob, KnobState, LargeArticulatedObject, LargeObject, Model,
    ParkingPosition, Part, Room, Visual,
)
from hearth.worldmodel.pose import Pose

#: A hinge whose geometry stays this close to its axis (m) ...
KNOB_MAX_RADIUS = 0.07
#: ... and this short along it (m) is a knob.
KNOB_MAX_DEPTH = 0.09
#: Settings besides "off" given to an imported knob.
KNOB_SETTINGS = 3
#: A marker's colour differs from the grip's by at least this (RGB distance, 0..1.7).
MARKER_COLOR_DISTANCE = 0.35
#: An appliance lower than this (m) stands on a counter of this height.
COUNTER_HEIGHT = 0.9

_GEOM_PLANE, _GEOM_SPHERE, _GEOM_CAPSULE, _GEOM_ELLIPSOID = 0, 2, 3, 4
_GEOM_CYLINDER, _GEOM_BOX, _GEOM_MESH = 5, 6, 7
_JNT_SLIDE, _JNT_HINGE = 2, 3


def _mujoco():
    try:
        import mujoco
    except ImportError:
        raise WorldError("importing MJCF needs the mujoco package: pip install 'hearth[mujoco]'",
                         file="") from None
    return mujoco


def _T(pos, quat_wxyz) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    w, x, y, z = (float(q) for q in quat_wxyz)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    T[:3, 3] = pos
    return T


def _slug(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_]+", "_", text).strip("_")
    return s if s and not s[0].isdigit() else f"n_{s}"


@dataclass
class _Geom:
    """One visual geom, in the world frame of the model at ``qpos0``, with its primitive."""
    index: int
    body: int
    T: np.ndarray
    visual: Visual           # in the geom's own frame (pose identity) but for capsules' parts
    points: np.ndarray       # a few points of its surface (world), for extents


def _flattened(path: Path) -> str:
    """The MJCF at ``path`` as one text MuJoCo compiles from anywhere: ``<include>``s
    expanded, asset files made absolute (a mesh's against the compiler's ``meshdir``), and
    textures dropped (Hearth keeps colours, not images; models in the wild carry texture
    quirks MuJoCo refuses, such as two textures of one name in LIBERO's stoves). Parsed with
    the world files' safe parser (no entities, no network)."""
    from hearth.worldmodel.io import _parse_tree
    root = _parse_tree(path.read_bytes(), str(path)).getroot()
    home = path.parent
    comp = root.find("compiler")
    meshdir = home
    if comp is not None:
        for key in ("assetdir", "meshdir"):
            if comp.get(key):
                meshdir = (home / comp.get(key)).resolve()
        for key in ("assetdir", "meshdir", "texturedir"):
            comp.attrib.pop(key, None)

    def expand(el, base: Path, depth: int = 0) -> None:
        for child in list(el):
            if not isinstance(child.tag, str):
                continue
            if child.tag == "include":
                if depth > 20:
                    raise WorldError("includes nested too deep", file=str(path), line=child.sourceline)
                f = (base / child.get("file", "")).resolve()
                sub = _parse_tree(f.read_bytes(), str(f)).getroot()
                expand(sub, f.parent, depth + 1)
                i = list(el).index(child)
                el.remove(child)
                for j, c in enumerate(list(sub)):
                    el.insert(i + j, c)
                continue
            if child.tag == "texture" or child.tag == "hfield":
                el.remove(child)
                continue
            if child.tag in ("material",):
                child.attrib.pop("texture", None)
            if child.tag == "mesh" and child.get("file"):
                child.set("file", str((meshdir / child.get("file")).resolve()))
            if child.tag == "skin" and child.get("file"):
                child.set("file", str((meshdir / child.get("file")).resolve()))
            expand(child, base, depth)
    expand(root, home)
    from lxml import etree
    return etree.tostring(root, encoding="unicode")


class _Model:
    """The compiled MuJoCo model and what the import needs of it."""

    def __init__(self, path: Path):
        mujoco = _mujoco()
        try:
            self.m = mujoco.MjModel.from_xml_string(_flattened(path))
        except ValueError as err:
            raise WorldError(f"MuJoCo cannot read this model: {err}", file=str(path)) from None
        self.d = mujoco.MjData(self.m)
        mujoco.mj_kinematics(self.m, self.d)
        self.mj = mujoco
        m = self.m
        self.name = lambda kind, i: mujoco.mj_id2name(m, kind, i) or ""
        groups = set(int(g) for g in m.geom_group)
        self.visual_groups = {1, 2} & groups or groups

    def body_T(self, b: int) -> np.ndarray:
        return _T(self.d.xpos[b], self.d.xquat[b])

    def geom_color(self, g: int) -> tuple:
        m = self.m
        rgba = m.geom_rgba[g]
        if m.geom_matid[g] >= 0 and np.allclose(rgba, (0.5, 0.5, 0.5, 1.0)):
            rgba = m.mat_rgba[m.geom_matid[g]]
        return tuple(float(c) for c in rgba)

    def visual(self, g: int) -> bool:
        return (int(self.m.geom_group[g]) in self.visual_groups
                and self.geom_color(g)[3] > 0.05 and int(self.m.geom_type[g]) != _GEOM_PLANE)


def import_model(path, out_dir, object_id: str = "", object_type: str = "",
                 name: str = "", front: str = "auto", body: str = "") -> Path:
    """Write ``out_dir/world.xml`` (and ``out_dir/meshes/``): a kitchen holding the MJCF
    model at ``path`` as an appliance (see the module's docstring). ``front``: the model's
    axis ("+x", "-x", "+y", "-y") that faces the room, "auto": the side the horizontal knob
    axes point to (knobs on a front panel), else -x (knobs on top: LIBERO's and Meta-World's
    robots stand on the -x side). Returns the world file's path."""
    from hearth.worldmodel.io import atomic_write, load_world, to_xml
    path, out = Path(path), Path(out_dir)
    if not path.is_file():
        raise WorldError("no such file", file=str(path))
    mm = _Model(path)
    base = _slug(path.stem)
    object_id = object_id or base
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    obj, size = _convert(mm, path, out, object_id, object_type or _guess_type(body or path.stem),
                         name or (body or path.stem).replace("_", " "), front, body)
    apartment = _kitchen(obj, size)
    data = to_xml(apartment)
    target = out / "world.xml"
    atomic_write(target, data)
    load_world(target)            # what we wrote must load and validate
    return target


def _guess_type(stem: str) -> str:
    s = stem.lower()
    for word in ("oven", "stove", "cooktop", "hob", "cooker", "microwave", "dial"):
        if word in s:
            return {"cooktop": "stove", "hob": "stove", "dial": "appliance"}.get(word, word)
    return "appliance"


# -- the walk ------------------------------------------------------------------------------

def _geoms(mm: _Model, out: Path, meshes: dict, bodies: set) -> dict[int, list[_Geom]]:
    """Visual geoms of ``bodies`` by body, world frame at qpos0."""
    m, d = mm.m, mm.d
    by_body: dict[int, list[_Geom]] = {}
    for g in range(m.ngeom):
        if int(m.geom_bodyid[g]) not in bodies or not mm.visual(g):
            continue
        T = _T(d.geom_xpos[g], _quat_of(d.geom_xmat[g]))
        color = mm.geom_color(g)[:3]
        size = m.geom_size[g]
        gname = mm.name(mm.mj.mjtObj.mjOBJ_GEOM, g)
        kind = int(m.geom_type[g])
        vis: list[tuple[np.ndarray, Visual]] = []
        if kind == _GEOM_BOX:
            vis.append((np.eye(4), Visual("box", size=tuple(2 * float(s) for s in size), color=color,
                                          name=gname)))
        elif kind == _GEOM_CYLINDER:
            vis.append((np.eye(4), Visual("cylinder", radius=float(size[0]),
                                          length=2 * float(size[1]), color=color, name=gname)))
        elif kind == _GEOM_SPHERE:
            vis.append((np.eye(4), Visual("sphere", radius=float(size[0]), color=color, name=gname)))
        elif kind == _GEOM_CAPSULE:
            r, h = float(size[0]), float(size[1])
            vis.append((np.eye(4), Visual("cylinder", radius=r, length=2 * h, color=color, name=gname)))
            for s in (-1, 1):
                Ts = np.eye(4)
                Ts[2, 3] = s * h
                vis.append((Ts, Visual("sphere", radius=r, color=color, name=gname)))
        elif kind in (_GEOM_MESH, _GEOM_ELLIPSOID):
            file = _mesh_file(mm, g, out, meshes)
            if file is None:
                continue
            vis.append((np.eye(4), Visual("mesh", file=file, color=color, name=gname)))
        else:
            continue
        for Tl, v in vis:
            Tw = T @ Tl
            by_body.setdefault(int(m.geom_bodyid[g]), []).append(
                _Geom(g, int(m.geom_bodyid[g]), Tw, v, _surface_points(v, Tw, meshes, out)))
    return by_body


def _quat_of(xmat) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    x, y, z, w = Rotation.from_matrix(np.asarray(xmat, dtype=float).reshape(3, 3)).as_quat()
    return np.array([w, x, y, z])


def _mesh_file(mm: _Model, g: int, out: Path, meshes: dict) -> Optional[str]:
    """A PLY file (relative to ``out``) of geom ``g``'s mesh (an ellipsoid: a unit sphere
    scaled), in the geom's frame; written once per mesh."""
    import open3d as o3d
    m = mm.m
    if int(m.geom_type[g]) == _GEOM_ELLIPSOID:
        key = ("ellipsoid", tuple(np.round(m.geom_size[g], 6)))
        if key not in meshes:
            sphere = o3d.geometry.TriangleMesh.create_sphere(1.0, resolution=16)
            sphere.vertices = o3d.utility.Vector3dVector(np.asarray(sphere.vertices) * m.geom_size[g][:3])
            meshes[key] = (f"meshes/ellipsoid_{len(meshes)}.ply", sphere)
            o3d.io.write_triangle_mesh(str(out / meshes[key][0]), sphere)
        return meshes[key][0]
    mid = int(m.geom_dataid[g])
    if mid < 0:
        return None
    key = ("mesh", mid)
    if key not in meshes:
        va, vn = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
        fa, fn = int(m.mesh_faceadr[mid]), int(m.mesh_facenum[mid])
        mesh = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(np.asarray(m.mesh_vert[va:va + vn], dtype=np.float64)),
            o3d.utility.Vector3iVector(np.asarray(m.mesh_face[fa:fa + fn], dtype=np.int32)))
        name = _slug(mm.name(mm.mj.mjtObj.mjOBJ_MESH, mid) or f"mesh{mid}")
        meshes[key] = (f"meshes/{name}_{mid}.ply", mesh)
        o3d.io.write_triangle_mesh(str(out / meshes[key][0]), mesh, write_ascii=False)
    return meshes[key][0]


def _surface_points(v: Visual, T: np.ndarray, meshes: dict, out: Path) -> np.ndarray:
    if v.shape == "mesh":
        mesh = next(mh for f, mh in meshes.values() if f == v.file)
        p = np.asarray(mesh.vertices)
    elif v.shape == "box":
        p = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * np.asarray(v.size) / 2
    elif v.shape == "cylinder":
        a = np.linspace(0, 2 * math.pi, 16, endpoint=False)
        ring = np.stack([v.radius * np.cos(a), v.radius * np.sin(a)], axis=1)
        p = np.vstack([np.hstack([ring, np.full((16, 1), s * v.length / 2)]) for s in (-1, 1)])
    else:
        p = np.vstack([np.eye(3), -np.eye(3)]) * v.radius
    return p @ T[:3, :3].T + T[:3, 3]


def _convert(mm: _Model, path: Path, out: Path, object_id: str, object_type: str, name: str,
             front: str, body: str = "") -> tuple:
    m = mm.m
    root = 0
    if body:
        root = mm.mj.mj_name2id(m, mm.mj.mjtObj.mjOBJ_BODY, body)
        if root < 0:
            names = sorted(n for n in (mm.name(mm.mj.mjtObj.mjOBJ_BODY, b) for b in range(m.nbody)) if n)
            raise WorldError(f"the model has no body {body!r} (bodies: {', '.join(names[:30])})",
                             file=str(path))
    meshes: dict = {}
    children: dict[int, list[int]] = {}
    for b in range(1, m.nbody):
        children.setdefault(int(m.body_parentid[b]), []).append(b)

    def subtree(b: int) -> list[int]:
        out_ = [b]
        for c in children.get(b, []):
            out_ += subtree(c)
        return out_

    def joint_of(b: int) -> Optional[int]:
        for j in range(int(m.body_jntadr[b]), int(m.body_jntadr[b]) + int(m.body_jntnum[b])):
            if int(m.jnt_type[j]) in (_JNT_HINGE, _JNT_SLIDE):
                return j
        return None

    def points(bodies) -> np.ndarray:
        ps = [g.points for b in bodies for g in geoms.get(b, [])]
        return np.vstack(ps) if ps else np.zeros((0, 3))

    in_root = set(subtree(root))
    geoms = _geoms(mm, out, meshes, in_root)
    all_pts = points(in_root)
    if len(all_pts) == 0:
        raise WorldError("the model has no visible geometry", file=str(path))
    # The object frame: z = 0 at the model's lowest point, the front towards +x.
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    joints = {b: joint_of(b) for b in in_root if b != root}
    knob_like = {}
    for b, j in joints.items():
        if j is None or int(m.jnt_type[j]) != _JNT_HINGE:
            continue
        axis_w = mm.d.xaxis[j].copy()
        anchor = mm.d.xanchor[j].copy()
        p = points(subtree(b))
        if len(p) == 0:
            continue
        rel = p - anchor
        along = rel @ axis_w
        radial = np.linalg.norm(rel - np.outer(along, axis_w), axis=1)
        if radial.max() <= KNOB_MAX_RADIUS and np.ptp(along) <= KNOB_MAX_DEPTH:
            knob_like[b] = (axis_w, anchor)
    yaw = _front_yaw(front, knob_like, m, joints, mm, lo, hi)
    T_obj_model = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T_obj_model[:2, :2] = [[c, -s], [s, c]]
    centre = (lo + hi) / 2
    T_obj_model[:3, 3] = -(T_obj_model[:3, :3] @ np.array([centre[0], centre[1], lo[2]]))

    used_ids: set[str] = {object_id}

    def new_id(text: str) -> str:
        base = f"{object_id}_{_slug(text)}" if text else f"{object_id}_node"
        i, nid = 1, base
        while nid in used_ids:
            i += 1
            nid = f"{base}_{i}"
        used_ids.add(nid)
        return nid

    def visuals_in(bodies, T_frame_world) -> list[Visual]:
        outv = []
        for b in bodies:
            for g in geoms.get(b, []):
                outv.append(replace(g.visual, pose=Pose.from_matrix(T_frame_world @ g.T)))
        return outv

    def static_bodies(b: int) -> list[int]:
        """``b`` and the descendants reached without crossing a joint."""
        out_ = [b]
        for c in children.get(b, []):
            if joints.get(c) is None:
                out_ += static_bodies(c)
        return out_

    def moving_below(static: list[int]) -> list[int]:
        """The bodies with a joint whose parent is one of ``static``."""
        return [c for b in static for c in children.get(b, []) if joints.get(c) is not None]

    def knob(b: int, T_world_parent: np.ndarray) -> Knob:
        j = joints[b]
        axis_w, anchor = knob_like[b]
        p = points(subtree(b))
        # +z out of the appliance: towards where the knob's geometry stands from its joint,
        # else away from its parent's geometry.
        reach = float(((p - anchor) @ axis_w).mean())
        if abs(reach) < 0.002:
            parent_c = points(static_bodies(int(m.body_parentid[b])))
            ref = parent_c.mean(axis=0) if len(parent_c) else (lo + hi) / 2
            reach = float((p.mean(axis=0) - ref) @ axis_w)
        sign = 1.0 if reach >= 0 else -1.0
        z = sign * axis_w
        back = float(((p - anchor) @ z).min())
        R_body = mm.body_T(b)[:3, :3]
        y0 = R_body[:, 1] - (R_body[:, 1] @ z) * z
        if np.linalg.norm(y0) < 1e-6:
            y0 = R_body[:, 0] - (R_body[:, 0] @ z) * z
        y0 /= np.linalg.norm(y0)
        T_wk = np.eye(4)
        T_wk[:3, :3] = np.column_stack([np.cross(y0, z), y0, z])
        T_wk[:3, 3] = anchor + back * z
        T_kw = np.linalg.inv(T_wk)
        vis = visuals_in(subtree(b), T_kw)
        pk = p @ T_kw[:3, :3].T + T_kw[:3, 3]
        radius = float(np.linalg.norm(pk[:, :2], axis=1).max())
        depth = float(pk[:, 2].max())
        grip, marker = _split_marker(vis, subtree(b), geoms)
        lo_j, hi_j = (float(m.jnt_range[j][0]), float(m.jnt_range[j][1])) if m.jnt_limited[j] \
            else (-math.pi, math.pi)
        off_q = min(max(0.0, lo_j), hi_j)
        end = hi_j if (hi_j - off_q) >= (off_q - lo_j) else lo_j
        if not m.jnt_limited[j]:
            end = off_q + math.radians(270)
        states = [KnobState("off", sign * off_q)]
        for i in range(1, KNOB_SETTINGS + 1):
            states.append(KnobState(str(i), sign * (off_q + (end - off_q) * i / KNOB_SETTINGS)))
        turns = "either"
        if m.jnt_limited[j]:
            turns = "counterclockwise" if sign * (end - off_q) > 0 else "clockwise"
        kid = new_id(mm.name(mm.mj.mjtObj.mjOBJ_BODY, b) or mm.name(mm.mj.mjtObj.mjOBJ_JOINT, j) or "knob")
        symmetry = 1 if marker else _symmetry(pk, radius)
        return Knob(kid, Pose.from_matrix(np.linalg.inv(T_world_parent) @ T_wk), states, "off",
                    angle=sign * off_q, radius=max(radius, 0.005), depth=max(depth, 0.002),
                    grip=Model(grip), marker=Model(marker) if marker else None, turns=turns,
                    symmetry=symmetry if _separated(states, symmetry) else 1)

    def part(b: int, T_world_parent: np.ndarray) -> Part:
        j = joints[b]
        T_wb = mm.body_T(b)
        axis_b = np.asarray(m.jnt_axis[j], dtype=float)
        T_origin = T_wb.copy()
        T_origin[:3, 3] = mm.d.xanchor[j]
        T_po = np.linalg.inv(T_world_parent) @ T_origin
        lo_j, hi_j = (float(m.jnt_range[j][0]), float(m.jnt_range[j][1])) if m.jnt_limited[j] \
            else (-math.pi, math.pi)
        revolute = int(m.jnt_type[j]) == _JNT_HINGE
        pid = new_id(mm.name(mm.mj.mjtObj.mjOBJ_BODY, b) or mm.name(mm.mj.mjtObj.mjOBJ_JOINT, j) or "part")
        T_ow = np.linalg.inv(T_origin)
        mine = static_bodies(b)
        handles, vis = [], []
        for bb in mine:
            bname = mm.name(mm.mj.mjtObj.mjOBJ_BODY, bb).lower()
            for g in geoms.get(bb, []):
                if "handle" in bname or "handle" in g.visual.name.lower():
                    handles.append(_handle(new_id("handle"), T_ow @ g.T, g))
                else:
                    vis.append(replace(g.visual, pose=Pose.from_matrix(T_ow @ g.T)))
        p = Part(pid, "door" if revolute else "drawer",
                 Joint("revolute" if revolute else "prismatic", origin=Pose.from_matrix(T_po),
                       axis=tuple(float(a) for a in axis_b), lower=lo_j, upper=hi_j,
                       state=min(max(0.0, lo_j), hi_j)),
                 name=pid.replace("_", " "), model=Model(vis), handles=handles)
        for mb in moving_below(mine):
            (p.knobs.append(knob(mb, T_origin)) if mb in knob_like
             else p.parts.append(part(mb, T_origin)))
        return p

    T_world_obj = np.linalg.inv(T_obj_model)
    root_static = static_bodies(root)
    obj = LargeArticulatedObject(
        id=object_id, type=object_type, pose=Pose(), name=name,
        model=Model(visuals_in(root_static, T_obj_model)), affordances=["appliance"])
    for mb in moving_below(root_static):
        (obj.knobs.append(knob(mb, T_world_obj)) if mb in knob_like
         else obj.parts.append(part(mb, T_world_obj)))
    if not obj.knobs:
        raise WorldError("the model has no knob (a hinge whose geometry stays within "
                         f"{KNOB_MAX_RADIUS} m of its axis)", file=str(path))
    if any(p.type == "door" for p in obj.parts) or any(p.type == "drawer" for p in obj.parts):
        obj.affordances.append("openable")
    obj.description = f"imported from {path.name}"
    p_obj = all_pts @ T_obj_model[:3, :3].T + T_obj_model[:3, 3]
    return obj, np.ptp(p_obj, axis=0)


def _front_yaw(front: str, knob_like: dict, m, joints, mm, lo, hi) -> float:
    """The yaw that turns the model's front to +x."""
    named = {"+x": (1, 0), "-x": (-1, 0), "+y": (0, 1), "-y": (0, -1)}
    if front in named:
        v = np.array(named[front], dtype=float)
    else:
        v = np.zeros(2)
        centre = (lo + hi) / 2
        for axis_w, anchor in knob_like.values():
            if abs(axis_w[2]) < 0.7:
                a = axis_w[:2] / np.linalg.norm(axis_w[:2])
                v += a if float((anchor[:2] - centre[:2]) @ a) >= 0 else -a
        if np.linalg.norm(v) < 1e-6:
            v = np.array([-1.0, 0.0])
        side = np.argmax(np.abs(v))
        v = np.eye(2)[side] * np.sign(v[side])
    return -math.atan2(v[1], v[0])


def _symmetry(points_knob: np.ndarray, radius: float) -> int:
    """The most-fold turn (4, 3 or 2) about +z that maps the knob's surface points (knob
    frame) onto themselves within 3 % of its radius, else 1."""
    from scipy.spatial import cKDTree
    if len(points_knob) < 8 or radius <= 0:
        return 1
    tree = cKDTree(points_knob)
    for n in (4, 3, 2):
        a = 2 * math.pi / n
        R = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        d, _ = tree.query(points_knob @ R.T)
        if float(np.percentile(d, 95)) <= 0.03 * radius:
            return n
    return 1


def _separated(states: list[KnobState], symmetry: int) -> bool:
    """Whether the states still look different when angles are only seen modulo the
    symmetry (else the knob is declared without one; docs/world-format.md)."""
    period = 2 * math.pi / symmetry
    for i, a in enumerate(states):
        for b in states[i + 1:]:
            if abs(math.remainder(a.angle - b.angle, period)) < math.radians(1.0):
                return False
    return True


def _split_marker(vis: list[Visual], bodies, geoms) -> tuple[list[Visual], list[Visual]]:
    """(grip, marker): the marker is what differs in colour from the largest visual and is
    smaller than it."""
    if len(vis) < 2:
        return vis, []

    def size(v: Visual) -> float:
        if v.shape == "box":
            return float(np.prod(v.size))
        if v.shape == "cylinder":
            return math.pi * v.radius ** 2 * v.length
        if v.shape == "sphere":
            return 4.0 * v.radius ** 3
        return 1.0            # a mesh: taken as the body of the knob
    main = max(vis, key=size)
    marker = [v for v in vis if v is not main and size(v) < size(main)
              and np.linalg.norm(np.subtract(v.color, main.color)) >= MARKER_COLOR_DISTANCE]
    grip = [v for v in vis if all(v is not w for w in marker)]
    return grip, marker


def _handle(hid: str, T_part_geom: np.ndarray, g: _Geom) -> Handle:
    """A handle bar along the geom's longest side (its centre at the geom's)."""
    pts = g.points @ np.linalg.inv(g.T)[:3, :3].T + np.linalg.inv(g.T)[:3, 3]
    ext = np.ptp(pts, axis=0)
    k = int(np.argmax(ext))
    R = np.eye(3)
    if k != 2:                          # the handle frame's +z along the bar
        R = np.roll(np.eye(3), 2 - k, axis=1)
    T = T_part_geom.copy()
    T[:3, :3] = T_part_geom[:3, :3] @ R
    rest = sorted(float(e) for i, e in enumerate(ext) if i != k)
    return Handle(hid, Pose.from_matrix(T), radius=max(rest[0] / 2, 0.004), length=float(ext[k]),
                  color=tuple(g.visual.color))


def _kitchen(obj: LargeArticulatedObject, size) -> Apartment:
    """A 4 x 3.5 m kitchen with the appliance against its north wall, facing south (+x of
    the object towards the room); one lower than 0.5 m (a cooktop) is set into a counter,
    its front 3 cm behind the counter's edge, as stoves are. Parking positions in front of
    it: 0.6 m from a standing appliance's front (as the demo home's oven), 0.45 m from the
    counter's edge for a cooktop (a robot's camera 1.3 m up sees knobs on top of a 0.9 m
    counter from within ~50 degrees of their axis there, from ~70 degrees a metre away).
    A cupboard beside it: a second landmark, so that a localisation fix is pinned along the
    wall too."""
    depth, height = max(float(size[0]), 0.05), float(size[2])
    wall = 3.5 - 0.05
    on_counter = height < 0.5
    yaw = -math.pi / 2                                     # object +x -> world -y
    objects: list = []
    if on_counter:
        cd = max(0.6, depth + 0.1)
        objects.append(LargeObject(
            id="counter", type="counter", name="counter",
            pose=Pose(2.0, wall - cd / 2, 0, 0, 0, yaw),
            model=Model([Visual("box", Pose(0, 0, (COUNTER_HEIGHT - 0.04) / 2),
                                size=(cd, 1.6, COUNTER_HEIGHT - 0.04), color=(0.55, 0.42, 0.3)),
                         Visual("box", Pose(0, 0, COUNTER_HEIGHT - 0.02), size=(cd, 1.6, 0.04),
                                color=(0.8, 0.8, 0.78), name="top")]),
            parking=[ParkingPosition("counter_front", Pose(cd / 2 + 0.45, 0.5, 0, 0, 0, math.pi))],
            default_parking="counter_front"))
        obj.pose = Pose(2.0, wall - cd + 0.03 + depth / 2, COUNTER_HEIGHT, 0.0, 0.0, yaw)
        stand = depth / 2 + 0.03 + 0.45
    else:
        obj.pose = Pose(2.0, wall - depth / 2, 0.0, 0.0, 0.0, yaw)
        stand = depth / 2 + 0.6
    obj.parking = [ParkingPosition(f"{obj.id}_front", Pose(stand, 0, 0, 0, 0, math.pi)),
                   ParkingPosition(f"{obj.id}_left", Pose(stand, 0.3, 0, 0, 0, math.pi)),
                   ParkingPosition(f"{obj.id}_right", Pose(stand, -0.3, 0, 0, 0, math.pi))]
    obj.default_parking = obj.parking[0].id
    objects.append(LargeObject(
        id="cupboard", type="cupboard", name="cupboard",
        pose=Pose(0.45, wall - 0.3, 0, 0, 0, yaw),
        model=Model([Visual("box", Pose(0, 0, 0.45), size=(0.6, 0.8, 0.9), color=(0.9, 0.88, 0.82))]),
        parking=[ParkingPosition("cupboard_front", Pose(1.2, 0, 0, 0, 0, math.pi))],
        default_parking="cupboard_front"))
    objects.append(obj)
    room = Room("kitchen", "kitchen", bounds=(0.0, 0.0, 4.0, 3.5), objects=objects)
    return Apartment("imported", name=f"a kitchen with {obj.name}", rooms=[room])
