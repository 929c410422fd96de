"""The scenario suite: the named missions on seeded simulated homes, in parallel processes.

A :class:`Case` names a mission, a seed and whether its goal can be reached. From the seed,
:func:`make_case_scenario` perturbs the demo home with ``robot.scenario.make_scenario`` (a
config per mission) and then sets up what the mission is about:

- ``fetch_object`` / ``search_object``: the blue cup is put, in truth, on the side table
  (60 %), where the map believes it (kitchen table, 25 %) or on the bathroom counter (15 %);
  unachievable: it is not in the home at all. Expected: "succeeded", or a failure whose
  reason says "no blue cup at the N places searched".
- ``turn_off_oven``: one or two oven knobs are on in truth; unachievable: one of them is stuck.
  Expected: "succeeded", or "I cannot turn off oven knob N ...".
- ``refine_localisation``: the scenario's localisation error (up to 12 cm, 5 degrees) at one
  of the kitchen's landmarks. Expected: "succeeded" with the residual error under 2 cm.

``warmup`` learned searches come first for fetch cases: the map records 20 searches (by
default) drawn from the same placement distribution, walking the learned search order until
the object's true place, as ``RecordSearch`` would (map-level: no rendering), so the run can
compare the learned order (``learned=True``) with the fixed order from the map's prior.

:func:`run_suite` runs cases in worker processes with the **spawn** start method: open3d's
OpenMP thread pool deadlocks in forked children (open3d issues #1552, #6096, #7133).
"""
from __future__ import annotations

import math
import multiprocessing
import re
import time
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Optional

import numpy as np
from hearth import demo_world_path, missions_dir

DEMO_WORLD = demo_world_path()
MISSIONS = missions_dir()

#: Where the blue cup turns up in truth, and how often (fetch and search cases).
CUP_PLACES = (("side_table", 0.60), ("kitchen_table", 0.25), ("bathroom_counter", 0.15))
#: Landmarks to refine the localisation at (refine_localisation cases).
LANDMARKS = ("cupboard", "oven", "fridge", "drawer_unit")
TARGET = "blue_cup"


@dataclass(frozen=True)
class Case:
    mission: str                 # fetch_object | search_object | turn_off_oven | refine_localisation
    seed: int
    achievable: bool = True
    learned: bool = True
    warmup: int = 0
    runs_dir: Optional[str] = None
    params: dict = field(default_factory=dict)     # extra mission parameters


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


# ---------------------------------------------------------------------------------------
# Scenarios
# ---------------------------------------------------------------------------------------
def _config(mission: str):
    from hearth.robot.scenario import ScenarioConfig
    if mission in ("fetch_object", "search_object"):
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


def place_on(world, object_id: str, place_id: str, rng, source: str = "scenario") -> bool:
    """Move a small object onto a free spot of a place's first surface (world changed)."""
    from worldmodel.pose import Pose
    place = world.get(place_id)
    surf = place.surfaces[0]
    others = [c for c in place.children if c.id != object_id]
    for _ in range(60):
        x = surf.pose.x + rng.uniform(-0.35, 0.35) * surf.size_x
        y = surf.pose.y + rng.uniform(-0.35, 0.35) * surf.size_y
        if all(math.hypot(x - o.pose.x, y - o.pose.y) > 0.15 for o in others):
            world.move_object(object_id, place_id,
                              Pose(x, y, surf.pose.z, 0.0, 0.0, float(rng.uniform(-math.pi, math.pi))),
                              relation=surf.relation, source=source)
            return True
    return False


def sample_cup_place(rng) -> str:
    names = [p for p, _ in CUP_PLACES]
    probs = np.array([w for _, w in CUP_PLACES])
    return str(rng.choice(names, p=probs / probs.sum()))


def warm_up(belief, object_id: str, n: int, rng) -> None:
    """Record ``n`` map-level searches: walk the learned search order until the place the
    object is drawn at (CUP_PLACES), counting a miss at each place before it."""
    from worldmodel.pose import Pose
    from worldmodel.search import search_order
    start = belief.parking_positions("kitchen_table")[0][1]
    for _ in range(n):
        true_place = sample_cup_place(rng)
        for p in search_order(belief, object_id, Pose.planar(start.x, start.y, start.yaw)):
            found = p.place == true_place
            belief.record_search(object_id, p.place, found, source="warm-up")
            if found:
                break


