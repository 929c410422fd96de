"""Scenarios: a belief map and a perturbed truth for the simulated robot (docs/robot-adapter.md).

``make_scenario(world, seed)`` copies the world twice: the *belief* stays as the world was;
the *truth* is perturbed with a numpy Generator seeded by ``seed`` (so a seed always gives
the same scenario):

- small objects moved to other supporting surfaces (the ``surface`` elements of large
  objects: table tops, shelves) with room above them for the object, at free spots;
- doors and drawers left ajar, knobs turned on;
- clutter (small boxes and cylinders) and taller occluders put on surfaces open enough above
  (table tops; shelves only where the shelf above leaves room), unknown to the belief;
- a true start pose at a parking position and a localisation error (believed = true composed
  with the error, body frame);
- optionally a stuck knob and a locked door.

Everything perturbed is taken from the map (its surfaces, parts, knobs and parking
positions), so any valid world works; a world the tool cannot use (no parking position to
start the robot at) is one ``RobotError`` line naming the node. A world without surfaces
gets no moved objects, clutter or occluders, and ``Scenario.notes`` says so.

``save_scenario`` writes ``belief.xml``, ``truth.xml`` (worldmodel XML) and
``scenario.json`` (format below, versioned), and copies the files the world refers to
(meshes, point clouds) into the scenario directory, so that both maps validate there;
``load_scenario`` reads them back.

scenario.json (version 1)::

    {"version": 1, "seed": 7, "source": "data/demo_home/world.xml",
     "belief": "belief.xml", "truth": "truth.xml",
     "start_pose": {"x":..,"y":..,"yaw":..},          # true base pose at the start
     "localisation_error": {"x":..,"y":..,"yaw":..},  # body frame, believed = true * error
     "stuck_knobs": [...], "locked": [...],
     "perturbations": [{"kind": "moved"|"joint"|"knob"|"clutter"|"occluder", ...}, ...]}
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from hearth.robot.errors import RobotError
from hearth.worldmodel.nodes import Model, SmallObject, Visual
from hearth.worldmodel.pose import Pose

VERSION = 1
FILE = "scenario.json"


@dataclass
class ScenarioConfig:
    """How much to perturb (counts, probabilities, metres, radians)."""
    moved_objects: tuple[int, int] = (1, 3)
    door_ajar_probability: float = 0.3
    knob_on_probability: float = 0.3
    clutter: tuple[int, int] = (1, 4)
    occluders: tuple[int, int] = (0, 2)
    max_position_error: float = 0.12
    max_yaw_error: float = math.radians(5)
    stuck_knob_probability: float = 0.15
    locked_door_probability: float = 0.1


@dataclass
class Scenario:
    seed: int
    belief: object
    truth: object
    start_pose: Pose
    localisation_error: Pose
    stuck_knobs: list[str] = field(default_factory=list)
    locked: list[str] = field(default_factory=list)
    perturbations: list[dict] = field(default_factory=list)
    source: str = ""
    directory: Optional[Path] = None
    notes: list[str] = field(default_factory=list)


def make_scenario(world, seed: int, config: ScenarioConfig = ScenarioConfig()) -> Scenario:
    """A scenario from ``world`` (left unchanged) and ``seed``."""
    rng = np.random.default_rng(seed)
    _check_usable(world)
    belief = world.copy()
    truth = world.copy()
    log: list[dict] = []
    notes: list[str] = []
    surfaces = _surfaces(truth)
    room = _headroom(truth, surfaces)
    # Small objects to other surfaces.
    small = sorted(o.id for o in truth.small_objects())
    n = min(int(rng.integers(config.moved_objects[0], config.moved_objects[1] + 1)), len(small))
    if n and not surfaces:
        notes.append("no <surface> in the map: no small object moved, no clutter put down")
        n = 0
    for oid in rng.choice(small, size=n, replace=False) if n else []:
        oid = str(oid)
        here = truth.parent(oid).id
        height = _height(truth, oid) + 0.01
        fits = [s for s in surfaces if room[(s[0], s[1].id)] >= height]
        options = [s for s in fits if s[0] != here] or fits
        if not options:
            notes.append(f"{oid}: no surface has room for it; not moved")
            continue
        spot = _free_spot(truth, options, rng)
        if spot is None:
            continue
        parent, surface, pose = spot
        truth.move_object(oid, parent, pose, relation=surface.relation, source="scenario")
        log.append(dict(kind="moved", object=oid, from_parent=here, to_parent=parent,
                        surface=surface.id, pose=pose.as_dict()))
    # Doors, drawers and knobs.
    for part in sorted(truth.nodes("Part"), key=lambda p: p.id):
        j = part.joint
        if j.type == "fixed" or rng.random() >= config.door_ajar_probability:
            continue
        lo, hi = j.lower, j.upper
        value = float(rng.uniform(lo + 0.15 * (hi - lo), lo + 0.7 * (hi - lo)))
        truth.set_joint_state(part.id, value, source="scenario")
        log.append(dict(kind="joint", part=part.id, state=value))
    for knob in sorted(truth.knobs(), key=lambda k: k.id):
        if rng.random() >= config.knob_on_probability:
            continue
        on = [s.name for s in knob.states if s.name != knob.off]
        if not on:
            continue
        state = str(rng.choice(on))
        truth.set_knob_state(knob.id, state, source="scenario")
        log.append(dict(kind="knob", knob=knob.id, state=state))
    # Clutter and occluders on surfaces open enough above (table tops), unknown to the belief.
    for kind, (lo_n, hi_n) in (("clutter", config.clutter), ("occluder", config.occluders)):
        tops = [s for s in surfaces if s[1].relation == "on"
                and room[(s[0], s[1].id)] >= CLUTTER_HEIGHT[kind] + 0.02]
        for i in range(int(rng.integers(lo_n, hi_n + 1)) if tops else 0):
            spot = _free_spot(truth, tops, rng)
            if spot is None:
                continue
            parent, surface, pose = spot
            oid = f"{kind}_{i}"
            while oid in truth:
                oid += "_"
            obj = _clutter(oid, kind, rng, pose)
            truth.add_small_object(obj, parent, source="scenario")
            log.append(dict(kind=kind, object=obj.id, parent=parent, pose=pose.as_dict()))
    # Start pose and localisation error.
    parkings = [pose for o in sorted(truth.large_objects(), key=lambda o: o.id)
                for _, pose in truth.parking_positions(o.id)]
    start = parkings[int(rng.integers(len(parkings)))] if parkings else Pose()
    r = config.max_position_error * math.sqrt(rng.random())
    a = rng.uniform(-math.pi, math.pi)
    error = Pose.planar(r * math.cos(a), r * math.sin(a),
                        float(rng.uniform(-config.max_yaw_error, config.max_yaw_error)))
    stuck, locked = [], []
    knobs = sorted(k.id for k in truth.knobs())
    if knobs and rng.random() < config.stuck_knob_probability:
        stuck.append(str(rng.choice(knobs)))
    doors = sorted(p.id for p in truth.nodes("Part") if p.joint.type == "revolute")
    if doors and rng.random() < config.locked_door_probability:
        locked.append(str(rng.choice(doors)))
    return Scenario(seed=int(seed), belief=belief, truth=truth, start_pose=start,
                    localisation_error=error, stuck_knobs=stuck, locked=locked,
                    perturbations=log, source=str(world.path or ""), notes=notes)


def save_scenario(scenario: Scenario, directory) -> Path:
    """Write belief.xml, truth.xml and scenario.json into ``directory`` (created), with copies
    of the mesh and point-cloud files the maps refer to (``copy_world_files``)."""
    from hearth.worldmodel.io import save_world
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    copy_world_files([scenario.belief, scenario.truth], d)
    save_world(scenario.belief, d / "belief.xml")
    save_world(scenario.truth, d / "truth.xml")
    meta = dict(version=VERSION, seed=scenario.seed, source=scenario.source,
                belief="belief.xml", truth="truth.xml",
                start_pose=_planar_dict(scenario.start_pose),
                localisation_error=_planar_dict(scenario.localisation_error),
                stuck_knobs=scenario.stuck_knobs, locked=scenario.locked,
                perturbations=scenario.perturbations)
    (d / FILE).write_text(json.dumps(meta, indent=1) + "\n")
    scenario.directory = d
    return d


def load_scenario(directory, clock=None) -> Scenario:
    """Read a scenario directory; RobotError (one line, with the file) when it is broken."""
    from hearth.worldmodel.errors import WorldError
    from hearth.worldmodel.io import load_world
    d = Path(directory)
    path = d / FILE
    if not path.is_file():
        raise RobotError("no scenario here (scenario.json is missing)", file=str(path))
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        line = getattr(err, "lineno", None)
        raise RobotError(f"corrupt scenario: {getattr(err, 'msg', err)}", file=str(path),
                         line=line) from None
    if not isinstance(meta, dict) or meta.get("version") != VERSION:
        v = meta.get("version") if isinstance(meta, dict) else None
        raise RobotError(f"unknown scenario version {v!r} (this Hearth reads {VERSION})",
                         file=str(path))
    try:
        worlds = {}
        for key in ("belief", "truth"):
            f = d / str(meta.get(key, f"{key}.xml"))
            if not f.is_file():
                raise RobotError(f"{f.name} is missing", file=str(path))
            worlds[key] = load_world(f, clock=clock)
        sp, le = meta["start_pose"], meta["localisation_error"]
        return Scenario(seed=int(meta.get("seed", 0)), belief=worlds["belief"],
                        truth=worlds["truth"],
                        start_pose=Pose.planar(float(sp["x"]), float(sp["y"]), float(sp["yaw"])),
                        localisation_error=Pose.planar(float(le["x"]), float(le["y"]),
                                                       float(le["yaw"])),
                        stuck_knobs=list(meta.get("stuck_knobs", [])),
                        locked=list(meta.get("locked", [])),
                        perturbations=list(meta.get("perturbations", [])),
                        source=str(meta.get("source", "")), directory=d)
    except WorldError:
        raise
    except (KeyError, TypeError, ValueError) as err:
        raise RobotError(f"bad scenario field: {err}", file=str(path)) from None


def copy_world_files(worlds, directory) -> None:
    """Copy the files ``worlds`` refer to (mesh visuals, room point clouds; relative to each
    world's ``base_dir``) into ``directory``, so world files saved there validate.

    A relative path inside the world's folder keeps its path (``meshes/door.ply`` lands in
    ``directory/meshes/door.ply``); any other (absolute, or leading out with ``..``) is copied
    to ``directory/files/`` under a name made unique by a hash of its source path, and the
    maps are rewritten to it. Each world's ``base_dir`` becomes ``directory``. RobotError
    naming the node when a file is missing."""
    import hashlib
    import os
    import shutil
    d = Path(directory)
    copied: dict[Path, str] = {}
    for world in worlds:
        base = Path(world.base_dir) if world.base_dir is not None else Path.cwd()
        for node_id, holder, attr in _file_refs(world):
            rel = getattr(holder, attr)
            src = (base / rel).resolve()
            if src not in copied:
                if not src.is_file():
                    raise RobotError(f"{attr if attr != 'file' else 'mesh'} file {rel!r} not found "
                                     f"(looked in {base})", node=node_id)
                inside = not os.path.isabs(rel) and ".." not in Path(rel).parts
                new = Path(rel).as_posix() if inside else (
                    f"files/{hashlib.sha1(str(src).encode()).hexdigest()[:10]}-{src.name}")
                dst = d / new
                if dst.resolve() != src:
                    dst.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(src, dst)
                copied[src] = new
            setattr(holder, attr, copied[src])
        world.base_dir = d.resolve()


def _file_refs(world):
    """(node id, object, attribute) for every file reference of a world
    (hearth.worldmodel.validate.file_references)."""
    from hearth.worldmodel.validate import file_references
    return file_references(world.apartment)


def _check_usable(world) -> None:
    """RobotError naming the node when a scenario cannot be made from ``world``."""
    if not any(o.parking for o in world.large_objects()):
        raise RobotError("the map has no parking position to start the robot at (add a large "
                         "object with <parking>; docs/world-format.md)",
                         node=world.apartment.id)


def _planar_dict(p: Pose) -> dict:
    return dict(x=p.x, y=p.y, yaw=p.yaw)


def _surfaces(world) -> list:
    out = []
    for obj in sorted(world.large_objects(), key=lambda o: o.id):
        for s in obj.surfaces:
            out.append((obj.id, s))
    return out


#: The tallest clutter and occluder ``_clutter`` makes (metres).
CLUTTER_HEIGHT = {"clutter": 0.15, "occluder": 0.33}


def _height(world, object_id: str) -> float:
    """Height (metres) of a small object's model above its base."""
    from hearth.worldmodel.geometry import small_object_meshes
    meshes = small_object_meshes(world, world.get(object_id), T_world_object=np.eye(4))
    z = [np.asarray(m.mesh.vertices)[:, 2].max() for m in meshes if len(m.mesh.vertices)]
    return float(max(z)) if z else 0.0


