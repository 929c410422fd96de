"""Registering large objects and reading the state of their doors and drawers (RAMCIP 5.2.1).

The base (carcass) is registered first, against what the camera should see of it: the model
rendered at the believed pose from the current camera. Then every part is registered under its
joint constraint in the registered parent's frame, parents before children:

1. coarse: the part's surface samples are placed at every state of a grid over the joint's
   whole range (5 degrees / 2 cm) and scored against the observed depth image (agreeing points
   minus points the camera sees through; back faces culled). No ray casting, no ICP restarts:
   all states of a part cost one vectorised projection (~1 ms);
2. fine: the object is rendered once with every part at its coarse state; what the camera
   should see of each part is registered to the observation with the 1-DoF point-to-plane ICP.

A part whose visible, matched surface is too small (a door seen edge-on, a door hidden behind
another) is reported as unknown (``value`` None), never with a guessed angle.

Pure: the map (``World``), the depth image and the camera go in; nothing is read from files
(meshes come from the map's primitives) and the map is not changed (skills write the result).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np
import open3d as o3d

from hearth.perception.errors import PerceptionError
from hearth.perception.registration import (
    DepthAgreement, ICPConfig, ICPResult, JointAxis, RegistrationFailed, View, crop_box,
    depth_agreement, observed_view, register_6dof, register_joint, register_planar,
    render_reference, single_threaded_blas, transform,
)
from hearth.worldmodel.frames import joint_T
from hearth.worldmodel.geometry import handle_visuals, knob_T, knob_visuals, model_visuals, object_meshes, visual_mesh
from hearth.worldmodel.nodes import LargeArticulatedObject, LargeObject, Part


@dataclass(frozen=True)
class ArticulatedConfig:
    """``base``: ICP of the base; ``joint``: the 1-DoF refinement; ``coarse_step_deg`` /
    ``coarse_step_m``: the coarse grid over a joint's range; ``samples``: surface samples per
    part for the coarse search; a part needs ``min_points`` matched model points and
    ``min_fitness`` (matched / expected visible) to get a state; ``margin``: how far (m) the
    observation is cropped around the believed object; ``mode``: "planar" (x, y, yaw: furniture
    on the floor) or "6dof" for the base."""
    base: ICPConfig = ICPConfig(gates=(0.06, 0.03, 0.012), iterations=(8, 6, 6),
                                min_fitness=0.05, min_coverage=0.3)
    joint: ICPConfig = ICPConfig(voxel=0.0, gates=(0.04, 0.012), iterations=(8, 8),
                                 robust_scale=0.01, min_fitness=0.0, min_points=10)
    coarse_step_deg: float = 5.0
    coarse_step_m: float = 0.02
    samples: int = 1200
    min_points: int = 40
    min_fitness: float = 0.5
    min_incidence: float = 0.15
    margin: float = 0.10
    mode: str = "planar"
    reference_scale: float = 0.25
    stride: int = 2
    search_range: float = 0.15
    search_step: float = 0.0125
    #: The base is registered only when at least this many of its points would be seen (at
    #: the reference resolution), and trusted only within these moves from the map.
    min_base_points: int = 250
    max_base_move: float = 0.06
    max_base_turn_deg: float = 3.0
    #: A door's hinge may shift by this much (sigma, m) when its object's base could not be
    #: registered (``register_joint``'s ``slack``): the map's pose of an object moved a
    #: little is centimetres off, and a door read from a hinge there is degrees off.
    hinge_slack: float = 0.02


@dataclass
class PartState:
    """A part's registered state. ``value``: radians (revolute) or metres (prismatic), None when
    unknown (``reason`` says why). ``state`` is the user-facing figure: degrees for doors,
    metres for drawers. ``T_world_part``: the part frame in the world (None when unknown)."""
    part_id: str
    joint_type: str
    value: Optional[float]
    T_world_part: Optional[np.ndarray]
    fitness: float = 0.0
    residual: float = float("inf")
    points: int = 0
    reason: str = ""
    coarse_value: Optional[float] = None

    @property
    def known(self) -> bool:
        return self.value is not None

    @property
    def state(self) -> Optional[float]:
        if self.value is None:
            return None
        return math.degrees(self.value) if self.joint_type == "revolute" else self.value

    @property
    def unit(self) -> str:
        return "deg" if self.joint_type == "revolute" else "m"


@dataclass
class ObjectRegistration:
    """A registered large object. ``T_world_object``: where the object is, in the frame the
    observation was given in; ``correction``: ``T_model_observed`` (maps observed points onto the
    believed model); ``parts``: per part id; ``timings_ms``: per step."""
    object_id: str
    T_world_object: np.ndarray
    correction: np.ndarray
    base: ICPResult
    parts: dict[str, PartState] = field(default_factory=dict)
    observed: Optional[View] = None
    timings_ms: dict[str, float] = field(default_factory=dict)
    base_note: str = ""

    def states(self) -> dict[str, float]:
        """Known joint states (radians / metres) by part id."""
        return {k: p.value for k, p in self.parts.items() if p.value is not None}


# -- helpers -------------------------------------------------------------------------------

def _part_nodes(part: Part) -> list[str]:
    """The part and what moves rigidly with it (its handles and knobs, not sub-parts)."""
    return [part.id] + [h.id for h in part.handles] + [k.id for k in part.knobs]


def _object_nodes(obj: LargeObject) -> list[str]:
    out = [obj.id]
    if isinstance(obj, LargeArticulatedObject):
        out += [h.id for h in obj.handles] + [k.id for k in obj.knobs]
    return out


def part_samples(world, part: Part, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) surface points and unit normals of a part (with its handles and knobs) in the
    part frame, area-weighted."""
    lib, base_dir = world.apartment.library, world.base_dir
    mesh = o3d.geometry.TriangleMesh()
    for v in model_visuals(part.model, lib):
        mesh += visual_mesh(v, base_dir)
    for h in part.handles:
        for v in handle_visuals(h):
            mesh += visual_mesh(v, base_dir).transform(h.pose.matrix())
    for k in part.knobs:
        for v in knob_visuals(k):
            mesh += visual_mesh(v, base_dir).transform(knob_T(k))
    if len(mesh.triangles) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    mesh.compute_triangle_normals()
    o3d.utility.random.seed(seed)
    pc = mesh.sample_points_uniformly(n, use_triangle_normal=True)
    return np.asarray(pc.points), np.asarray(pc.normals)


