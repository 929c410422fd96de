"""A second renderer: the world file's geometry as an MJCF model, drawn by MuJoCo's OpenGL
renderer (software rendering: Mesa's llvmpipe through EGL, or OSMesa), with the same camera
intrinsics and the same Kinect-class noise (hearth/robot/noise.py) as Hearth's ray caster
(hearth/perception/render.py). docs/renderers-and-assets.md says what maps to what and what differs.

- ``world_to_mjcf(world)``: the MJCF text of a world and the labels of its geoms. Rooms,
  switches and large objects are bodies fixed in the world; every part is a body with a hinge
  (revolute) or slide (prismatic) joint at its joint origin, every knob a body with a hinge
  about its +z axis; joint states and knob angles are the joints' positions (``qpos``), so a
  new state is a new ``qpos``, not a new model. Boxes, cylinders and spheres stay MuJoCo
  primitives (MuJoCo tessellates them itself); meshes are read as Hearth reads them (open3d)
  and handed to MuJoCo as vertex and face arrays.
- ``MujocoScene(world)``: the compiled model and its renderer; ``render(K, T_world_camera)``
  returns a ``hearth.perception.render.Rendering`` as Hearth's ``Scene.render`` does (depth in
  metres along the optical axis, colour, per-pixel node labels, incidence), so the noise model
  and every consumer take it unchanged. ``set_states`` and ``hide`` change joint positions and
  hide nodes between frames.
- ``render_view(...)``: ``hearth.robot.sim.render_view``'s signature and result (a ``Frame``).

MuJoCo picks its OpenGL back-end from ``MUJOCO_GL`` when it is first imported; unset, this
module asks for ``egl`` (scripts/sysdeps.sh installs Mesa's EGL and OSMesa). ``available()``
says whether rendering works here, and why not.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hearth.robot.errors import RobotError
from hearth.perception.camera import Intrinsics

#: The OpenGL back-end asked for when ``MUJOCO_GL`` is not set.
DEFAULT_GL = "egl"
#: Near and far clipping planes (m). MuJoCo 3+ draws with a reversed float depth buffer, so
#: depth keeps ~1e-6 relative precision over the whole range.
NEAR, FAR = 0.02, 20.0
#: Lights as Hearth's shading has them (hearth/perception/render.py: colour x (0.85 (1 - 0.45) lit
#: + 0.85 x 0.45), lit the cosine to ``LIGHT_WORLD``): a directional light from the same
#: direction and an ambient term. MuJoCo then shades per pixel with interpolated normals, adds
#: specular highlights on shiny materials and anti-aliases edges (4 samples), which Hearth's
#: flat-shaded ray caster does not.
AMBIENT, DIFFUSE = 0.85 * 0.45, 0.85 * 0.55
_HIDDEN_GROUP = 5                 # geoms of hidden nodes are moved to this (disabled) group


class MujocoUnavailable(RobotError):
    """MuJoCo is not installed or cannot render here (the reason in the message): a
    ``RobotError``, so the CLI prints it as one line with exit status 2."""


def _mujoco():
    os.environ.setdefault("MUJOCO_GL", DEFAULT_GL)
    if os.environ["MUJOCO_GL"] in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
    try:
        import mujoco
    except ImportError as err:  # pragma: no cover - depends on the machine
        raise MujocoUnavailable(f"the mujoco package is not installed ({err}); "
                                "pip install 'hearth[mujoco]'") from None
    return mujoco


_AVAILABLE: Optional[tuple[bool, str]] = None


def available() -> tuple[bool, str]:
    """(True, back-end) when MuJoCo renders here, else (False, the reason). Tried once."""
    global _AVAILABLE
    if _AVAILABLE is None:
        try:
            mujoco = _mujoco()
            ctx = mujoco.GLContext(8, 8)
            ctx.make_current()
            ctx.free()
            _AVAILABLE = (True, os.environ.get("MUJOCO_GL", ""))
        except MujocoUnavailable as err:
            _AVAILABLE = (False, str(err))
        except Exception as err:  # noqa: BLE001 - any GL failure means "cannot render here"
            _AVAILABLE = (False, f"MuJoCo cannot open an OpenGL context with "
                                 f"MUJOCO_GL={os.environ.get('MUJOCO_GL')}: {err}")
    return _AVAILABLE


# -- world -> MJCF ------------------------------------------------------------------------

@dataclass(frozen=True)
class GeomLabel:
    """What a geom of the MJCF model is in the map: ``node`` id, ``owner`` (the large object
    or room), the visual's ``name`` tag and ``material``; the geom ``g<index>``."""
    node: str
    owner: str
    name: str
    material: str


