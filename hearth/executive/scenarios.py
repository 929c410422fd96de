"""The scenario suite: the named missions on seeded simulated homes, in parallel processes.

A :class:`Case` names a mission, a world (the demo home, a generated home ``home:SEED``, or a
world file), a seed, the node the mission is about (``target``) and whether its goal can be
reached. Everything it needs is taken from that world's map, nothing from one home in
particular: the object to fetch, the appliance whose knobs to turn off, the landmark to
localise at, the places an object turns up at.

From the seed, :func:`make_case_scenario` perturbs the world with
``hearth.robot.scenario.make_scenario`` (a config per mission) and then sets up what the
mission is about:

- ``fetch_object`` / ``search_object``: the target object is put, in truth, at one of three
  places drawn per object (:func:`object_places`): another place that holds small objects
  (60 %), where the map believes it (25 %) or a third place (15 %), on any of that place's
  surface levels; unachievable: it is not in the home at all. Expected: "succeeded", or a
  failure whose reason says "no ... at the N places searched".
- ``turn_off_oven``: one or two of the appliance's knobs are on in truth; unachievable: one
  of them is stuck. Expected: "succeeded", or "I cannot turn off ...".
- ``refine_localisation``: the scenario's localisation error (up to 12 cm, 5 degrees) at a
  landmark. Expected: "succeeded" with the residual error under 2 cm.

A **wrong success** is a mission that says it did what it did not: a knob left on reported
off, an object reported found (or handed over) where it is not, a localisation residual over
2 cm reported corrected. The suite counts them apart from plain failures.

``warmup`` learned searches come first for fetch cases: the map records searches (20 by
default) drawn from the same placement distribution, walking the learned search order until
the object's true place, as ``RecordSearch`` would (map level: no rendering), so the run can
compare the learned order (``learned=True``) with the fixed order from the map's prior.

hearth/executive/suite.py runs cases on an engine (``suite.run_suite``): worker processes on
this machine (started with **spawn**: open3d's OpenMP thread pool deadlocks in forked
children, open3d issues #1552, #6096, #7133) or Ray tasks, each with a time limit.
"""
from __future__ import annotations

import hashlib
import math
import os
import re
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np

from hearth import demo_world_path, missions_dir

MISSIONS = missions_dir()
NAMED = ("fetch_object", "turn_off_oven", "refine_localisation")
FETCH = ("fetch_object", "search_object")
#: The missions a suite case can be made for.
SUITE_MISSIONS = FETCH + ("turn_off_oven", "refine_localisation")
#: Where an object turns up in truth, and how often: another place, the believed one, a third.
PLACE_WEIGHTS = (0.60, 0.25, 0.15)
#: A localisation residual above this after "corrected" is a wrong success (centimetres).
RESIDUAL_LIMIT_CM = 2.0
#: A found object further than this from its true place is a wrong success (metres).
FOUND_TOLERANCE_M = 0.10
#: An achievable fetch case puts its object where some pose of the search shows at least this
#: many pixels of it in the head camera's 640 x 480 image (about 50 depth points at the
#: detector's stride of 2; docs/suite.md). A placement no pose shows (a shelf or a cupboard's
#: front hiding it from every pose the head can take) is drawn again.
MIN_VISIBLE_PX = 200


@dataclass(frozen=True)
class Case:
    mission: str                 # fetch_object | search_object | turn_off_oven | refine_localisation
    seed: int
    achievable: bool = True
    learned: bool = True
    warmup: int = 0
    runs_dir: Optional[str] = None
    params: dict = field(default_factory=dict)     # extra mission parameters
    world: str = "demo"          # "demo", "home:SEED" (hearth.worldmodel.homegen) or a world file
    target: str = ""             # the node the mission is about ("": the first the map offers)
    # A model set (hearth.worldmodel.learned: objects learned from views) whose models the
    # belief's small objects get in place of the drawn ones ("": the drawn ones). The truth
    # the simulator renders keeps the drawn models.
    models: str = ""
    # Where a fetch case's object starts in truth, when not drawn from its places: "stay"
    # (where the home has it, in a drawer or behind a sliding door; the map believes it
    # there), "sliding:FURNITURE" (on a shelf of that furniture behind one of its sliding
    # doors; the map believes it where the home has it). "": drawn (object_places).
    hide: str = ""