def _joint_axis(part: Part, T_world_parent: np.ndarray) -> JointAxis:
    j = part.joint
    return JointAxis(T_world_parent @ j.origin.matrix(), tuple(j.axis), j.type, j.lower, j.upper)


def _grid(part: Part, cfg: ArticulatedConfig) -> np.ndarray:
    j = part.joint
    step = math.radians(cfg.coarse_step_deg) if j.type == "revolute" else cfg.coarse_step_m
    n = max(2, int(math.ceil((j.upper - j.lower) / step)) + 1)
    return np.linspace(j.lower, j.upper, n)


def coarse_joint_search(samples: tuple[np.ndarray, np.ndarray], joint: JointAxis,
                        values: np.ndarray, depth: np.ndarray, K, T_world_camera: np.ndarray,
                        tau: float = 0.02) -> np.ndarray:
    """Score of every joint value: ``depth_agreement`` of the part's front-facing samples."""
    pts, nrm = samples
    cam = T_world_camera[:3, 3]
    T_cw = np.linalg.inv(T_world_camera)
    Ts = np.stack([joint.T_world_part(v) for v in values])             # (S, 4, 4)
    pw = np.einsum("sij,nj->sni", Ts[:, :3, :3], pts) + Ts[:, None, :3, 3]
    nw = np.einsum("sij,nj->sni", Ts[:, :3, :3], nrm)
    front = np.einsum("sni,sni->sn", nw, cam - pw) > 0
    return depth_agreement(pw @ T_cw[:3, :3].T + T_cw[:3, 3], depth, K, tau, mask=front)


def _move(correction: np.ndarray, T_world_object: np.ndarray) -> tuple[float, float, float]:
    """How far a correction moves the object's origin (x, y in metres) and turns it (rad)."""
    T_new = np.linalg.inv(correction) @ T_world_object
    d = T_new[:3, 3] - T_world_object[:3, 3]
    return float(d[0]), float(d[1]), float(math.atan2(correction[1, 0], correction[0, 0]))