@dataclass
class MJCF:
    """A world as MJCF: ``xml`` (text), ``labels`` (per geom, in geom order), ``joints``
    (map node id -> MJCF joint name, for parts and knobs) and ``states`` (node id -> the
    world's joint state or knob angle)."""
    xml: str
    labels: list[GeomLabel]
    joints: dict[str, str]
    states: dict[str, float]


def _f(x: float) -> str:
    return f"{float(x):.9g}"


def _pose_attrs(T: np.ndarray) -> str:
    from scipy.spatial.transform import Rotation
    q = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()      # x, y, z, w
    return (f'pos="{_f(T[0, 3])} {_f(T[1, 3])} {_f(T[2, 3])}" '
            f'quat="{_f(q[3])} {_f(q[0])} {_f(q[1])} {_f(q[2])}"')


class _Writer:
    """Collects bodies, geoms and meshes while the world is walked."""

    def __init__(self, base_dir):
        self.base_dir = base_dir
        self.labels: list[GeomLabel] = []
        self.meshes: dict[tuple, str] = {}      # (file, scale) -> mesh name
        self.assets: list[str] = []
        self.joints: dict[str, str] = {}
        self.states: dict[str, float] = {}

    def _mesh(self, v) -> str:
        from hearth.worldmodel.geometry import visual_mesh
        from hearth.worldmodel.nodes import Visual
        from hearth.worldmodel.pose import Pose
        key = (v.file, tuple(v.scale))
        if key not in self.meshes:
            m = visual_mesh(Visual("mesh", Pose(), file=v.file, scale=v.scale), self.base_dir)
            vert = np.asarray(m.vertices, dtype=np.float64)
            face = np.asarray(m.triangles, dtype=np.int64)
            name = f"mesh{len(self.meshes)}"
            self.assets.append(
                f'<mesh name="{name}" inertia="shell" vertex="{" ".join(map(_f, vert.reshape(-1)))}" '
                f'face="{" ".join(map(str, face.reshape(-1)))}"/>')
            self.meshes[key] = name
        return self.meshes[key]

    def geoms(self, visuals, T_body_node: np.ndarray, node: str, owner: str) -> str:
        """Geoms of ``visuals`` (in the node's frame) in a body whose frame is
        ``T_body_node`` away from the node's."""
        out = []
        for v in visuals:
            i = len(self.labels)
            self.labels.append(GeomLabel(node, owner, v.name, v.material))
            T = T_body_node @ v.pose.matrix()
            r, g, b = (min(max(float(c), 0.0), 1.0) for c in v.color)
            spec = f'material="{"shiny" if v.material == "shiny" else "matte"}"'
            common = f'name="g{i}" {_pose_attrs(T)} rgba="{_f(r)} {_f(g)} {_f(b)} 1" {spec}'
            if v.shape == "box":
                sx, sy, sz = (max(float(s) / 2, 1e-6) for s in v.size)
                out.append(f'<geom type="box" size="{_f(sx)} {_f(sy)} {_f(sz)}" {common}/>')
            elif v.shape == "cylinder":
                out.append(f'<geom type="cylinder" size="{_f(v.radius)} {_f(v.length / 2)}" '
                           f'{common}/>')
            elif v.shape == "sphere":
                out.append(f'<geom type="sphere" size="{_f(v.radius)}" {common}/>')
            else:
                out.append(f'<geom type="mesh" mesh="{self._mesh(v)}" {common}/>')
        return "".join(out)