@dataclass
class CaseResult:
    mission: str
    seed: int
    achievable: bool
    learned: bool
    outcome: str
    reason: str
    category: str                # succeeded | not_found | cannot | other
    correct: bool
    sim_time_s: float
    wall_time_s: float
    positions_visited: Optional[int] = None
    residual_cm: Optional[float] = None
    said: list = field(default_factory=list)
    map_changes: list = field(default_factory=list)
    log_path: Optional[str] = None
    world: str = "demo"
    target: str = ""
    target_type: str = ""
    wrong_success: bool = False
    #: where a fetch case's object stands in truth when the mission starts: "drawer" (in a
    #: drawer), "sliding" (behind a sliding door of a track), "" elsewhere
    where: str = ""
    #: Every drive of the simulated robot: [path length, straight line] in metres.
    drives: list = field(default_factory=list)
    #: Why the simulated robot refused each drive it had no path for (docs/navigation.md).
    refused_drives: list = field(default_factory=list)
    models: str = ""


# ---------------------------------------------------------------------------------------
# Worlds and what the missions are about in them
# ---------------------------------------------------------------------------------------
def home_cache_dir() -> Path:
    """Where generated homes are written once per machine (``$HEARTH_HOME_DIR``, default
    ``~/.cache/hearth/homes``)."""
    return Path(os.environ.get("HEARTH_HOME_DIR") or Path.home() / ".cache" / "hearth" / "homes")


def world_path(spec: str) -> Path:
    """The world file of ``demo``, ``home:SEED`` (generated on first use, kept per generator
    version) or a path."""
    if spec == "demo":
        return demo_world_path()
    if spec.startswith("home:"):
        from hearth.worldmodel import homegen
        seed = int(spec.split(":", 1)[1])
        version = getattr(homegen, "GENERATOR_VERSION", 1)
        out = home_cache_dir() / f"v{version}" / f"home-{seed:04d}"
        path = out / "world.xml"
        if not path.exists():
            homegen.make_home(seed, out)
        return path
    return Path(spec)


def resolve_world(spec: str):
    from hearth.worldmodel import load_world
    return load_world(world_path(spec))


def fetch_targets(world) -> list[str]:
    """Graspable small objects, one of each type first (sorted by type, then id), then the
    rest: the fetch cases of a home cover every kind of object it holds."""
    objs = sorted((o for o in world.small_objects() if o.graspable), key=lambda o: (o.type, o.id))
    firsts, rest, seen = [], [], set()
    for o in objs:
        (rest if o.type in seen else firsts).append(o.id)
        seen.add(o.type)
    return firsts + rest


def appliance_targets(world) -> list[str]:
    """Large objects with knobs, by id."""
    return sorted(o.id for o in world.large_objects() if world.knobs(o.id))


def landmark_targets(world) -> list[str]:
    """Static large objects with parking positions (landmarks to localise at), by id."""
    return sorted(o.id for o in world.landmarks() if o.parking)


def targets(world, mission: str) -> list[str]:
    if mission in FETCH:
        return fetch_targets(world)
    if mission == "turn_off_oven":
        return appliance_targets(world)
    if mission == "refine_localisation":
        return landmark_targets(world)
    raise ValueError(f"no targets for mission {mission!r}")


def object_places(world, object_id: str) -> list[tuple[str, float]]:
    """The places an object turns up at in the suite, with their probabilities: another
    place (PLACE_WEIGHTS[0]), the one the map believes (PLACE_WEIGHTS[1]), a third one
    (PLACE_WEIGHTS[2]). Fixed per home and object (the same every run)."""
    from hearth.worldmodel.search import candidate_places
    from hearth.worldmodel.validate import all_parts
    believed = world.parent(object_id).id
    others = sorted(p.id for p in candidate_places(world) if p.id != believed
                    and (p.surfaces or any(q.surfaces for q in all_parts(p))))
    if not others:
        return [(believed, 1.0)]
    h = int(hashlib.sha256(object_id.encode()).hexdigest()[:8], 16)
    rng = np.random.default_rng(h)
    picks = [str(p) for p in rng.choice(others, size=min(2, len(others)), replace=False)]
    out = [(picks[0], PLACE_WEIGHTS[0]), (believed, PLACE_WEIGHTS[1])]
    if len(picks) > 1:
        out.append((picks[1], PLACE_WEIGHTS[2]))
    total = sum(w for _, w in out)
    return [(p, w / total) for p, w in out]


def object_height(world, object_id: str) -> float:
    """Height (metres) of a small object's model above its base."""
    from hearth.robot.scenario import _height
    return _height(world, object_id)