def _headroom(world, surfaces) -> dict:
    """(object id, surface id) -> free height above the surface (metres; inf when nothing of
    its object is above it): up to the next surface of the same object above it (less a
    board's thickness), else up to the object's top when the surface is inside it."""
    from hearth.worldmodel.geometry import object_meshes
    tops = {}
    out = {}
    for oid, s in surfaces:
        if oid not in tops:
            obj = world.get(oid)
            meshes = object_meshes(world, obj, T_world_object=np.eye(4), children=False)
            z = [np.asarray(m.mesh.vertices)[:, 2].max() for m in meshes if len(m.mesh.vertices)]
            tops[oid] = float(max(z)) if z else -math.inf
        above = [o.pose.z for o2, o in surfaces if o2 == oid and o.pose.z > s.pose.z + 1e-6
                 and abs(o.pose.x - s.pose.x) < (o.size_x + s.size_x) / 2
                 and abs(o.pose.y - s.pose.y) < (o.size_y + s.size_y) / 2]
        if above:
            out[(oid, s.id)] = min(above) - s.pose.z - 0.03
        elif s.pose.z < tops[oid] - 0.03:
            out[(oid, s.id)] = tops[oid] - s.pose.z - 0.03
        else:
            out[(oid, s.id)] = math.inf
    return out