def _knob_bodies(w: _Writer, k, library, owner: str) -> str:
    """A knob: a body at its pose with a hinge about +z (its angle is the joint's position);
    a fixed base in a body of its own beside it."""
    from hearth.worldmodel.geometry import knob_parts
    turning, fixed = [], []
    for _role, v, turns in knob_parts(k, library):
        (turning if turns else fixed).append(v)
    jname = f"j{len(w.joints)}"
    w.joints[k.id] = jname
    w.states[k.id] = float(k.angle)
    T = k.pose.matrix()
    out = (f'<body name="b_{jname}" {_pose_attrs(T)}><inertial pos="0 0 0" mass="0.01" '
           f'diaginertia="1e-5 1e-5 1e-5"/><joint name="{jname}" type="hinge" axis="0 0 1"/>'
           + w.geoms(turning, np.eye(4), k.id, owner) + "</body>")
    if fixed:
        out += f'<body {_pose_attrs(T)}>' + w.geoms(fixed, np.eye(4), k.id, owner) + "</body>"
    return out


def _part_body(w: _Writer, part, library, owner: str, inside=None) -> str:
    """A part's body (joint, geoms, handles, knobs, child parts) and the small objects
    ``inside`` it (part id -> objects whose pose is in that part's frame: a drawer's)."""
    from hearth.worldmodel.geometry import handle_visuals, model_visuals
    j = part.joint
    body = f'<body {_pose_attrs(j.origin.matrix())}>'
    if j.type in ("revolute", "prismatic"):
        jname = f"j{len(w.joints)}"
        w.joints[part.id] = jname
        w.states[part.id] = float(j.state)
        axis = np.asarray(j.axis, dtype=float)
        body = (f'<body name="b_{jname}" {_pose_attrs(j.origin.matrix())}><inertial pos="0 0 0" '
                f'mass="1" diaginertia="0.01 0.01 0.01"/><joint name="{jname}" '
                f'type="{"hinge" if j.type == "revolute" else "slide"}" '
                f'axis="{_f(axis[0])} {_f(axis[1])} {_f(axis[2])}"/>')
    out = body + w.geoms(model_visuals(part.model, library), np.eye(4), part.id, owner)
    for h in part.handles:
        out += w.geoms(handle_visuals(h), h.pose.matrix(), h.id, owner)
    for k in part.knobs:
        out += _knob_bodies(w, k, library, owner)
    for c in (inside or {}).get(part.id, ()):
        out += w.geoms(model_visuals(c.model, library), c.pose.matrix(), c.id, c.id)
    for c in part.parts:
        out += _part_body(w, c, library, owner, inside)
    return out + "</body>"