def sample_place(places: list[tuple[str, float]], rng) -> str:
    names = [p for p, _ in places]
    probs = np.array([w for _, w in places])
    return str(rng.choice(names, p=probs / probs.sum()))


def object_words(world, object_id: str) -> str:
    """What a person would say for the object ("blue cup") when those words name it alone,
    else its id."""
    from hearth.worldmodel.nodes import SmallObject
    words = world.label(object_id)
    matches = [m for m in world.find(words) if isinstance(m.node, SmallObject)]
    if matches and matches[0].node.id == object_id and \
            (len(matches) == 1 or not math.isclose(matches[1].score, matches[0].score)):
        return words
    return object_id


# ---------------------------------------------------------------------------------------
# Scenarios
# ---------------------------------------------------------------------------------------
def _config(mission: str):
    from hearth.robot.scenario import ScenarioConfig
    if mission in FETCH:
        return ScenarioConfig(moved_objects=(0, 1), knob_on_probability=0.0, clutter=(0, 2),
                              occluders=(0, 1), stuck_knob_probability=0.0,
                              locked_door_probability=0.0, door_ajar_probability=0.0)
    if mission == "turn_off_oven":
        return ScenarioConfig(moved_objects=(0, 1), knob_on_probability=0.3, clutter=(0, 1),
                              occluders=(0, 0), stuck_knob_probability=0.0,
                              locked_door_probability=0.0, door_ajar_probability=0.0)
    return ScenarioConfig(moved_objects=(0, 2), knob_on_probability=0.0, clutter=(0, 2),
                          occluders=(0, 0), stuck_knob_probability=0.0,
                          locked_door_probability=0.0)


def place_on(world, object_id: str, place_id: str, rng, source: str = "scenario",
             level: Optional[str] = None) -> bool:
    """Move a small object to a free spot of one of a place's surfaces (``level``: that
    surface's id; default: one drawn at random), its parts' included (into a drawer when
    the object is low enough for it). Returns False when no spot is free."""
    from hearth.worldmodel.pose import Pose
    from hearth.worldmodel.containers import headroom
    from hearth.worldmodel.validate import all_parts
    place = world.get(place_id)
    # (part or None, surface): the place's own surfaces and its parts' (a drawer's floor, for
    # an object low enough to stay in the closed drawer)
    height = None
    options = [(None, s) for s in place.surfaces]
    for part in all_parts(place):
        for s in part.surfaces:
            if height is None:
                height = object_height(world, object_id)
            if height <= headroom(part, s):
                options.append((part, s))
    if not options:
        return False
    if level is not None:
        part, surf = next(o for o in options if o[1].id == level)
    else:
        part, surf = options[int(rng.integers(len(options)))]
    pid = part.id if part is not None else ""
    others = [c for c in place.children if c.id != object_id and c.part == pid
              and abs(c.pose.z - surf.pose.z) < 0.05]
    T = surf.pose.matrix()      # surface frame in the place's (or part's) frame
    obj = world.get(object_id)
    before = (world.parent(object_id).id, obj.pose, obj.relation, obj.part)
    for _ in range(60):
        u = rng.uniform(-0.35, 0.35) * surf.size_x
        v = rng.uniform(-0.35, 0.35) * surf.size_y
        x, y, z = (T @ np.array([u, v, 0.0, 1.0]))[:3]
        if all(math.hypot(x - o.pose.x, y - o.pose.y) > 0.15 for o in others):
            world.move_object(object_id, place_id,
                              Pose(float(x), float(y), float(z), 0.0, 0.0,
                                   float(rng.uniform(-math.pi, math.pi))),
                              relation=surf.relation, source=source, part=pid)
            if not _in_furniture(world, object_id, place_id):
                return True
    world.move_object(object_id, before[0], before[1], relation=before[2] or "on",
                      source=source, part=before[3] or "")
    return False


def _in_furniture(world, object_id: str, place_id: str) -> bool:
    """Whether the small object, where it stands, runs into its furniture's own geometry:
    above its bottom, a point of its surface within 4 mm of the furniture's (a remote on the
    floor "under" a pedestal table, sunk in the pedestal's foot; a surface's extent is a
    rectangle, the furniture's shape is not)."""
    from hearth.worldmodel.geometry import distance_to_object, small_object_meshes
    own = [np.asarray(lm.mesh.sample_points_uniformly(300).points)
           for lm in small_object_meshes(world, world.get(object_id)) if len(lm.mesh.triangles)]
    if not own:
        return False
    pts = np.vstack(own)
    pts = pts[pts[:, 2] > pts[:, 2].min() + 0.004]
    return bool((distance_to_object(world, place_id, pts) < 0.004).any())


