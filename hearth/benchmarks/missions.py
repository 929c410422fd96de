"""`hearth bench missions --json [--homes N] [--world W] [--scenarios K] [--jobs J]
[--engine local|ray|local,ray] [--address ADDR] [--timeout S]`: the named missions on
generated homes and the demo home (hearth/executive/scenarios.py), on an engine of
hearth/executive/suite.py (the same as `hearth suite`): spawned worker processes here, or one Ray
task per scenario.

Worlds: by default the demo home and ``--homes`` generated homes (``home:SEED`` for seeds
``--seed`` .. ``--seed + N - 1``, made by hearth.worldmodel.homegen and cached); ``--world W`` (a
world file, repeatable) runs on those instead; ``--no-demo`` leaves the demo home out.
Per world and mission, ``--scenarios`` cases (fetch: at least one per kind of small object
of the home), targets taken from the map.

Prints one JSON object. Per mission, pooled over every world run: ``success_rate``
(achievable cases), ``unachievable_correct_rate`` (object absent / knob stuck ending with
"no ... at the N places searched" / "I cannot ..."), ``wrong_success`` (said it succeeded
and did not: a knob left on, an object not where it was reported, a residual over 2 cm after
"corrected"), ``failure_reasons``, ``sim_time_s_mean``, ``wall_time_s_mean``; fetch:
``positions_visited_mean_learned`` / ``_fixed`` (after the warm-up searches) and
``success_rate_by_object_type``, ``cases_in_drawers`` / ``cases_behind_sliding_doors``
(achievable cases of the main order whose object stood in a drawer / behind a sliding door
of a track, in truth) with their ``success_rate_in_drawers`` /
``success_rate_behind_sliding_doors`` (``..._every_order``: the runs of both orders);
localisation: the residual error. ``--order fixed`` runs the fetch cases with the fixed
search order only (its figures are then the main ones), ``--order learned`` with the
learned one only, ``both`` (default) each achievable case twice. Then the same per mission
for the generated homes alone (``generated``) and the demo home alone (``demo``),
``per_world`` success rates, the ``slowest`` cases, and ``navigation``: the simulated
robot's drives of 0.5 m or more (it follows paths on the map's occupancy grid,
docs/navigation.md), ``path_over_straight_median`` / ``_p90`` (path length over the
straight line), ``path_m_median``, ``straight_m_median``, ``drives``, and the goals it had
no path to, ``refused_drives`` with ``refused_reasons`` counted by kind. Wall times are inflated when other
work shares the CPU.

``--learned-models`` (issue 42): each fetch case with the learned search order runs once more
with the belief's small objects given the models learned from views
(hearth.benchmarks.learning.model_set_for, cached per world; the truth the simulator renders
keeps the drawn ones). The figures above are the drawn models'; ``learned_models`` per fetch
mission has the same figures with the learned models, ``drawn_success_rate`` on the same
cases and ``success_ratio`` (target >= 0.95), and ``model_sets``.

``--verbose`` (or ``HEARTH_BENCH_VERBOSE=1``) prints one line per case on stderr as it
finishes; ``--missions`` picks missions; ``--warmup`` sets the warm-up searches.

Engines: ``engine``, ``scenarios_per_s`` (cases over the wall time, the engine's start
included: a Ray start costs seconds) and ``errors_by_kind`` (exception / timeout / crashed,
the mission's own; engine: a case the engine could not deliver, such as a world that
arrived incomplete on a worker). Engine errors are listed in ``engine_errors``, left out of
every mission figure, and make the command exit 1.
``--engine local,ray`` runs the same cases on both, one after the other: the summary is the
first engine's, and ``engines`` gives each one's ``scenarios_per_s``, ``total_wall_s`` and
``startup_s`` (until its first result), ``ray_over_local`` the ratio of their wall times, and
``same_results`` whether every case gave the same result on both (all but
``hearth.executive.suite_worker.VARYING``), with the keys of those that did not in ``differing``.
"""
from __future__ import annotations

import os
import sys
import time