def world_to_mjcf(world, width: int = 640, height: int = 480) -> MJCF:
    """The MJCF model of ``world``'s geometry as ``hearth.worldmodel.geometry.scene_meshes`` draws it
    (rooms, switches, large objects with their parts, handles, knobs and children), in the
    world's current joint states and knob angles; ``width`` x ``height``: the largest image
    it will render (MuJoCo's off-screen buffer)."""
    from hearth.worldmodel.geometry import handle_visuals, model_visuals, room_visuals
    from hearth.worldmodel.nodes import LargeArticulatedObject, Visual
    from hearth.worldmodel.pose import Pose
    w = _Writer(world.base_dir)
    library = world.apartment.library
    bodies = []
    for room in world.apartment.rooms:
        T_room = room.pose.matrix()
        bodies.append(f'<body {_pose_attrs(T_room)}>'
                      + w.geoms(room_visuals(room, world), np.eye(4), room.id, room.id) + "</body>")
        for s in room.switches:
            bodies.append(f'<body {_pose_attrs(T_room @ s.pose.matrix())}>'
                          + w.geoms([Visual("box", Pose(), size=(0.02, 0.08, 0.08),
                                            color=(0.95, 0.95, 0.9))], np.eye(4), s.id, room.id)
                          + "</body>")
        for obj in room.objects:
            b = f'<body {_pose_attrs(world.T_world(obj.id))}>'
            b += w.geoms(model_visuals(obj.model, library), np.eye(4), obj.id, obj.id)
            if isinstance(obj, LargeArticulatedObject):
                for h in obj.handles:
                    b += w.geoms(handle_visuals(h), h.pose.matrix(), h.id, obj.id)
                for k in obj.knobs:
                    b += _knob_bodies(w, k, library, obj.id)
                inside: dict = {}
                for c in obj.children:
                    if c.part:
                        inside.setdefault(c.part, []).append(c)
                for p in obj.parts:
                    b += _part_body(w, p, library, obj.id, inside)
            for c in obj.children:
                if not c.part:       # those in a part (a drawer) move with its body
                    b += w.geoms(model_visuals(c.model, library), c.pose.matrix(), c.id, c.id)
            bodies.append(b + "</body>")
    from hearth.perception.render import LIGHT_WORLD
    L = -np.asarray(LIGHT_WORLD, dtype=float)
    a, d = _f(AMBIENT), _f(DIFFUSE)
    xml = (
        '<mujoco model="hearth-world">'
        '<compiler angle="radian" autolimits="true" boundmass="1e-6" boundinertia="1e-9"/>'
        f'<visual><global offwidth="{int(width)}" offheight="{int(height)}"/>'
        '<quality shadowsize="0" offsamples="4"/>'
        f'<headlight active="1" ambient="{a} {a} {a}" diffuse="0 0 0" specular="0 0 0"/>'
        '</visual>'
        '<default><geom contype="0" conaffinity="0" group="1"/></default>'
        '<asset><material name="matte" specular="0" shininess="0"/>'
        '<material name="shiny" specular="0.6" shininess="0.7"/>'
        f'{"".join(w.assets)}</asset>'
        '<worldbody>'
        f'<light directional="true" castshadow="false" dir="{_f(L[0])} {_f(L[1])} {_f(L[2])}" '
        f'pos="0 0 10" diffuse="{d} {d} {d}" specular="0.3 0.3 0.3" ambient="0 0 0"/>'
        + "".join(bodies) + "</worldbody></mujoco>")
    return MJCF(xml, w.labels, w.joints, w.states)


# -- rendering -----------------------------------------------------------------------------

class _Context:
    """One OpenGL context per process (a context belongs to the thread that made it
    current; the benches render on one thread), grown when a larger image is asked for."""
    ctx = None
    size = (0, 0)

    @classmethod
    def get(cls, width: int, height: int):
        mujoco = _mujoco()
        if cls.ctx is None or width > cls.size[0] or height > cls.size[1]:
            if cls.ctx is not None:
                cls.ctx.free()
            w, h = max(width, cls.size[0], 640), max(height, cls.size[1], 480)
            cls.ctx = mujoco.GLContext(w, h)
            cls.size = (w, h)
        cls.ctx.make_current()
        return cls.ctx