# -- the pipeline --------------------------------------------------------------------------

@single_threaded_blas
def register_base(world, object_id: str, depth: np.ndarray, K, T_world_camera: np.ndarray,
                  cfg: ArticulatedConfig = ArticulatedConfig(),
                  observed: Optional[View] = None, include_parts: bool = False) -> ObjectRegistration:
    """Register a large object (rigid; planar or 6-DoF) from one depth image: its base only,
    or with ``include_parts`` the whole object with its parts in the map's states (right when
    the map's door states are right; a fridge's carcass hides behind its door).

    ``depth``: metres, 0 = no reading; ``T_world_camera``: the believed camera pose. Raises
    ``RegistrationFailed`` when the object is not seen well enough.
    """
    t0 = time.perf_counter()
    obj = world.get(object_id)
    if not isinstance(obj, LargeObject):
        raise PerceptionError("not a large object", node=object_id)
    T_obj = world.T_world(object_id)
    meshes = object_meshes(world, obj, children=False)
    ref = render_reference(meshes, K, T_world_camera, scale=cfg.reference_scale)
    base_ref = ref if include_parts else ref.select(_object_nodes(obj))
    if len(base_ref) < max(cfg.base.min_points, cfg.min_base_points):
        raise RegistrationFailed(f"the camera would see only {len(base_ref)} points of it",
                                 node=object_id)
    t1 = time.perf_counter()
    obs = observed if observed is not None else observed_view(depth, K, T_world_camera, cfg.stride)
    lo, hi = base_ref.points.min(0), base_ref.points.max(0)
    src = obs.points[crop_box(obs.points, lo, hi, cfg.margin)]
    t2 = time.perf_counter()
    try:
        if cfg.mode == "6dof":
            res = register_6dof(src, base_ref.points, base_ref.normals, cfg=cfg.base)
        else:
            scorer = DepthAgreement(base_ref.points, depth, K, T_world_camera, max_points=1500)
            res = register_planar(src, base_ref.points, base_ref.normals, cfg=cfg.base,
                                  scorer=scorer, search_range=cfg.search_range,
                                  search_step=cfg.search_step)
    except RegistrationFailed as err:
        raise RegistrationFailed(err.message, err.result, node=object_id) from None
    # ICP can slide to where other surfaces (open drawers in front of the carcass) pull it;
    # the depth image says whether it explains the view better than where it started.
    check = DepthAgreement(base_ref.points, depth, K, T_world_camera, max_points=2000)
    s_new, s_old = check([res.T, np.eye(4)])
    if s_new < s_old and cfg.mode != "6dof":
        # Once more from the map's pose with the tighter gates only.
        fine = replace(cfg.base, gates=cfg.base.gates[1:], iterations=cfg.base.iterations[1:])
        try:
            res2 = register_planar(src, base_ref.points, base_ref.normals, cfg=fine)
            s2 = check([res2.T])[0]
            if s2 >= s_old:
                res, s_new = res2, s2
        except RegistrationFailed:
            pass
    if s_new < s_old:
        raise RegistrationFailed(f"the registration explains the view worse than the map's pose "
                                 f"({s_new} vs {s_old} agreeing points)", res, node=object_id)
    t3 = time.perf_counter()
    T_world_object = np.linalg.inv(res.T) @ T_obj
    return ObjectRegistration(object_id, T_world_object, res.T, res, observed=obs,
                              timings_ms={"reference": 1000 * (t1 - t0),
                                          "observed": 1000 * (t2 - t1),
                                          "base_icp": 1000 * (t3 - t2)})