def place_observably(truth, object_id: str, place_id: str, rng, fallback=(),
                     tries: int = 6) -> bool:
    """Put the object at a free spot of the place (``place_on``) that the robot can see:
    :func:`observable`. A spot no pose of the search shows is drawn again (``tries`` times at
    the place, then at each ``fallback`` place in turn); with none observable it stays at the
    last spot drawn. Returns whether the placement is observable."""
    for pid in [place_id, *[p for p in fallback if p != place_id]]:
        for _ in range(tries):
            if not place_on(truth, object_id, pid, rng):
                break
            if observable(truth, object_id):
                return True
    return False


def place_behind_sliding_door(truth, object_id: str, furniture: str, rng,
                              tries: int = 40) -> bool:
    """Put the object on a surface of ``furniture`` where one of its sliding doors (closed,
    as the home has them) stands in front of it and some pose of the search sees it once
    that door is slid aside (:func:`observable`). Returns whether such a spot was found
    (else the object stays at the last spot drawn)."""
    from hearth.worldmodel.containers import covering_door
    levels = [s.id for s in truth.get(furniture).surfaces if s.relation == "in"]
    for _ in range(tries):
        level = str(rng.choice(levels)) if levels else None
        if not place_on(truth, object_id, furniture, rng, level=level):
            continue
        if covering_door(truth, object_id) and _reachable_behind(truth, object_id) \
                and observable(truth, object_id):
            return True
    return False


def _reachable_behind(truth, object_id: str) -> bool:
    """Whether sliding the covering door aside uncovers the object (not where the closed
    doors overlap in the middle: covered by one or the other, whichever is open)."""
    from hearth.worldmodel.containers import covering_door, search_states
    states = search_states(truth, object_id)
    before = {pid: truth.get(pid).joint.state for pid in states}
    try:
        for pid, value in states.items():
            truth.set_joint_state(pid, value, source="scenario")
        return covering_door(truth, object_id) is None
    finally:
        for pid, value in before.items():
            truth.set_joint_state(pid, value, source="scenario")


def hidden_cases(world) -> list[tuple[str, str]]:
    """(object, hide) of the fetch cases a home adds to its drawn ones: every graspable object
    the home has in a drawer or behind a sliding door ("stay"), and for each furniture with
    sliding doors that holds none, its first fetch target put behind one of them
    ("sliding:FURNITURE"): the suite then holds every such object (issue 43)."""
    from hearth.worldmodel.validate import all_parts
    found = fetch_targets(world)
    out = [(o, "stay") for o in found if hidden_where(world, o)]
    holding = {world.parent(o).id for o, _ in out}
    for lo in world.large_objects():
        if lo.id in holding or not any(p.track for p in all_parts(lo)):
            continue
        if found and any(s.relation == "in" for s in lo.surfaces):
            out.append((found[0], f"sliding:{lo.id}"))
    return out


def observable(truth, object_id: str) -> bool:
    """Whether a search can see the object where it stands in the truth: some pose it can take
    (a parking position of its furniture or a next-best-view candidate, doors open) shows at
    least MIN_VISIBLE_PX pixels of it (``hearth.robot.scenario.visible_pixels``)."""
    from hearth.robot.scenario import visible_pixels
    return visible_pixels(truth, object_id)[0] >= MIN_VISIBLE_PX


def warm_up(belief, object_id: str, n: int, rng, places: list[tuple[str, float]],
            start=None) -> None:
    """Record ``n`` map-level searches: walk the learned search order (from ``start``, a base
    Pose; default: the believed place's first parking position) until the place the object
    is drawn at, counting a miss at each place before it."""
    from hearth.worldmodel.search import search_order
    if start is None:
        start = belief.parking_positions(belief.parent(object_id).id)[0][1]
    for _ in range(n):
        true_place = sample_place(places, rng)
        for p in search_order(belief, object_id, start):
            found = p.place == true_place
            belief.record_search(object_id, p.place, found, source="warm-up")
            if found:
                break


def _target(case: Case, world) -> str:
    if case.target:
        return case.target
    found = targets(world, case.mission)
    if not found:
        raise ValueError(f"{case.world}: nothing in this home for {case.mission}")
    return found[case.seed % len(found)]