def add_arguments(parser) -> None:
    from hearth.executive.argtypes import suite_missions
    parser.add_argument("--missions", type=suite_missions,
                        default=("fetch_object", "turn_off_oven", "refine_localisation"),
                        help="comma-separated missions (default: the three named ones)")
    parser.add_argument("--order", choices=("learned", "fixed", "both"), default="both",
                        help="search order of the fetch cases: the learned one, the fixed one "
                             "from the map, or both (default; each achievable case runs twice)")
    parser.add_argument("--warmup", type=int, default=20,
                        help="map-level warm-up searches before each fetch case (default 20)")
    parser.add_argument("--homes", type=int, default=None,
                        help="generated homes to run on (default 6; 2 with --quick)")
    parser.add_argument("--world", action="append", default=None, metavar="WORLD",
                        help="a world file to run on instead of generated homes (repeatable)")
    parser.add_argument("--no-demo", action="store_true", help="leave the demo home out")
    parser.add_argument("--verbose", action="store_true", help="per-case lines on stderr")
    parser.add_argument("--learned-models", action="store_true",
                        help="run every fetch case again with the belief's small objects "
                             "learned from views (hearth bench learning's pipeline) in place "
                             "of their drawn models: figures under learned_models")
    from hearth.robot.mujoco_render import add_renderer_argument
    add_renderer_argument(parser)       # the simulated robot's frames ($HEARTH_SIM_RENDERER)
    from hearth.executive.suite import add_engine_arguments
    add_engine_arguments(parser, several=True)


def worlds_of(args) -> list[str]:
    out = [] if getattr(args, "no_demo", False) else ["demo"]
    if getattr(args, "world", None):
        return out + list(args.world)
    homes = args.homes if getattr(args, "homes", None) is not None else (2 if args.quick else 6)
    return out + [f"home:{args.seed + i}" for i in range(max(0, int(homes)))]


def run(args) -> dict:
    from hearth.executive import suite_worker
    from hearth.executive.scenarios import suite_cases, summarise

    n = args.scenarios or (2 if args.quick else 4)
    missions = getattr(args, "missions", None) or ("fetch_object", "turn_off_oven",
                                                   "refine_localisation")
    worlds = worlds_of(args)
    renderer = getattr(args, "renderer", None) or "hearth"
    os.environ["HEARTH_SIM_RENDERER"] = renderer      # the workers' simulated robots inherit it
    order = getattr(args, "order", None) or "both"
    orders = ("learned", "fixed") if order == "both" else (order,)
    cases = suite_cases(n, seed=args.seed, missions=missions,
                        warmup=getattr(args, "warmup", 20), worlds=worlds, orders=orders)
    learned_sets = {}
    if getattr(args, "learned_models", False):
        cases = cases + learned_cases(cases, args.seed, learned_sets,
                                      None if getattr(args, "no_progress", False) else
                                      (lambda s: print(f"[missions] learning {s}", file=sys.stderr,
                                                       flush=True)))
    verbose = getattr(args, "verbose", False) or bool(os.environ.get("HEARTH_BENCH_VERBOSE"))
    engines = getattr(args, "engine", None) or ["local"]
    engines = [engines] if isinstance(engines, str) else list(engines)
    jobs = max(1, int(args.jobs or 1))
    runs = {}
    for name in engines:
        runs[name] = _run_on(name, cases, jobs, args, verbose)
    first = runs[engines[0]]
    results = first["results"]
    out = {"scenarios_per_mission": n, "jobs": jobs, "seed": args.seed,
           "worlds": worlds, "warmup_searches": getattr(args, "warmup", 20),
           "order": order,
           "cases_run": len(results), "engine": engines[0], "renderer": renderer,
           "total_wall_s": first["total_wall_s"], "scenarios_per_s": first["scenarios_per_s"],
           "errors_by_kind": first["errors_by_kind"],
           "load_average": [round(x, 2) for x in os.getloadavg()]}
    if len(engines) > 1:
        out["engines"] = {k: {f: v[f] for f in ("scenarios_per_s", "total_wall_s", "startup_s",
                                                "describe", "errors_by_kind")}
                          for k, v in runs.items()}
        if "local" in runs and "ray" in runs:
            out["ray_over_local"] = round(runs["ray"]["total_wall_s"]
                                          / runs["local"]["total_wall_s"], 3)
        a, b = (runs[e]["results"] for e in engines[:2])
        differing = [x["key"] for x, y in zip(a, b)
                     if suite_worker.comparable(x) != suite_worker.comparable(y)]
        out["same_results"] = not differing
        out["differing"] = differing
    drawn = [r for r in results if not r.get("models")]
    out.update(summarise(drawn))
    if learned_sets:
        out["learned_models"] = learned_figures(results, learned_sets)
    return out