@single_threaded_blas
def register_articulated(world, object_id: str, depth: np.ndarray, K,
                         T_world_camera: np.ndarray, cfg: ArticulatedConfig = ArticulatedConfig(),
                         parts: Optional[list[str]] = None) -> ObjectRegistration:
    """Register the base, then every part (or the given ``parts``) under its joint, parents
    before children. See the module docstring."""
    T_obj = world.T_world(object_id)
    note = ""
    try:
        out = register_base(world, object_id, depth, K, T_world_camera, cfg)
        x, y, yaw = _move(out.correction, T_obj)
        if math.hypot(x, y) > cfg.max_base_move or abs(math.degrees(yaw)) > cfg.max_base_turn_deg:
            note = (f"base registration moved it {math.hypot(x, y) * 100:.1f} cm, "
                    f"{math.degrees(yaw):.1f} deg: more than a door reading trusts (register "
                    f"the object first)")
    except RegistrationFailed as err:
        note = err.message
    if note:
        # The base barely shows (a fridge is all door, a wall cabinet shows a few edges) or
        # moved more than expected: the parts are read from where the map has the base, and
        # the reason stays in ``base_note``. A door's angle and the base's yaw are confounded
        # when only the door is seen, so the base is never fitted to the doors.
        out = ObjectRegistration(object_id, T_obj, np.eye(4),
                                 ICPResult(np.eye(4), 0.0, float("inf"), False, 0),
                                 observed=observed_view(depth, K, T_world_camera, cfg.stride),
                                 base_note=f"base kept from the map: {note}")
    obj = world.get(object_id)
    obs = out.observed
    level = [(p, out.T_world_object) for p in getattr(obj, "parts", [])]
    states: dict[str, float] = {}
    while level:
        t0 = time.perf_counter()
        coarse: dict[str, tuple] = {}
        for part, T_parent in level:
            if parts is not None and part.id not in parts:
                continue
            joint = _joint_axis(part, T_parent)
            if part.joint.type == "fixed":
                out.parts[part.id] = PartState(part.id, "fixed", 0.0, joint.T_world_joint)
                continue
            samples = part_samples(world, part, cfg.samples)
            grid = _grid(part, cfg)
            scores = coarse_joint_search(samples, joint, grid, depth, K, T_world_camera)
            best = float(grid[int(np.argmax(scores))])
            coarse[part.id] = (part, joint, best, samples, grid, scores)
            states[part.id] = best
        t1 = time.perf_counter()
        out.timings_ms["coarse"] = out.timings_ms.get("coarse", 0.0) + 1000 * (t1 - t0)
        if not coarse:
            break
        meshes = object_meshes(world, obj, T_world_object=out.T_world_object, states=states,
                               children=False)
        ref = render_reference(meshes, K, T_world_camera, scale=cfg.reference_scale)
        t2 = time.perf_counter()
        out.timings_ms["part_reference"] = out.timings_ms.get("part_reference", 0.0) + 1000 * (t2 - t1)
        nxt = []
        for pid, (part, joint, best, samples, grid, scores) in coarse.items():
            try:
                normal = part_face(world, part).T_part_face[:3, 0]
            except PerceptionError as err:
                st = PartState(pid, part.joint.type, None, None, coarse_value=best,
                               reason=err.message)
            else:
                st = _refine_part(part, joint, best, samples, grid, ref, obs, cfg,
                                  T_world_camera[:3, 3], normal,
                                  slack=cfg.hinge_slack if note else 0.0)
            out.parts[pid] = st
            if st.value is not None:
                states[pid] = st.value
                nxt += [(c, st.T_world_part) for c in part.parts]
        out.timings_ms["part_icp"] = out.timings_ms.get("part_icp", 0.0) + 1000 * (time.perf_counter() - t2)
        level = nxt
    return out