def make_case_scenario(case: Case, world=None):
    """The case's Scenario (belief and truth worlds, start pose, localisation error, stuck
    knobs), the mission's parameters and the target."""
    from hearth.robot.scenario import make_scenario
    world = world if world is not None else resolve_world(case.world)
    target = _target(case, world)
    sc = make_scenario(world, case.seed, _config(case.mission))
    if case.models:
        from hearth.worldmodel.learned import apply_model_set
        apply_model_set(sc.belief, case.models)
    rng = np.random.default_rng(10_000 + case.seed)
    params: dict[str, Any] = {}
    if case.mission in FETCH:
        params = {"object": object_words(world, target), "learned": case.learned}
        places = object_places(world, target)
        if case.achievable and case.hide.startswith("sliding:"):
            place_behind_sliding_door(sc.truth, target, case.hide.split(":", 1)[1], rng)
        elif case.achievable and case.hide != "stay":
            place_observably(sc.truth, target, sample_place(places, rng), rng,
                             fallback=[p for p, _ in places] + [world.parent(target).id])
        elif case.achievable:       # "stay": where the home has it, whatever the scenario moved
            home = world.get(target)
            sc.truth.move_object(target, world.parent(target).id, home.pose,
                                 relation=home.relation, source="scenario", part=home.part)
        else:
            sc.truth.remove_small_object(target, source="scenario")
        if case.warmup:
            warm_up(sc.belief, target, case.warmup, np.random.default_rng(20_000 + case.seed),
                    places, start=sc.start_pose)
    elif case.mission == "turn_off_oven":
        params = {"oven": target}
        knobs = sorted(sc.truth.knobs(target), key=lambda k: k.id)
        on = [k for k in knobs if k.state != k.off]
        if not on:
            for k in rng.choice(knobs, size=int(rng.integers(1, min(2, len(knobs)) + 1)),
                                replace=False):
                sc.truth.set_knob_state(k.id, str(rng.choice([s.name for s in k.states
                                                               if s.name != k.off])))
            on = [k for k in knobs if k.state != k.off]
        if not case.achievable:
            sc.stuck_knobs = [str(rng.choice([k.id for k in on]))]
    elif case.mission == "refine_localisation":
        params = {"at": target}
    params.update(case.params)
    return sc, params, target


# ---------------------------------------------------------------------------------------
# Running one case
# ---------------------------------------------------------------------------------------
_PATH = re.compile(r"^\S+ failed: ")


def short_reason(reason: str) -> str:
    """The sentence of a mission's reason, without the failing node's path."""
    return _PATH.sub("", reason or "")


def categorise(outcome: str, reason: str) -> str:
    if outcome == "succeeded":
        return "succeeded"
    r = short_reason(reason)
    if re.search(r"\bno .+ at the \d+ places? searched", r):
        return "not_found"
    if r.startswith("I cannot"):
        return "cannot"
    return "other"


def _wrong_success(case: Case, target: str, sim, belief, residual: Optional[float]) -> bool:
    """Whether a mission that says it succeeded did not do what it says (truth in ``sim``)."""
    if sim is None:
        return False
    truth = sim.truth
    if case.mission == "fetch_object":
        return target not in getattr(sim, "handed_over", [target])
    if case.mission == "search_object":
        if target not in truth:
            return True
        found = belief.T_world(target)[:3, 3]
        return float(np.linalg.norm(found - truth.T_world(target)[:3, 3])) > FOUND_TOLERANCE_M
    if case.mission == "turn_off_oven":
        return any(k.state != k.off for k in truth.knobs(target))
    if case.mission == "refine_localisation":
        return residual is not None and residual > RESIDUAL_LIMIT_CM
    return False


def hidden_where(truth, object_id: str) -> str:
    """"drawer" when the object is in a drawer (a part of its furniture, by ``part``),
    "sliding" when a sliding door of a track stands in front of it, else ""."""
    if object_id not in truth:
        return ""
    from hearth.worldmodel.containers import covering_door
    if truth.get(object_id).part:
        return "drawer"
    return "sliding" if covering_door(truth, object_id) else ""