class MujocoScene:
    """A world compiled to MuJoCo and ready to render (``render`` as
    ``hearth.perception.render.Scene.render``). ``states``: joint states / knob angles by node id
    that differ from the world's."""

    def __init__(self, world, states: Optional[dict] = None):
        ok, why = available()
        if not ok:
            raise MujocoUnavailable(why)
        mujoco = _mujoco()
        self._mj = mujoco
        self.mjcf = world_to_mjcf(world)
        try:
            self.model = mujoco.MjModel.from_xml_string(self.mjcf.xml)
        except ValueError as err:
            raise MujocoUnavailable(f"MuJoCo refused the world's MJCF: {err}") from None
        self.data = mujoco.MjData(self.model)
        self.nodes = [g.node for g in self.mjcf.labels]
        self.owners = [g.owner for g in self.mjcf.labels]
        self.names = [g.name for g in self.mjcf.labels]
        self.materials = [g.material for g in self.mjcf.labels]
        self._qadr = {nid: int(self.model.jnt_qposadr[mujoco.mj_name2id(
            self.model, mujoco.mjtObj.mjOBJ_JOINT, j)]) for nid, j in self.mjcf.joints.items()}
        self._group = self.model.geom_group.copy()
        self.set_states(dict(self.mjcf.states, **(states or {})))
        self._ctx = None
        self._con = None
        self._scn = mujoco.MjvScene(self.model, maxgeom=max(1000, 2 * self.model.ngeom))
        self._opt = mujoco.MjvOption()
        self._opt.geomgroup[_HIDDEN_GROUP] = 0
        self._cam = mujoco.MjvCamera()

    def set_states(self, states: dict) -> None:
        """Joint states (parts, m or rad) and knob angles (rad) by node id; unknown ids are
        ignored (a node the model has no joint for)."""
        for nid, value in states.items():
            adr = self._qadr.get(nid)
            if adr is not None and value is not None:
                self.data.qpos[adr] = float(value)
        self._mj.mj_kinematics(self.model, self.data)
        self._mj.mj_camlight(self.model, self.data)      # the lights' world directions

    def hide(self, node_ids=()) -> None:
        """Draw nothing of these nodes until the next ``hide`` (``()``: show everything)."""
        hidden = set(node_ids)
        self.model.geom_group[:] = self._group
        for i, n in enumerate(self.nodes):
            if n in hidden:
                self.model.geom_group[i] = _HIDDEN_GROUP

    def _context(self, width: int, height: int):
        mujoco = self._mj
        ctx = _Context.get(width, height)
        if self._con is None or self._ctx is not ctx:
            self.model.vis.global_.offwidth = _Context.size[0]
            self.model.vis.global_.offheight = _Context.size[1]
            self._con = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_100)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
            self._con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
            self._ctx = ctx
        return self._con

    def _camera(self, K: Intrinsics, T_world_camera: np.ndarray, near: float, far: float) -> None:
        """The scene's OpenGL camera: pose from ``T_world_camera`` (x right, y down, z
        forward; OpenGL's camera looks along -z with +y up) and a frustum whose pixel grid is
        K's, pixel centres at integer coordinates as hearth/perception/camera.py has them."""
        T = np.asarray(T_world_camera, dtype=float)
        for cam in (self._scn.camera[0], self._scn.camera[1]):
            cam.pos[:] = T[:3, 3]
            cam.forward[:] = T[:3, 2]
            cam.up[:] = -T[:3, 1]
            cam.orthographic = 0
            cam.frustum_near, cam.frustum_far = near, far
            # Window x of pixel column u's centre is u + 0.5; with u = fx X/Z + cx the near
            # plane spans [-(cx + 0.5), W - cx - 0.5] * near / fx (rows likewise, y up).
            left = -(K.cx + 0.5) * near / K.fx
            right = (K.width - K.cx - 0.5) * near / K.fx
            cam.frustum_center = 0.5 * (left + right)
            cam.frustum_width = 0.5 * (right - left)
            cam.frustum_top = (K.cy + 0.5) * near / K.fy
            cam.frustum_bottom = -(K.height - K.cy - 0.5) * near / K.fy

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0):
        """A ``hearth.perception.render.Rendering`` of the view (noise-free)."""
        from hearth.perception.render import Rendering
        mujoco = self._mj
        W, H = int(K.width), int(K.height)
        con = self._context(W, H)
        rect = mujoco.MjrRect(0, 0, W, H)
        mujoco.mjv_updateScene(self.model, self.data, self._opt, None, self._cam,
                               mujoco.mjtCatBit.mjCAT_ALL, self._scn)
        near, far = NEAR, max(FAR, max_range * 1.5)
        self._camera(K, T_world_camera, near, far)
        # Colour: shaded, anti-aliased.
        self._scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 0
        self._scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 0
        self._scn.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        self._scn.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = 0
        color = np.empty((H, W, 3), dtype=np.uint8)
        mujoco.mjr_render(rect, self._scn, con)
        mujoco.mjr_readPixels(color, None, rect, con)
        # Labels and depth: a pass of flat geom-id colours (what mujoco.Renderer does for
        # both: no blending of ids or depths across an edge).
        self._scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
        self._scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
        ids = np.empty((H, W, 3), dtype=np.uint8)
        zbuf = np.empty((H, W), dtype=np.float32)
        mujoco.mjr_render(rect, self._scn, con)
        mujoco.mjr_readPixels(ids, zbuf, rect, con)
        color, ids, zbuf = color[::-1], ids[::-1].astype(np.int64), zbuf[::-1].astype(np.float64)
        seg = ids[..., 0] + ids[..., 1] * 256 + ids[..., 2] * 65536     # scene geom + 1, 0: none
        table = np.full(self._scn.ngeom + 1, -1, dtype=np.int32)
        for g in self._scn.geoms[:self._scn.ngeom]:
            if g.segid >= 0 and g.objtype == int(mujoco.mjtObj.mjOBJ_GEOM):
                table[g.segid + 1] = g.objid
        labels = table[np.clip(seg, 0, len(table) - 1)]
        # Reversed z: window depth 1 at the near plane, 0 at the far one (mujoco.Renderer).
        c = -(far + near) / (far - near)
        d = -2.0 * far * near / (far - near)
        c, d = -0.5 * c - 0.5, -0.5 * d
        with np.errstate(divide="ignore"):
            depth = d / (zbuf + c)
        hit = (labels >= 0) & (depth > 0) & (depth <= max_range)
        depth = np.where(hit, depth, 0.0).astype(np.float32)
        labels = np.where(hit, labels, -1).astype(np.int32)
        color[~hit] = 0
        normals = _normals_from_depth(depth, K)
        incidence = np.abs(np.einsum("hwk,hwk->hw", normals, _grid(K)[1])).astype(np.float32)
        incidence[~hit] = 0
        tri = np.arange(H * W, dtype=np.uint32).reshape(H, W)
        tri[~hit] = H * W
        table_n = np.vstack([normals.reshape(-1, 3), np.zeros((1, 3), np.float32)])
        return Rendering(depth=depth, color=np.ascontiguousarray(color), labels=labels,
                         nodes=self.nodes, owners=self.owners, names=self.names,
                         materials=self.materials, incidence=incidence, triangle=tri,
                         triangle_normals_camera=table_n)

    def close(self) -> None:
        """Free the OpenGL resources (buffers, uploaded meshes) of this scene."""
        con, self._con = getattr(self, "_con", None), None
        if con is not None and getattr(self, "_ctx", None) is _Context.ctx and _Context.ctx is not None:
            try:
                _Context.ctx.make_current()
                con.free()
            except Exception:  # noqa: BLE001 - at interpreter exit GL may be gone already
                pass

    def __del__(self):
        # The benches make a scene per truth they render (a moved object, opened doors):
        # without this each would keep its off-screen buffers until the process ends.
        self.close()