def make_case_scenario(case: Case, world=None):
    """The case's Scenario (belief and truth worlds, start pose, localisation error, stuck
    knobs) and the mission's parameters."""
    from hearth.robot.scenario import make_scenario
    from worldmodel import load_world
    world = world or load_world(DEMO_WORLD)
    sc = make_scenario(world, case.seed, _config(case.mission))
    rng = np.random.default_rng(10_000 + case.seed)
    params: dict[str, Any] = {}
    if case.mission in ("fetch_object", "search_object"):
        params = {"object": "blue cup", "learned": case.learned}
        # The scenario may have moved the cup: belief and truth start from the map's place.
        if case.achievable:
            place_on(sc.truth, TARGET, sample_cup_place(rng), rng)
        else:
            sc.truth.remove_small_object(TARGET, source="scenario")
        if case.warmup:
            warm_up(sc.belief, TARGET, case.warmup, np.random.default_rng(20_000 + case.seed))
    elif case.mission == "turn_off_oven":
        knobs = sorted(sc.truth.knobs("oven"), key=lambda k: k.id)
        on = [k for k in knobs if k.state != k.off]
        if not on:
            for k in rng.choice(knobs, size=int(rng.integers(1, 3)), replace=False):
                sc.truth.set_knob_state(k.id, str(rng.choice([s.name for s in k.states
                                                               if s.name != k.off])))
            on = [k for k in knobs if k.state != k.off]
        if not case.achievable:
            sc.stuck_knobs = [str(rng.choice([k.id for k in on]))]
    elif case.mission == "refine_localisation":
        params = {"at": LANDMARKS[case.seed % len(LANDMARKS)]}
    params.update(case.params)
    return sc, params


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


def run_case(case: Case, on_event: Optional[Callable] = None, world=None,
             record_to: Optional[str] = None, replay_from: Optional[str] = None) -> CaseResult:
    """Run one case on the simulated robot (simulated clock). ``record_to``: write every
    capture and action to a recording directory (robot.recording.RecordingRobot);
    ``replay_from``: run on a recording instead of the simulator (robot.recording.ReplayRobot),
    with the same belief map."""
    from executive.executive import Executive
    from hearth.robot.clock import SimClock
    from hearth.robot.recording import RecordingRobot, ReplayRobot
    from hearth.robot.simulated import SimulatedRobot

    sc, params = make_case_scenario(case, world)
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
        cat == ("not_found" if case.mission in ("fetch_object", "search_object") else "cannot"))
    visited = None
    if case.mission in ("fetch_object", "search_object"):
        visited = len(res.outputs.get("searched") or [])
    residual = None
    if case.mission == "refine_localisation" and sim is not None:
        err = sim.localisation_error()
        residual = round(math.hypot(err.x, err.y) * 100, 2)
        if cat == "succeeded" and residual > 2.0:
            correct = False
            cat = "other"
            res_reason = f"corrected, but still {residual:.1f} cm off"
        else:
            res_reason = res.reason
    else:
        res_reason = res.reason
    return CaseResult(mission=case.mission, seed=case.seed, achievable=case.achievable,
                      learned=case.learned, outcome=res.outcome, reason=short_reason(res_reason),
                      category=cat, correct=correct, sim_time_s=round(res.duration, 2),
                      wall_time_s=round(wall, 2), positions_visited=visited,
                      residual_cm=residual, said=said, map_changes=changes,
                      log_path=str(res.log_path) if res.log_path else None)


def _worker(case_dict: dict) -> dict:
    # Keep each worker's numeric libraries on one thread: the workers are the parallelism.
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(1)
    except ImportError:  # pragma: no cover
        pass
    try:
        import open3d as o3d
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    except ImportError:  # pragma: no cover
        pass
    try:
        return asdict(run_case(Case(**case_dict)))
    except Exception as err:  # noqa: BLE001 - one broken case must not lose the others
        c = Case(**case_dict)
        return asdict(CaseResult(mission=c.mission, seed=c.seed, achievable=c.achievable,
                                 learned=c.learned, outcome="error",
                                 reason=f"{type(err).__name__}: {err}", category="other",
                                 correct=False, sim_time_s=0.0, wall_time_s=0.0))