def run_case(case: Case, on_event: Optional[Callable] = None, world=None,
             record_to: Optional[str] = None, replay_from: Optional[str] = None) -> CaseResult:
    """Run one case on the simulated robot (simulated clock). ``record_to``: write every
    capture and action to a recording directory (hearth.robot.recording.RecordingRobot);
    ``replay_from``: run on a recording instead of the simulator (ReplayRobot), with the same
    belief map."""
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock
    from hearth.robot.recording import RecordingRobot, ReplayRobot
    from hearth.robot.simulated import SimulatedRobot

    world = world if world is not None else resolve_world(case.world)
    sc, params, target = make_case_scenario(case, world)
    clock = SimClock()
    sim = None
    if replay_from is not None:
        robot = ReplayRobot(replay_from, clock=clock)
    else:
        sim = SimulatedRobot(sc.truth, clock=clock, start_pose=sc.start_pose,
                             localisation_error=sc.localisation_error,
                             stuck_knobs=sc.stuck_knobs, locked=sc.locked, seed=case.seed)
        robot = sim
        if record_to is not None:
            robot = RecordingRobot(sim, record_to, info=dict(mission=case.mission,
                                                             seed=case.seed, params=params))
    belief = sc.belief
    where = hidden_where(sc.truth, target) if case.mission in FETCH else ""
    changes: list[str] = []
    belief.subscribe(lambda ch: changes.append(f"{ch.node} {ch.field}: {ch.old} -> {ch.new}")
                     if ch.field not in ("search",) else None)
    said: list[str] = []
    inner_say = robot.say

    def say(text):
        said.append(text)
        return inner_say(text)
    robot.say = say
    ex = Executive(world=belief, robot=robot, clock=clock, tick_hz=10.0,
                   runs_dir=case.runs_dir, background=False)
    if on_event is not None:
        ex.subscribe(on_event)
    t0 = time.perf_counter()
    handle = ex.submit(str(MISSIONS / f"{case.mission}.yaml"), **params)
    ex.run_until_idle(200_000)
    wall = time.perf_counter() - t0
    res = handle.result
    if record_to is not None:
        robot.writer.flush()
    cat = categorise(res.outcome, res.reason)
    correct = (cat == "succeeded") if case.achievable else (
        cat == ("not_found" if case.mission in FETCH else "cannot"))
    visited = len(res.outputs.get("searched") or []) if case.mission in FETCH else None
    residual = None
    reason = res.reason
    if case.mission == "refine_localisation" and sim is not None:
        err = sim.localisation_error()
        residual = round(math.hypot(err.x, err.y) * 100, 2)
    wrong = cat == "succeeded" and (not case.achievable
                                    or _wrong_success(case, target, sim, belief, residual))
    if wrong:
        correct = False
        if case.mission == "refine_localisation":
            reason = f"corrected, but still {residual:.1f} cm off"
        else:
            reason = "reported success, but the truth says otherwise"
    node = world.get(target) if target in world else None
    return CaseResult(mission=case.mission, seed=case.seed, achievable=case.achievable,
                      learned=case.learned, outcome=res.outcome, reason=short_reason(reason),
                      category=cat, correct=correct, sim_time_s=round(res.duration, 2),
                      wall_time_s=round(wall, 2), positions_visited=visited,
                      residual_cm=residual, said=said, map_changes=changes,
                      log_path=str(res.log_path) if res.log_path else None, world=case.world,
                      target=target, target_type=getattr(node, "type", "") or "",
                      wrong_success=wrong, where=where, drives=_drives(sim),
                      refused_drives=_refused_drives(sim), models=case.models)


# ---------------------------------------------------------------------------------------
# The suite and its summary
# ---------------------------------------------------------------------------------------
#: The search orders a fetch case runs with: the learned one and the fixed one from the map.
ORDERS = ("learned", "fixed")