def _free_spot(world, options, rng, margin: float = 0.07, clearance: float = 0.12, tries: int = 40):
    """(parent id, surface, pose in the parent's frame) of a free spot on one of ``options``."""
    for _ in range(tries):
        parent, s = options[int(rng.integers(len(options)))]
        hx, hy = max(s.size_x / 2 - margin, 0.0), max(s.size_y / 2 - margin, 0.0)
        local = np.array([rng.uniform(-hx, hx), rng.uniform(-hy, hy), 0.0, 1.0])
        p = s.pose.matrix() @ local
        others = [c.pose.position for c in world.get(parent).children]
        if all(np.hypot(*(p[:2] - o[:2])) > clearance for o in others):
            return parent, s, Pose(float(p[0]), float(p[1]), float(p[2]), 0.0, 0.0,
                                   float(rng.uniform(-math.pi, math.pi)))
    return None


_COLOURS = [(0.85, 0.2, 0.2), (0.2, 0.6, 0.25), (0.9, 0.75, 0.2), (0.6, 0.3, 0.7),
            (0.95, 0.95, 0.95), (0.3, 0.3, 0.35), (0.9, 0.5, 0.2)]


def _clutter(oid: str, kind: str, rng, pose: Pose) -> SmallObject:
    color = _COLOURS[int(rng.integers(len(_COLOURS)))]
    if kind == "occluder":        # a cereal-box-like board, taller than cups
        sx, sy, sz = rng.uniform(0.15, 0.25), rng.uniform(0.05, 0.08), rng.uniform(0.25, 0.33)
        vis = Visual("box", Pose(0, 0, sz / 2), size=(sx, sy, sz), color=color)
    elif rng.random() < 0.5:
        sx, sy, sz = rng.uniform(0.05, 0.14), rng.uniform(0.05, 0.14), rng.uniform(0.03, 0.12)
        vis = Visual("box", Pose(0, 0, sz / 2), size=(sx, sy, sz), color=color)
    else:
        r, h = rng.uniform(0.025, 0.05), rng.uniform(0.04, 0.15)
        vis = Visual("cylinder", Pose(0, 0, h / 2), radius=r, length=h, color=color)
    return SmallObject(id=oid, type=kind, pose=pose, description=f"scenario {kind}",
                       graspable=False, model=Model(visuals=[vis]))