def learned_cases(cases, seed: int, sets: dict, progress=None) -> list:
    """The fetch cases again, each with its world's model set (learned once per world and
    cached: hearth.benchmarks.learning.model_set_for); ``sets`` gets world -> directory. Only
    the cases with the learned search order (those ``success_rate`` counts): the fixed order's
    twins would say nothing more of the models."""
    from dataclasses import replace

    from hearth.benchmarks.learning import model_set_for
    from hearth.executive.scenarios import FETCH
    out = []
    for c in cases:
        if c.mission not in FETCH or not c.learned:
            continue
        if c.world not in sets:
            sets[c.world] = str(model_set_for(c.world, seed, progress=progress))
        out.append(replace(c, models=sets[c.world]))
    return out


def learned_figures(results: list[dict], sets: dict) -> dict:
    """Per fetch mission, the summary of the cases run with learned models, and
    ``success_ratio``: their success rate over the drawn models' on the same cases (issue
    42 asks >= 0.95); ``model_sets``: per world, its directory, the objects learned and
    those that could not be (and why)."""
    from hearth.executive.scenarios import summarise
    from hearth.worldmodel.learned import read_model_set
    learned = [r for r in results if r.get("models")]
    drawn_keys = {(r["world"], r["mission"], r["seed"], r["target"], r["learned"])
                  for r in learned}
    drawn = [r for r in results if not r.get("models")
             and (r["world"], r["mission"], r["seed"], r["target"], r["learned"]) in drawn_keys]
    a, b = summarise(learned), summarise(drawn)
    out = {}
    for m in sorted({r["mission"] for r in learned}):
        keep = ("cases", "success_rate", "unachievable_correct_rate", "wrong_success",
                "failure_reasons", "success_rate_by_object_type", "positions_visited_mean_learned")
        out[m] = {k: a[m][k] for k in keep if k in a[m]}
        sa, sb = a[m].get("success_rate"), b.get(m, {}).get("success_rate")
        out[m]["drawn_success_rate"] = sb
        out[m]["success_ratio"] = round(sa / sb, 4) if sa is not None and sb else None
    out["model_sets"] = {}
    for w, d in sets.items():
        m = read_model_set(d)
        out["model_sets"][w] = dict(directory=d, learned=len(m["objects"]),
                                    not_learned=m["not_learned"])
    return out


def incomplete(result: dict) -> str | None:
    """Why the figures leave cases out: cases an engine could not deliver
    (``engine_errors``: a world that arrived incomplete on a worker)."""
    bad = {k: (v.get("errors_by_kind") or {}).get("engine", 0)
           for k, v in result.get("engines", {"": result}).items()}
    if any(bad.values()):
        return ("the engine could not deliver " + ", ".join(
            f"{n} case(s){' on ' + k if k else ''}" for k, n in bad.items() if n)
            + "; they are left out of the figures (engine_errors)")
    return None


def _run_on(name: str, cases, jobs: int, args, verbose: bool) -> dict:
    from collections import Counter

    from hearth.executive import suite
    engine = suite.make_engine(name, jobs=jobs, address=getattr(args, "address", None),
                               timeout=getattr(args, "timeout", suite.DEFAULT_TIMEOUT_S))
    done = [0]
    first = [None]
    t0 = time.perf_counter()

    def progress(r):
        done[0] += 1
        if first[0] is None:
            first[0] = time.perf_counter() - t0
        if verbose:
            print(f"[{name} {done[0]}/{len(cases)}] {r['world']} {r['mission']} {r['target']} "
                  f"seed {r['seed']} {'learned' if r['learned'] else 'fixed'}"
                  f"{'' if r['achievable'] else ' (unachievable)'}: {r['outcome']} "
                  f"({r['reason']}) {r['sim_time_s']} s sim, {r['wall_time_s']} s wall"
                  + (" WRONG SUCCESS" if r.get("wrong_success") else ""),
                  file=sys.stderr, flush=True)

    got = suite.run_cases(cases, engine, on_result=progress,
                          log=lambda s: print(s, file=sys.stderr, flush=True))
    wall = time.perf_counter() - t0
    results = [got[suite.case_key(c)] for c in cases]
    return {"results": results, "total_wall_s": round(wall, 1),
            "scenarios_per_s": round(len(results) / wall, 3) if wall > 0 else None,
            "startup_s": round(first[0], 1) if first[0] is not None else None,
            "describe": engine.describe(),
            "errors_by_kind": dict(Counter(r["error"] for r in results if r.get("error")))}
