"""Scenarios: a belief map and a perturbed truth for the simulated robot (docs/robot-adapter.md).

``make_scenario(world, seed)`` copies the world twice: the *belief* stays as the world was;
the *truth* is perturbed with a numpy Generator seeded by ``seed`` (so a seed always gives
the same scenario):

- small objects moved to other supporting surfaces (the ``surface`` elements of large
  objects: table tops, shelves), at free spots;
- doors and drawers left ajar, knobs turned on;
- clutter (small boxes and cylinders) and taller occluders put on tables, unknown to the
  belief;
- a true start pose at a parking position and a localisation error (believed = true composed
  with the error, body frame);
- optionally a stuck knob and a locked door.

``save_scenario`` writes ``belief.xml``, ``truth.xml`` (worldmodel XML) and
``scenario.json`` (format below, versioned); ``load_scenario`` reads them back.

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
from worldmodel.nodes import Model, SmallObject, Visual
from worldmodel.pose import Pose

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


def make_scenario(world, seed: int, config: ScenarioConfig = ScenarioConfig()) -> Scenario:
    """A scenario from ``world`` (left unchanged) and ``seed``."""
    rng = np.random.default_rng(seed)
    belief = world.copy()
    truth = world.copy()
    log: list[dict] = []
    surfaces = _surfaces(truth)
    # Small objects to other surfaces.
    small = sorted(o.id for o in truth.small_objects())
    n = min(int(rng.integers(config.moved_objects[0], config.moved_objects[1] + 1)), len(small))
    for oid in rng.choice(small, size=n, replace=False) if n else []:
        oid = str(oid)
        here = truth.parent(oid).id
        options = [s for s in surfaces if s[0] != here] or surfaces
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
    # Clutter and occluders on tables, unknown to the belief.
    tops = [s for s in surfaces if s[1].relation == "on"]
    for kind, (lo_n, hi_n) in (("clutter", config.clutter), ("occluder", config.occluders)):
        for i in range(int(rng.integers(lo_n, hi_n + 1)) if tops else 0):
            spot = _free_spot(truth, tops, rng)
            if spot is None:
                continue
            parent, surface, pose = spot
            obj = _clutter(f"{kind}_{i}", kind, rng, pose)
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
                    perturbations=log, source=str(world.path or ""))


def save_scenario(scenario: Scenario, directory) -> Path:
    """Write belief.xml, truth.xml and scenario.json into ``directory`` (created)."""
    from worldmodel.io import save_world
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
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
    from worldmodel.errors import WorldError
    from worldmodel.io import load_world
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


def _planar_dict(p: Pose) -> dict:
    return dict(x=p.x, y=p.y, yaw=p.yaw)


def _surfaces(world) -> list:
    out = []
    for obj in sorted(world.large_objects(), key=lambda o: o.id):
        for s in obj.surfaces:
            out.append((obj.id, s))
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