def suite_cases(n: int, seed: int = 0, missions=NAMED, warmup: int = 20,
                unachievable_every: int = 4, worlds=("demo",), fetch_every_type: bool = True,
                orders=ORDERS, hidden: bool = True) -> list[Case]:
    """Cases per world and mission. Targets come from each world's map (:func:`targets`):
    fetch and search cases cover every kind of small object of the home (one case per type,
    at least ``n``), the oven cases cycle through its appliances with knobs, the localisation
    cases through its landmarks. Every ``unachievable_every``-th fetch or oven case is
    unachievable (object absent, knob stuck). Each achievable fetch case runs twice, with the
    learned and with the fixed search order, after ``warmup`` searches (``orders``: only
    those named; an unachievable case runs with the first). With ``hidden``, each home's
    fetch cases also hold every object in a drawer or behind a sliding door
    (:func:`hidden_cases`)."""
    orders = tuple(orders) or ORDERS
    if any(o not in ORDERS for o in orders):
        raise ValueError(f"search orders are {', '.join(ORDERS)}, not {orders!r}")
    cases = []
    for w in worlds:
        world = resolve_world(w)
        for m in missions:
            found = targets(world, m)
            if not found:
                continue
            count = n
            if m in FETCH and fetch_every_type:
                count = max(n, len({world.get(t).type for t in found}))
            for i in range(count):
                s = seed + i
                achievable = not (m in FETCH + ("turn_off_oven",) and unachievable_every
                                  and i % unachievable_every == unachievable_every - 1)
                target = found[i % len(found)]
                if m in FETCH:
                    for order in (orders if achievable else orders[:1]):
                        cases.append(Case(m, s, achievable, learned=order == "learned",
                                          warmup=warmup, world=w, target=target))
                else:
                    cases.append(Case(m, s, achievable, world=w, target=target))
            if m in FETCH and hidden:
                for i, (target, hide) in enumerate(hidden_cases(world)):
                    for order in orders:
                        cases.append(Case(m, seed + count + i, True, learned=order == "learned",
                                          warmup=warmup, world=w, target=target, hide=hide))
    return cases


def _drives(sim) -> list:
    """[path_m, straight_m] of each drive the simulated robot made (its action log)."""
    if sim is None:
        return []
    return [[e["path_m"], e["straight_m"]] for e in sim.log
            if e.get("action") == "navigate_to" and "path_m" in e]


def _refused_drives(sim) -> list:
    """The reasons of the drives the simulated robot refused (no path, outside the home)."""
    if sim is None:
        return []
    return [e["refused"] for e in sim.log
            if e.get("action") == "navigate_to" and e.get("refused")]


def _reason_kind(reason: str) -> str:
    """A refusal's reason with its coordinates and distances left out, so alike ones count
    together ("no path to (x, y): the goal (x, y) is inside wardrobe_1")."""
    reason = re.sub(r"\(-?[\d.]+, -?[\d.]+\)", "(x, y)", reason)
    return re.sub(r"-?\d+\.\d+ m\b", "d m", reason)


def navigation_summary(results: list[dict]) -> dict:
    """Path length against the straight line over every drive of 0.5 m or more:
    ``path_over_straight_median`` (and the 90th percentile), ``path_m_median``, ``drives``;
    ``refused_drives`` (goals the robot had no path to, each refused where it stood) and
    ``refused_reasons`` (their reasons, counted by kind)."""
    d = [r for res in results for r in (res.get("drives") or []) if r[1] >= 0.5]
    refused = [x for res in results for x in (res.get("refused_drives") or [])]
    kinds: dict = {}
    for x in refused:
        kinds[_reason_kind(x)] = kinds.get(_reason_kind(x), 0) + 1
    out = {"refused_drives": len(refused), "refused_reasons": kinds}
    if not d:
        return {"drives": 0, **out}
    ratio = np.array([p / s for p, s in d])
    return {**out, "drives": len(d),
            "path_over_straight_median": round(float(np.median(ratio)), 3),
            "path_over_straight_p90": round(float(np.percentile(ratio, 90)), 3),
            "path_m_median": round(float(np.median([p for p, _ in d])), 3),
            "straight_m_median": round(float(np.median([s for _, s in d])), 3)}


def _mean(xs) -> Optional[float]:
    xs = [x for x in xs if x is not None]
    return round(float(np.mean(xs)), 3) if xs else None


def _rate(xs) -> Optional[float]:
    xs = list(xs)
    return round(sum(xs) / len(xs), 3) if xs else None