def _refine_part(part: Part, joint: JointAxis, best: float, samples, grid, ref: View, obs: View,
                 cfg: ArticulatedConfig, cam_position: np.ndarray,
                 face_normal: np.ndarray, slack: float = 0.0) -> PartState:
    view = ref.select(_part_nodes(part))
    jt = part.joint.type
    # Points seen at less than ~80 degrees from their normal: a door seen edge-on shows only
    # its thin edge (and, on a real sensor, grazing-angle dropouts), too little to trust.
    # Only the broad faces count (normals along the face's thin axis): seen edge-on, a door
    # shows its edge strip squarely, which pins down where the edge is but not, on a real
    # sensor, reliably the angle.
    rays = view.points - cam_position
    rays /= np.linalg.norm(rays, axis=1, keepdims=True) + 1e-12
    n_face = joint.T_world_part(best)[:3, :3] @ face_normal
    broad = np.abs(view.normals @ n_face) > 0.8
    well_seen = int(np.sum(broad & (-np.einsum("ij,ij->i", rays, view.normals) > cfg.min_incidence)))
    if well_seen < cfg.min_points:
        return PartState(part.id, jt, None, None, points=well_seen, coarse_value=best,
                         reason=f"only {well_seen} points of it would be seen well at the best "
                                f"coarse state (edge-on or hidden)")
    T_part = joint.T_world_part(best)
    T_inv = np.linalg.inv(T_part)
    mp = transform(T_inv, view.points)
    mn = view.normals @ T_inv[:3, :3].T
    # The observation around everywhere the part can be.
    pts = samples[0]
    corners = np.concatenate([transform(joint.T_world_part(v), pts[:: max(1, len(pts) // 200)])
                              for v in (grid[0], grid[len(grid) // 2], grid[-1])])
    m = crop_box(obs.points, corners.min(0), corners.max(0), 0.05, floor_z=None)
    observed = obs.points[m]
    if len(observed) < cfg.min_points:
        return PartState(part.id, jt, None, None, coarse_value=best,
                         reason="nothing observed where the part can be")
    try:
        res = register_joint(mp, mn, observed, joint, best, cfg.joint, slack=slack)
    except RegistrationFailed as err:
        return PartState(part.id, jt, None, None, coarse_value=best, reason=err.message)
    n_in = len(res.inliers)
    if n_in < cfg.min_points or res.fitness < cfg.min_fitness:
        return PartState(part.id, jt, None, None, fitness=res.fitness, residual=res.residual,
                         points=n_in, coarse_value=best,
                         reason=f"too little of it matched ({n_in} points, fitness "
                                f"{res.fitness:.2f})")
    return PartState(part.id, jt, float(res.value), res.T, fitness=res.fitness,
                     residual=res.residual, points=n_in, coarse_value=best)


# -- faces and handles ---------------------------------------------------------------------

@dataclass(frozen=True)
class Face:
    """A part's face, from its geometry. ``T_part_face``: origin at the centre of the face's
    outer surface, +x its outward normal, y and z in its plane (z the in-plane axis nearest
    the part's z, then y, then x); ``half_size``: (y, z) half sizes of its rectangle (m);
    ``thickness``: its extent along the normal (m)."""
    T_part_face: np.ndarray
    half_size: tuple[float, float]
    thickness: float


def _triangle_scatter(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, 3x3 sum over triangles of area * n n^T) of a triangle mesh."""
    V = np.asarray(mesh.vertices)
    F = np.asarray(mesh.triangles)
    if len(F) == 0:
        return V, np.zeros((3, 3))
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])   # 2 * area * n
    a = np.linalg.norm(cr, axis=1)
    ok = a > 1e-15
    return V, (cr[ok].T / a[ok]) @ cr[ok] * 0.5


def _parent_centre(world, part: Part) -> np.ndarray:
    """The part's parent's geometric centre in the part frame at the part's closed state
    (its lower limit, or 0 where that lies in the range): where "inside" is."""
    parent = world.parent(part.id)
    lib, base_dir = world.apartment.library, world.base_dir
    pts = [np.asarray(visual_mesh(v, base_dir).vertices)
           for v in model_visuals(parent.model, lib)] if getattr(parent, "model", None) else []
    pts = [p for p in pts if len(p)]
    c = (np.concatenate(pts).min(0) + np.concatenate(pts).max(0)) / 2 if pts else np.zeros(3)
    j = part.joint
    closed = min(max(0.0, j.lower), j.upper) if j.type != "fixed" else 0.0
    T = np.linalg.inv(joint_T(j, closed))
    return T[:3, :3] @ c + T[:3, 3]


def part_face(world, part: Part) -> Face:
    """The face of a door or drawer from its geometry, a box or a mesh (the visual named
    "face", else the one with the largest surface): its normal is the thin axis of a box, or
    for a mesh the dominant direction of its triangles' normals (the eigenvector of the
    area-weighted normal scatter with the largest eigenvalue: a slab's two broad sides);
    outward is the side its handles stand on, else the side away from its parent's centre.
    Raises PerceptionError when the part has no geometry."""
    lib, base_dir = world.apartment.library, world.base_dir
    vis = model_visuals(part.model, lib)
    cands = [v for v in vis if v.name == "face"] or vis
    meshes = [(v, visual_mesh(v, base_dir)) for v in cands]
    meshes = [(v, m) for v, m in meshes if len(m.triangles)]
    if not meshes:
        raise PerceptionError("the part has no geometry to find its face on", node=part.id)
    v, mesh = max(meshes, key=lambda vm: vm[1].get_surface_area())
    V, S = _triangle_scatter(mesh)
    if v.shape == "box":
        R = v.pose.matrix()[:3, :3]
        n = R[:, int(np.argmin(v.size))]
    else:
        n = np.linalg.eigh(S)[1][:, 2]
    centre = (V.min(0) + V.max(0)) / 2
    if part.handles:
        side = np.mean([(np.asarray(h.pose.position) - centre) @ n for h in part.handles])
    else:
        side = -(_parent_centre(world, part) - centre) @ n
    if side < 0:
        n = -n
    ez = next((a - (a @ n) * n for a in np.eye(3)[[2, 1, 0]]
               if np.linalg.norm(a - (a @ n) * n) > 0.7), None)
    ez = ez / np.linalg.norm(ez)
    ey = np.cross(ez, n)
    dn, dy, dz = V @ n, V @ ey, V @ ez
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = n, ey, ez
    T[:3, 3] = (dn.max() * n + (dy.min() + dy.max()) / 2 * ey + (dz.min() + dz.max()) / 2 * ez)
    return Face(T, (float(np.ptp(dy)) / 2, float(np.ptp(dz)) / 2), float(np.ptp(dn)))


@single_threaded_blas
def register_handles(world, reg: ObjectRegistration, T_world_camera: np.ndarray,
                     part_ids: Optional[list[str]] = None, cfg=None,
                     observed: Optional[np.ndarray] = None) -> dict:
    """Fine handle poses (hearth.perception.handles) for the registered parts with a known state,
    on the face their part's geometry gives (``part_face``). Returns {handle_id:
    HandleEstimate or PerceptionError}."""
    from hearth.perception.handles import HandleConfig, estimate_handle
    cfg = cfg or HandleConfig()
    pts = reg.observed.points if observed is None else observed
    out = {}
    for pid, st in reg.parts.items():
        if part_ids is not None and pid not in part_ids:
            continue
        part = world.get(pid)
        for h in getattr(part, "handles", []):
            if not st.known:
                out[h.id] = PerceptionError(f"state of {pid} unknown: {st.reason}", node=h.id)
                continue
            try:
                face = part_face(world, part)
                out[h.id] = estimate_handle(pts, st.T_world_part @ face.T_part_face,
                                            face.half_size, st.T_world_part @ h.pose.matrix(),
                                            h.radius, h.length, h.standoff,
                                            T_world_camera[:3, 3], h.id, cfg,
                                            prior_trusted=not reg.base_note)
            except PerceptionError as err:
                out[h.id] = err
    return out


@single_threaded_blas
def estimate_handle_pose(world, handle_id: str, depth: np.ndarray, K,
                         T_world_camera: np.ndarray,
                         cfg: ArticulatedConfig = ArticulatedConfig(), handle_cfg=None):
    """Register the handle's object (its base and the handle's part) and return the handle's
    fine pose (``HandleEstimate``) and the registration. Raises PerceptionError when the part's
    state is unknown or the handle is not seen."""
    part = world.parent(handle_id)
    obj = world.large_object_of(handle_id)
    parts = [n.id for n in world.chain(handle_id) if isinstance(n, Part)]
    reg = register_articulated(world, obj.id, depth, K, T_world_camera, cfg, parts=parts or None)
    if not isinstance(part, Part):
        raise PerceptionError("only handles on doors and drawers are estimated", node=handle_id)
    est = register_handles(world, reg, T_world_camera, [part.id], handle_cfg).get(handle_id)
    if isinstance(est, Exception) or est is None:
        raise est or PerceptionError("handle not found", node=handle_id)
    return est, reg