def run_suite(cases: list[Case], jobs: int = 1,
              progress: Optional[Callable[[dict], None]] = None) -> list[dict]:
    """Run the cases, ``jobs`` at a time in spawned worker processes (1: in this process)."""
    dicts = [asdict(c) for c in cases]
    out = []
    if jobs <= 1:
        for d in dicts:
            out.append(_worker(d))
            if progress:
                progress(out[-1])
        return out
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(processes=jobs, maxtasksperchild=None) as pool:
        for r in pool.imap(_worker, dicts):
            out.append(r)
            if progress:
                progress(r)
    return out


# ---------------------------------------------------------------------------------------
# The suite and its summary
# ---------------------------------------------------------------------------------------
def suite_cases(n: int, seed: int = 0, missions=("fetch_object", "turn_off_oven",
                                                 "refine_localisation"),
                warmup: int = 20, unachievable_every: int = 4) -> list[Case]:
    """``n`` seeded cases per mission; every ``unachievable_every``-th fetch or oven case is
    unachievable (object absent, knob stuck). Each achievable fetch case runs twice, with
    the learned and with the fixed search order, after ``warmup`` searches."""
    cases = []
    for m in missions:
        for i in range(n):
            s = seed + i
            achievable = not (m in ("fetch_object", "search_object", "turn_off_oven")
                              and unachievable_every and i % unachievable_every
                              == unachievable_every - 1)
            if m in ("fetch_object", "search_object"):
                cases.append(Case(m, s, achievable, learned=True, warmup=warmup))
                if achievable:
                    cases.append(Case(m, s, achievable, learned=False, warmup=warmup))
            else:
                cases.append(Case(m, s, achievable))
    return cases


def _mean(xs) -> Optional[float]:
    xs = [x for x in xs if x is not None]
    return round(float(np.mean(xs)), 3) if xs else None


def summarise(results: list[dict]) -> dict:
    """Per mission: success_rate (achievable cases; fetch: learned order),
    unachievable_correct_rate, failure_reasons (counts), sim/wall time means; fetch:
    positions_visited_mean with the learned and the fixed order (achievable runs that found
    the object); refine: residual error."""
    out: dict[str, Any] = {}
    for m in sorted({r["mission"] for r in results}):
        rs = [r for r in results if r["mission"] == m]
        main = [r for r in rs if r["learned"]]
        ach = [r for r in main if r["achievable"]]
        una = [r for r in main if not r["achievable"]]
        d: dict[str, Any] = {
            "cases": len(main),
            "success_rate": round(sum(r["outcome"] == "succeeded" and r["correct"]
                                      for r in ach) / len(ach), 3) if ach else None,
            "unachievable": len(una),
            "unachievable_correct_rate": round(sum(r["correct"] for r in una) / len(una), 3)
            if una else None,
            "failure_reasons": dict(Counter(r["reason"] for r in rs
                                            if r["outcome"] != "succeeded")),
            "sim_time_s_mean": _mean(r["sim_time_s"] for r in main),
            "wall_time_s_mean": _mean(r["wall_time_s"] for r in main),
        }
        if m in ("fetch_object", "search_object"):
            for learned, key in ((True, "learned"), (False, "fixed")):
                got = [r["positions_visited"] for r in rs if r["learned"] == learned
                       and r["achievable"] and r["outcome"] == "succeeded"]
                d[f"positions_visited_mean_{key}"] = _mean(got)
            fixed = [r for r in rs if not r["learned"]]
            d["success_rate_fixed_order"] = round(sum(r["outcome"] == "succeeded" for r in fixed)
                                                  / len(fixed), 3) if fixed else None
        if m == "refine_localisation":
            d["residual_cm_mean"] = _mean(r["residual_cm"] for r in main)
            d["residual_cm_max"] = max((r["residual_cm"] for r in main
                                        if r["residual_cm"] is not None), default=None)
        out[m] = d
    return out