def _mission_summary(rs: list[dict], m: str) -> dict:
    # the learned order's runs (a run of the fixed order alone: those)
    main = [r for r in rs if r["learned"]] or list(rs)
    ach = [r for r in main if r["achievable"]]
    una = [r for r in main if not r["achievable"]]
    d: dict[str, Any] = {
        "cases": len(main),
        "success_rate": _rate(r["outcome"] == "succeeded" and r["correct"] for r in ach),
        "unachievable": len(una),
        "unachievable_correct_rate": _rate(r["correct"] for r in una),
        "wrong_success": sum(bool(r.get("wrong_success")) for r in rs),
        "errors": sum(r["outcome"] == "error" for r in rs),
        "failure_reasons": dict(Counter(r["reason"] for r in rs if r["outcome"] != "succeeded"
                                        or not r["correct"])),
        "sim_time_s_mean": _mean(r["sim_time_s"] for r in main),
        "wall_time_s_mean": _mean(r["wall_time_s"] for r in main),
    }
    if m in FETCH:
        for learned, key in ((True, "learned"), (False, "fixed")):
            got = [r["positions_visited"] for r in rs if r["learned"] == learned
                   and r["achievable"] and r["outcome"] == "succeeded"]
            d[f"positions_visited_mean_{key}"] = _mean(got)
        fixed = [r for r in rs if not r["learned"] and r["achievable"]]
        d["success_rate_fixed_order"] = _rate(r["outcome"] == "succeeded" and r["correct"]
                                              for r in fixed)
        by_type: dict[str, list] = defaultdict(list)
        for r in ach:
            by_type[r.get("target_type") or "?"].append(r["outcome"] == "succeeded" and r["correct"])
        d["success_rate_by_object_type"] = {t: _rate(v) for t, v in sorted(by_type.items())}
        # where the object stood in truth (issue 43): in a drawer, behind a sliding door
        for where, key in (("drawer", "in_drawers"), ("sliding", "behind_sliding_doors")):
            got = [r for r in ach if r.get("where") == where]
            d[f"cases_{key}"] = len(got)
            d[f"success_rate_{key}"] = _rate(r["outcome"] == "succeeded" and r["correct"]
                                             for r in got)
            every = [r for r in rs if r["achievable"] and r.get("where") == where]
            d[f"success_rate_{key}_every_order"] = _rate(
                r["outcome"] == "succeeded" and r["correct"] for r in every)
    if m == "refine_localisation":
        d["residual_cm_mean"] = _mean(r["residual_cm"] for r in main)
        d["residual_cm_max"] = max((r["residual_cm"] for r in main
                                    if r["residual_cm"] is not None), default=None)
    return d


def summarise(results: list[dict]) -> dict:
    """Per mission, pooled over every world run: success_rate (achievable cases; fetch: the
    learned order), unachievable_correct_rate, wrong_success (count), failure_reasons
    (counts), sim/wall time means; fetch: positions_visited_mean with the learned and the
    fixed order (achievable runs that found the object) and success per object type;
    refine: residual error. Then ``generated`` (the same, generated homes only), ``demo``
    (the demo home only, when run), ``per_world`` (success per world and mission) and
    ``slowest`` (the five slowest cases by wall time)."""
    out: dict[str, Any] = {}
    # A case the engine could not deliver (hearth.executive.suite_worker.failure "engine") says nothing of
    # the mission: it is listed apart and left out of every figure below.
    out["engine_errors"] = [dict(world=r.get("world"), mission=r["mission"], seed=r["seed"],
                                 target=r.get("target"), reason=r["reason"])
                            for r in results if r.get("error") == "engine"]
    results = [r for r in results if r.get("error") != "engine"]
    missions = sorted({r["mission"] for r in results})
    for m in missions:
        out[m] = _mission_summary([r for r in results if r["mission"] == m], m)
    gen = [r for r in results if str(r.get("world", "demo")).startswith("home:")]
    if gen and len(gen) != len(results):
        out["generated"] = {m: _mission_summary([r for r in gen if r["mission"] == m], m)
                            for m in missions if any(r["mission"] == m for r in gen)}
    demo = [r for r in results if r.get("world", "demo") == "demo"]
    if demo and len(demo) != len(results):
        out["demo"] = {m: _mission_summary([r for r in demo if r["mission"] == m], m)
                       for m in missions if any(r["mission"] == m for r in demo)}
    per_world: dict[str, dict] = {}
    for w in sorted({r.get("world", "demo") for r in results}):
        rw = [r for r in results if r.get("world", "demo") == w and r["learned"]]
        per_world[w] = {m: _rate(r["correct"] for r in rw if r["mission"] == m)
                        for m in missions if any(r["mission"] == m for r in rw)}
    out["per_world"] = per_world
    out["wrong_success_total"] = sum(bool(r.get("wrong_success")) for r in results)
    out["navigation"] = navigation_summary(results)
    out["slowest"] = [dict(mission=r["mission"], world=r.get("world"), seed=r["seed"],
                           target=r.get("target"), wall_time_s=r["wall_time_s"],
                           outcome=r["outcome"])
                      for r in sorted(results, key=lambda r: -r["wall_time_s"])[:5]]
    return out