_GRIDS: dict = {}


def _grid(K: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel centre, the camera ray with z = 1 (H, W, 3) and that ray made unit, float32;
    cached per camera."""
    key = (K.fx, K.fy, K.cx, K.cy, K.width, K.height)
    if key not in _GRIDS:
        u, v = np.meshgrid(np.arange(K.width, dtype=np.float32), np.arange(K.height, dtype=np.float32))
        d = np.stack([(u - np.float32(K.cx)) / np.float32(K.fx),
                      (v - np.float32(K.cy)) / np.float32(K.fy), np.ones_like(u)], axis=-1)
        if len(_GRIDS) > 64:
            _GRIDS.clear()
        _GRIDS[key] = (d, d / np.linalg.norm(d, axis=-1, keepdims=True))
    return _GRIDS[key]


def _normals_from_depth(depth: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Unit normals (camera frame, facing the camera, float32) of a depth image: the cross
    product of the horizontal and the vertical difference to a neighbour, each taken on the
    side with the smaller depth step (so that a pixel at an edge takes its own surface's
    slope). OpenGL gives no normals back; MuJoCo's depth is what this has."""
    P = _grid(K)[0] * depth[..., None]

    def diff(axis: int) -> np.ndarray:
        d = np.diff(P, axis=axis)
        pad = [(0, 0)] * 3
        pad[axis] = (1, 0)
        bwd = np.pad(d, pad, mode="edge")
        pad[axis] = (0, 1)
        fwd = np.pad(d, pad, mode="edge")
        return np.where((np.abs(fwd[..., 2]) <= np.abs(bwd[..., 2]))[..., None], fwd, bwd)

    n = np.cross(diff(1), diff(0))
    norm = np.sqrt(np.einsum("hwk,hwk->hw", n, n))[..., None]
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    flip = np.einsum("hwk,hwk->hw", n, P) > 0
    n *= np.where(flip, np.float32(-1), np.float32(1))[..., None]     # facing the camera
    return n


def world_scene(world, states: Optional[dict] = None) -> MujocoScene:
    """A ``MujocoScene`` of ``world`` (``hearth.robot.sim.world_scene``'s counterpart)."""
    return MujocoScene(world, states)


def render_view(world, K: Intrinsics, T_world_camera, rng: Optional[np.random.Generator] = None,
                noise=None, states: Optional[dict] = None, scene: Optional[MujocoScene] = None,
                T_world_camera_believed=None, timestamp: float = 0.0):
    """``hearth.robot.sim.render_view`` with MuJoCo drawing the frame: the same ``Frame``,
    the same noise model (``noise``: a ``KinectNoise``; None: noise-free)."""
    from hearth.robot.noise import add_kinect_noise
    from hearth.robot.sim import Frame
    T_true = np.asarray(T_world_camera, dtype=float)
    scene = scene if scene is not None else MujocoScene(world, states)
    if states and scene is not None:
        scene.set_states(states)
    clean = scene.render(K, T_true)
    rng = rng if rng is not None else np.random.default_rng(0)
    noisy = add_kinect_noise(clean, rng, noise) if noise is not None else clean
    T_bel = T_true if T_world_camera_believed is None else np.asarray(T_world_camera_believed)
    return Frame(color=noisy.color, depth=noisy.depth, intrinsics=K, T_world_camera=T_bel.copy(),
                 timestamp=timestamp, T_world_camera_true=T_true.copy(), labels=clean.labels,
                 nodes=clean.nodes, owners=clean.owners, rendering=clean)



# -- the benches' hooks ----------------------------------------------------------------------

#: What ``--renderer`` of the knob and registration benches chooses from.
RENDERERS = ("hearth", "mujoco")


def add_renderer_argument(parser) -> None:  # pragma: no cover - argparse wiring
    parser.add_argument("--renderer", choices=RENDERERS, default="hearth",
                        help="draw the held-out frames with Hearth's ray caster (default) or "
                             "MuJoCo's OpenGL renderer (the mujoco extra; "
                             "docs/renderers-and-assets.md)")


def scene_for(world, renderer: str = "hearth", states: Optional[dict] = None):
    """A scene of ``world`` with ``render(K, T_world_camera)`` -> ``Rendering``: Hearth's
    ray caster (``hearth.perception.render.Scene``) or a ``MujocoScene``."""
    if renderer == "mujoco":
        return MujocoScene(world, states)
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import scene_meshes
    return Scene(scene_meshes(world, states=states))


class _KnobFrame:
    """One held-out knob frame's scene: the MuJoCo model with every knob at its map angle
    but ``angles``, and ``missing`` knobs hidden."""

    def __init__(self, scene: MujocoScene, angles: dict, missing=()):
        self.scene, self.angles, self.missing = scene, angles, tuple(missing)

    def render(self, K: Intrinsics, T_world_camera: np.ndarray, max_range: float = 8.0):
        self.scene.set_states(self.angles)
        self.scene.hide(self.missing)
        try:
            return self.scene.render(K, T_world_camera, max_range)
        finally:
            self.scene.hide()


def knob_scenes(world, renderer: str = "hearth"):
    """``hearth.perception.knob_data.KnobScenes`` of ``world`` whose frames (``scene(...).render``)
    are drawn by ``renderer``; where a camera may stand (``placeable``) is decided on Hearth's
    geometry either way, so both renderers get the same views."""
    from hearth.perception.knob_data import KnobScenes
    if renderer != "mujoco":
        return KnobScenes(world)
    mj = MujocoScene(world)
    rest = {k.id: float(k.angle) for k in world.knobs()}

    class MujocoKnobScenes(KnobScenes):
        def scene(self, owner: str, angles: dict, missing: tuple = ()):
            return _KnobFrame(mj, dict(rest, **{k: float(a) for k, a in angles.items()}), missing)

    return MujocoKnobScenes(world)
