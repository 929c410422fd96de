"""Triangle meshes of map nodes in any articulation state.

Every visual becomes an open3d ``TriangleMesh``; ``scene_meshes`` walks the map and returns
them in the world frame, each labelled with the node it belongs to, its colour and material,
so a renderer can produce depth, colour and per-pixel node labels. Joint states and knob
angles can be overridden without touching the map (to render a hypothesis).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Optional

import numpy as np
import open3d as o3d

from hearth.worldmodel.nodes import (
    Handle, Knob, LargeArticulatedObject, LargeObject, Model, Part, Room, SmallObject, Visual,
)
from hearth.worldmodel.frames import joint_T, knob_T, rotation_about_axis
from hearth.worldmodel.outline import outline_contains, room_openings, room_outline, segment_clip
from hearth.worldmodel.pose import Pose

WALL_HEIGHT = 2.5
WALL_THICKNESS = 0.1
CYLINDER_RESOLUTION = 24


@dataclass
class LabelledMesh:
    """A mesh in the world frame. ``node`` is the id of the map node it belongs to, ``owner``
    the large object (or room) that node is part of, ``name`` the visual's tag ("marker",
    "floor", "wall", "bar")."""
    node: str
    owner: str
    mesh: o3d.geometry.TriangleMesh
    color: tuple[float, float, float]
    material: str = "matte"
    name: str = ""


@lru_cache(maxsize=256)
def _primitive(shape: str, a: float, b: float, c: float) -> o3d.geometry.TriangleMesh:
    if shape == "box":
        m = o3d.geometry.TriangleMesh.create_box(a, b, c)
        m.translate((-a / 2, -b / 2, -c / 2))
    elif shape == "cylinder":
        m = o3d.geometry.TriangleMesh.create_cylinder(a, b, resolution=CYLINDER_RESOLUTION, split=1)
    elif shape == "sphere":
        m = o3d.geometry.TriangleMesh.create_sphere(a, resolution=12)
    else:  # pragma: no cover
        raise ValueError(shape)
    return m


@lru_cache(maxsize=64)
def _mesh_file(path: str) -> o3d.geometry.TriangleMesh:
    return o3d.io.read_triangle_mesh(path)


def visual_mesh(v: Visual, base_dir: Optional[Path] = None) -> o3d.geometry.TriangleMesh:
    """The visual's mesh in its node's frame (a fresh copy)."""
    if v.shape == "box":
        m = o3d.geometry.TriangleMesh(_primitive("box", *map(float, v.size)))
    elif v.shape == "cylinder":
        m = o3d.geometry.TriangleMesh(_primitive("cylinder", float(v.radius), float(v.length), 0.0))
    elif v.shape == "sphere":
        m = o3d.geometry.TriangleMesh(_primitive("sphere", float(v.radius), 0.0, 0.0))
    else:
        path = Path(v.file) if base_dir is None else Path(base_dir) / v.file
        m = o3d.geometry.TriangleMesh(_mesh_file(str(path)))
        sx, sy, sz = v.scale
        if sx == sy == sz:
            if sx != 1.0:
                m.scale(sx, center=(0, 0, 0))
        else:
            # open3d scales uniformly only; normals of a stretched mesh are recomputed.
            m.vertices = o3d.utility.Vector3dVector(np.asarray(m.vertices) * (sx, sy, sz))
            if m.has_triangle_normals():
                m.compute_triangle_normals()
            if m.has_vertex_normals():
                m.compute_vertex_normals()
    m.transform(v.pose.matrix())
    return m


def handle_visuals(h: Handle) -> list[Visual]:
    """A bar along +z at the handle frame's origin and two standoffs back to the face (-x).
    A recessed pull: its hollow as seen, a dark inlay 1 mm thick on the face (the renderer
    draws unions of solids, so the hollow itself is not cut out; its depth is not needed by
    anything that reads it: the pull is where the door's registered frame says)."""
    if h.handle_kind == "recessed":
        return [Visual("box", Pose(0.0005, 0, 0), size=(0.001, 2 * h.radius, h.length),
                       color=h.color, material="dark" if h.material == "dark" else "matte",
                       name="recess")]
    leg = max(h.length / 2 - 2 * h.radius, h.radius)
    out = [Visual("cylinder", Pose(), radius=h.radius, length=h.length, color=h.color,
                  material=h.material, name="bar")]
    for s in (-1, 1):
        out.append(Visual("box", Pose(-h.standoff / 2, 0, s * leg), size=(h.standoff, h.radius, h.radius),
                          color=h.color, material=h.material, name="standoff"))
    return out


#: The roles of a knob's shape, back to front (``Knob.base``, ``grip``, ``marker``).
KNOB_ROLES = ("base", "grip", "marker")


def knob_parts(k: Knob, library: Optional[dict] = None) -> list[tuple[str, Visual, bool]]:
    """The knob's shape as ``(role, visual, turns)`` in its frame at angle 0: the described
    base, grip and marker (a visual's ``name`` defaults to its role; ``turns`` is False for a
    fixed base), or for a plain knob (``Knob.described`` False) the format-1 knob: a cylinder
    of ``radius`` from the panel (z = 0) to z = ``depth`` in ``color`` and a marker bar of
    ``marker_color`` on its face from the centre towards +y. ``library``: the apartment's
    models, for shapes given by ``ref``."""
    if not k.described:
        r = k.radius
        return [
            ("base", Visual("cylinder", Pose(0, 0, k.depth / 2), radius=r, length=k.depth,
                            color=k.color, name="knob"), True),
            ("marker", Visual("box", Pose(0, 0.45 * r, k.depth + 0.001), size=(0.22 * r, 0.9 * r, 0.002),
                              color=k.marker_color, name="marker"), True),
        ]
    out = []
    for role in KNOB_ROLES:
        model = getattr(k, role)
        if model is None:
            continue
        if model.ref is not None and library is None:
            raise ValueError(f"knob {k.id}: its {role} names library model {model.ref!r}; "
                             "pass the library")
        for v in model_visuals(model, library or {}):
            out.append((role, v if v.name else replace(v, name=role),
                        not (role == "base" and k.base_fixed)))
    return out


def knob_visuals(k: Knob, library: Optional[dict] = None, angle: Optional[float] = None) -> list[Visual]:
    """The knob's visuals in its frame turned to ``angle`` (default: its current angle), the
    frame ``knob_T(k, angle)`` gives: what turns as described, a fixed base turned back so
    that it stays where it is on the panel (see ``knob_parts``)."""
    a = k.angle if angle is None else angle
    out = []
    for _role, v, turns in knob_parts(k, library):
        if not turns and a != 0.0:
            v = replace(v, pose=Pose.from_matrix(rotation_about_axis((0, 0, 1), -a) @ v.pose.matrix()))
        out.append(v)
    return out


#: Height of a doorway's opening (m); the wall above it (the lintel) is drawn.
DOORWAY_HEIGHT = 2.05


def room_visuals(room: Room, home=None) -> list[Visual]:
    """Floor, walls and a ceiling of a room (room frame; none without bounds or outline).

    A rectangle (bounds) gives four walls as before. An outline gives one wall per side,
    outside the floor, lengthened at convex corners to close them. The walls are open where
    a doorway of ``home`` (an Apartment or a World; None: no openings) crosses them, with a
    lintel above ``DOORWAY_HEIGHT``. The floor and ceiling of a rectilinear outline are boxes
    over its cells; of any other outline, one box over its bounding box."""
    poly = room_outline(room)
    if not poly:
        return []
    t, H = WALL_THICKNESS, WALL_HEIGHT
    floor = (0.62, 0.58, 0.52)
    wall = (0.88, 0.87, 0.83)
    openings = room_openings(home, room) if home is not None else []
    if room.outline is None and not openings:     # format 1: exactly the four boxes it had
        x0, y0, x1, y1 = room.bounds
        cx, cy, w, d = (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0
        return [
            Visual("box", Pose(cx, cy, -t / 2), size=(w, d, t), color=floor, name="floor"),
            Visual("box", Pose(cx, cy, H + t / 2), size=(w, d, t), color=(0.95, 0.95, 0.95), name="ceiling"),
            Visual("box", Pose(x0 - t / 2, cy, H / 2), size=(t, d, H), color=wall, name="wall"),
            Visual("box", Pose(x1 + t / 2, cy, H / 2), size=(t, d, H), color=wall, name="wall"),
            Visual("box", Pose(cx, y0 - t / 2, H / 2), size=(w + 2 * t, t, H), color=wall, name="wall"),
            Visual("box", Pose(cx, y1 + t / 2, H / 2), size=(w + 2 * t, t, H), color=wall, name="wall"),
        ]
    out = []
    for (cx, cy, w, d) in _floor_cells(poly):
        out.append(Visual("box", Pose(cx, cy, -t / 2), size=(w, d, t), color=floor, name="floor"))
        out.append(Visual("box", Pose(cx, cy, H + t / 2), size=(w, d, t), color=(0.95, 0.95, 0.95),
                          name="ceiling"))
    for a, b, yaw, length in wall_segments(poly, openings):
        c = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
        out.append(Visual("box", Pose(c[0], c[1], H / 2, 0, 0, yaw), size=(length, t, H),
                          color=wall, name="wall"))
    for a, b, yaw, length in wall_segments(poly, openings, lintels=True):
        c = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
        out.append(Visual("box", Pose(c[0], c[1], (DOORWAY_HEIGHT + H) / 2, 0, 0, yaw),
                          size=(length, t, H - DOORWAY_HEIGHT), color=wall, name="wall"))
    return out


def wall_segments(poly, openings=(), lintels: bool = False, thickness: float = WALL_THICKNESS):
    """The walls of a counter-clockwise floor polygon (room frame) as (a, b, yaw, length):
    the centre line of each wall box from a to b, ``thickness`` thick, outside the floor,
    lengthened by the thickness at convex corners; cut where an opening (a convex polygon in
    the same frame) crosses it. ``lintels``: the cut-out pieces instead (what stands above a
    doorway)."""
    n = len(poly)
    t = thickness
    out = []
    for i in range(n):
        a, b = np.asarray(poly[i], float), np.asarray(poly[(i + 1) % n], float)
        prev, nxt = np.asarray(poly[i - 1], float), np.asarray(poly[(i + 2) % n], float)
        e = b - a
        L = float(np.linalg.norm(e))
        if L < 1e-9:
            continue
        u = e / L
        nrm = np.array([u[1], -u[0]])           # outward for a counter-clockwise polygon

        def convex(p, q, r):
            return (q[0] - p[0]) * (r[1] - q[1]) - (q[1] - p[1]) * (r[0] - q[0]) > 0
        s0 = -t if convex(prev, a, b) else 0.0
        s1 = L + t if convex(a, b, nxt) else L
        cuts = []
        for op in openings:
            for off in (0.0, t / 2, t):
                p0 = a + u * s0 + nrm * off
                p1 = a + u * s1 + nrm * off
                c = segment_clip(tuple(p0), tuple(p1), op)
                if c is not None and c[1] > c[0]:
                    cuts.append((s0 + c[0] * (s1 - s0), s0 + c[1] * (s1 - s0)))
        cuts.sort()
        merged = []
        for c in cuts:
            if merged and c[0] <= merged[-1][1]:
                merged[-1] = (merged[-1][0], max(merged[-1][1], c[1]))
            else:
                merged.append(c)
        if lintels:
            pieces = merged
        else:
            pieces, at = [], s0
            for c0, c1 in merged:
                if c0 > at:
                    pieces.append((at, c0))
                at = max(at, c1)
            if s1 > at:
                pieces.append((at, s1))
        yaw = math.atan2(u[1], u[0])
        for p0, p1 in pieces:
            if p1 - p0 < 1e-4:
                continue
            out.append((tuple(a + u * p0 + nrm * t / 2), tuple(a + u * p1 + nrm * t / 2), yaw,
                        p1 - p0))
    return out


def _floor_cells(poly) -> list[tuple[float, float, float, float]]:
    """Boxes (cx, cy, w, d) covering a rectilinear polygon exactly (the grid its corners'
    coordinates make, cells inside kept, merged along rows); one bounding box for any other
    polygon."""
    xs = sorted({round(p[0], 9) for p in poly})
    ys = sorted({round(p[1], 9) for p in poly})
    n = len(poly)
    rectilinear = all(abs(poly[i][0] - poly[(i + 1) % n][0]) < 1e-9
                      or abs(poly[i][1] - poly[(i + 1) % n][1]) < 1e-9 for i in range(n))
    if not rectilinear:
        return [((xs[0] + xs[-1]) / 2, (ys[0] + ys[-1]) / 2, xs[-1] - xs[0], ys[-1] - ys[0])]
    out = []
    for j in range(len(ys) - 1):
        run = None
        for i in range(len(xs) - 1):
            inside = outline_contains(poly, (xs[i] + xs[i + 1]) / 2, (ys[j] + ys[j + 1]) / 2)
            if inside and run is None:
                run = xs[i]
            if not inside and run is not None:
                out.append(((run + xs[i]) / 2, (ys[j] + ys[j + 1]) / 2, xs[i] - run, ys[j + 1] - ys[j]))
                run = None
        if run is not None:
            out.append(((run + xs[-1]) / 2, (ys[j] + ys[j + 1]) / 2, xs[-1] - run, ys[j + 1] - ys[j]))
    return out


def model_visuals(model: Model, library: dict) -> list[Visual]:
    if model.ref is not None:
        return list(library[model.ref].visuals) + list(model.visuals)
    return list(model.visuals)


def part_T(part: Part, state: Optional[float] = None) -> np.ndarray:
    """``T_parent_part`` for a joint state (default: the part's current state)."""
    return joint_T(part.joint, state)


def _emit(out, visuals, T, node_id, owner, base_dir):
    for v in visuals:
        m = visual_mesh(v, base_dir)
        m.transform(T)
        out.append(LabelledMesh(node_id, owner, m, tuple(v.color), v.material, v.name))


def _part_meshes(out, part: Part, T_world_parent, owner, library, base_dir, states):
    T = T_world_parent @ part_T(part, states.get(part.id) if states else None)
    _emit(out, model_visuals(part.model, library), T, part.id, owner, base_dir)
    for h in part.handles:
        _emit(out, handle_visuals(h), T @ h.pose.matrix(), h.id, owner, base_dir)
    for k in part.knobs:
        a = states.get(k.id) if states else None
        _emit(out, knob_visuals(k, library, a), T @ knob_T(k, a), k.id, owner, base_dir)
    for c in part.parts:
        _part_meshes(out, c, T, owner, library, base_dir, states)


def object_meshes(world, obj: LargeObject, T_world_object: Optional[np.ndarray] = None,
                  states: Optional[dict] = None, children: bool = True) -> list[LabelledMesh]:
    """Meshes of a large object (parts, handles, knobs, and small objects when ``children``)
    in the world frame. ``T_world_object`` overrides where the object stands; ``states`` maps
    part ids to joint states and knob ids to angles."""
    library = world.apartment.library
    base_dir = world.base_dir
    T = world.T_world(obj.id) if T_world_object is None else T_world_object
    out: list[LabelledMesh] = []
    _emit(out, model_visuals(obj.model, library), T, obj.id, obj.id, base_dir)
    if isinstance(obj, LargeArticulatedObject):
        for h in obj.handles:
            _emit(out, handle_visuals(h), T @ h.pose.matrix(), h.id, obj.id, base_dir)
        for k in obj.knobs:
            a = states.get(k.id) if states else None
            _emit(out, knob_visuals(k, library, a), T @ knob_T(k, a), k.id, obj.id, base_dir)
        for p in obj.parts:
            _part_meshes(out, p, T, obj.id, library, base_dir, states)
    if children:
        for c in obj.children:
            T_obj_c = c.pose.matrix()
            if c.part:      # in a drawer: moves with it (at the given states, too)
                T_obj_c = part_in_object_T(obj, c.part, states) @ T_obj_c
            _emit(out, model_visuals(c.model, library), T @ T_obj_c, c.id, c.id, base_dir)
    return out


def part_in_object_T(obj, part_id: str, states: Optional[dict] = None) -> np.ndarray:
    """``T_object_part`` of a (nested) part of ``obj`` at its current joint states, or at
    ``states`` (part id -> joint state) where given. KeyError when it has no such part."""
    def walk(parts, T):
        for p in parts:
            Tp = T @ part_T(p, states.get(p.id) if states else None)
            if p.id == part_id:
                return Tp
            found = walk(p.parts, Tp)
            if found is not None:
                return found
        return None
    found = walk(getattr(obj, "parts", ()), np.eye(4))
    if found is None:
        raise KeyError(part_id)
    return found


def distance_to_object(world, object_id: str, points_world: np.ndarray) -> np.ndarray:
    """Distance (m) from each world point to a large object's own meshes (its parts in the
    map's states; not the small objects it holds), by open3d's distance query; inf where
    the object has no mesh."""
    pts = np.asarray(points_world, np.float32).reshape(-1, 3)
    meshes = object_meshes(world, world.get(object_id), children=False)
    if not meshes or not len(pts):
        return np.full(len(pts), np.inf)
    scene = o3d.t.geometry.RaycastingScene()
    for lm in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
    return scene.compute_distance(o3d.core.Tensor(pts)).numpy()


def small_object_meshes(world, obj: SmallObject, T_world_object: Optional[np.ndarray] = None):
    T = world.T_world(obj.id) if T_world_object is None else T_world_object
    out: list[LabelledMesh] = []
    _emit(out, model_visuals(obj.model, world.apartment.library), T, obj.id, obj.id, world.base_dir)
    return out


def scene_meshes(world, room_ids: Optional[list[str]] = None, states: Optional[dict] = None,
                 include_rooms: bool = True, exclude: tuple[str, ...] = ()) -> list[LabelledMesh]:
    """Every mesh of the home (or of the given rooms) in the world frame."""
    out: list[LabelledMesh] = []
    for room in world.apartment.rooms:
        if room_ids is not None and room.id not in room_ids:
            continue
        T_room = room.pose.matrix()
        if include_rooms:
            _emit(out, room_visuals(room, world), T_room, room.id, room.id, world.base_dir)
        for s in room.switches:
            _emit(out, [Visual("box", Pose(), size=(0.02, 0.08, 0.08), color=(0.95, 0.95, 0.9))],
                  T_room @ s.pose.matrix(), s.id, room.id, world.base_dir)
        for obj in room.objects:
            if obj.id in exclude:
                continue
            for lm in object_meshes(world, obj, states=states):
                if lm.node not in exclude:
                    out.append(lm)
    return out


def merge(meshes: list[LabelledMesh]) -> o3d.geometry.TriangleMesh:
    total = o3d.geometry.TriangleMesh()
    for lm in meshes:
        total += lm.mesh
    return total


def node_mesh(world, node_id: str, states: Optional[dict] = None) -> o3d.geometry.TriangleMesh:
    """One triangle mesh, world frame, of any node with its descendants, in its current (or
    the given) articulation state."""
    node = world.get(node_id)
    if isinstance(node, Room):
        return merge(scene_meshes(world, [node.id], states=states))
    if isinstance(node, LargeObject):
        return merge(object_meshes(world, node, states=states))
    if isinstance(node, SmallObject):
        return merge(small_object_meshes(world, node))
    obj = world.large_object_of(node_id)
    wanted = {n.id for n in world.descendants(node_id)} | {node_id}
    return merge([lm for lm in object_meshes(world, obj, states=states, children=False)
                  if lm.node in wanted])