# -- what the robot can see of a placement -------------------------------------------------------

def visible_pixels(world, object_id: str, open_doors: bool = True,
                   intrinsics=None) -> tuple[int, Optional[tuple[float, float, float]]]:
    """How well the robot's head camera can see a small object where it stands in ``world``
    (the truth): the most pixels of it, unhidden, in one view (640 x 480 Kinect image by
    default) over the poses a search can take near it (the parking positions of the furniture
    it stands on, and the next-best-view candidates around it, ``hearth.perception.nbv``), the head
    aimed at its middle within the head's tilt and pan limits, the furniture's doors open as
    the robot opens them (revolute ones a quarter turn) when ``open_doors``. Returns (pixels,
    the base pose (x, y, yaw) that sees them; None when none does).

    Only the object's bounding box in each image is ray cast (open3d RaycastingScene with the
    room's meshes: its walls, furniture and small objects), so a few hundred candidate views
    cost about as much as one full rendering."""
    import open3d as o3d
    from hearth.perception.camera import Intrinsics, project
    from hearth.perception.nbv import NBVConfig, candidate_bases
    from hearth.robot.sim import HEAD, camera_pose, pan_tilt_to
    from hearth.worldmodel.containers import search_states
    from hearth.worldmodel.geometry import part_in_object_T, scene_meshes, small_object_meshes

    K = intrinsics or Intrinsics.kinect()
    obj = world.get(object_id)
    parent = world.parent(object_id)
    room = world.room_of(parent.id)
    states = search_states(world, object_id) if open_doors else {}
    T_world_object = world.T_world(object_id)
    if obj.part and obj.part in states:     # in a drawer: where it is once the drawer is open
        T_world_object = world.T_world(parent.id) @ part_in_object_T(parent, obj.part, states) \
            @ obj.pose.matrix()
    scene = o3d.t.geometry.RaycastingScene()
    mine = set()
    for lm in scene_meshes(world, room_ids=[room.id], states=states or None):
        if len(lm.mesh.triangles):
            gid = scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(lm.mesh))
            if lm.node == object_id:
                mine.add(gid)
    verts = np.vstack([np.asarray(lm.mesh.vertices)
                       for lm in small_object_meshes(world, obj, T_world_object=T_world_object)])
    centre = verts.mean(0)
    aim = np.r_[centre[:2], (verts[:, 2].min() + verts[:, 2].max()) / 2]
    poses = [(p.x, p.y, p.yaw) for _, p in world.parking_positions(parent.id)]
    poses += [c[:3] for c in candidate_bases(world, centre, NBVConfig(), room)]
    best, best_pose = 0, None
    for x, y, yaw in poses:
        base = Pose.planar(x, y, yaw)
        pan, tilt = pan_tilt_to(base, aim, HEAD)
        T_wc = camera_pose(base, pan, tilt, HEAD)
        T_cw = np.linalg.inv(T_wc)
        uv, front = project(verts @ T_cw[:3, :3].T + T_cw[:3, 3], K)
        if not front.any():
            continue
        u0, v0 = np.floor(uv[front].min(0)).astype(int)
        u1, v1 = np.ceil(uv[front].max(0)).astype(int)
        u0, v0 = max(u0, 0), max(v0, 0)
        u1, v1 = min(u1, K.width - 1), min(v1, K.height - 1)
        if u1 < u0 or v1 < v0:
            continue
        u, v = np.meshgrid(np.arange(u0, u1 + 1), np.arange(v0, v1 + 1))
        d = np.stack([(u.ravel() - K.cx) / K.fx, (v.ravel() - K.cy) / K.fy,
                      np.ones(u.size)], axis=1) @ T_wc[:3, :3].T
        rays = np.c_[np.tile(T_wc[:3, 3], (len(d), 1)), d].astype(np.float32)
        ids = scene.cast_rays(o3d.core.Tensor(rays))["geometry_ids"].numpy()
        n = int(np.isin(ids, list(mine)).sum())
        if n > best:
            best, best_pose = n, (float(x), float(y), float(yaw))
    return best, best_pose
