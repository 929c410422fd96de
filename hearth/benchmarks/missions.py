"""`hearth bench missions --json [--homes N] [--world W] [--scenarios K] [--jobs J]`: the named
missions on generated homes and the demo home (executive/scenarios.py), in spawned worker
processes.

Worlds: by default the demo home and ``--homes`` generated homes (``home:SEED`` for seeds
``--seed`` .. ``--seed + N - 1``, made by worldmodel.homegen and cached); ``--world W`` (a
world file, repeatable) runs on those instead; ``--no-demo`` leaves the demo home out.
Per world and mission, ``--scenarios`` cases (fetch: at least one per kind of small object
of the home), targets taken from the map.

Prints one JSON object. Per mission, pooled over every world run: ``success_rate``
(achievable cases), ``unachievable_correct_rate`` (object absent / knob stuck ending with
"no ... at the N places searched" / "I cannot ..."), ``wrong_success`` (said it succeeded
and did not: a knob left on, an object not where it was reported, a residual over 2 cm after
"corrected"), ``failure_reasons``, ``sim_time_s_mean``, ``wall_time_s_mean``; fetch:
``positions_visited_mean_learned`` / ``_fixed`` (after the warm-up searches) and
``success_rate_by_object_type``; localisation: the residual error. Then the same per mission
for the generated homes alone (``generated``) and the demo home alone (``demo``),
``per_world`` success rates, and the ``slowest`` cases. Wall times are inflated when other
work shares the CPU.

``--verbose`` (or ``HEARTH_BENCH_VERBOSE=1``) prints one line per case on stderr as it
finishes; ``--missions`` picks missions; ``--warmup`` sets the warm-up searches.
"""
from __future__ import annotations

import os
import sys
import time


def add_arguments(parser) -> None:
    parser.add_argument("--missions", default="fetch_object,turn_off_oven,refine_localisation",
                        help="comma-separated missions (default: the three named ones)")
    parser.add_argument("--warmup", type=int, default=20,
                        help="map-level warm-up searches before each fetch case (default 20)")
    parser.add_argument("--homes", type=int, default=None,
                        help="generated homes to run on (default 6; 2 with --quick)")
    parser.add_argument("--world", action="append", default=None, metavar="WORLD",
                        help="a world file to run on instead of generated homes (repeatable)")
    parser.add_argument("--no-demo", action="store_true", help="leave the demo home out")
    parser.add_argument("--verbose", action="store_true", help="per-case lines on stderr")


def worlds_of(args) -> list[str]:
    out = [] if getattr(args, "no_demo", False) else ["demo"]
    if getattr(args, "world", None):
        return out + list(args.world)
    homes = args.homes if getattr(args, "homes", None) is not None else (2 if args.quick else 6)
    return out + [f"home:{args.seed + i}" for i in range(max(0, int(homes)))]


def run(args) -> dict:
    from executive.scenarios import run_suite, suite_cases, summarise

    n = args.scenarios or (2 if args.quick else 4)
    missions = tuple(m.strip() for m in getattr(args, "missions",
                     "fetch_object,turn_off_oven,refine_localisation").split(",") if m.strip())
    worlds = worlds_of(args)
    cases = suite_cases(n, seed=args.seed, missions=missions,
                        warmup=getattr(args, "warmup", 20), worlds=worlds)
    verbose = getattr(args, "verbose", False) or bool(os.environ.get("HEARTH_BENCH_VERBOSE"))
    done = [0]

    def progress(r):
        done[0] += 1
        if verbose:
            print(f"[{done[0]}/{len(cases)}] {r['world']} {r['mission']} {r['target']} seed "
                  f"{r['seed']} {'learned' if r['learned'] else 'fixed'}"
                  f"{'' if r['achievable'] else ' (unachievable)'}: {r['outcome']} "
                  f"({r['reason']}) {r['sim_time_s']} s sim, {r['wall_time_s']} s wall"
                  + (" WRONG SUCCESS" if r.get("wrong_success") else ""),
                  file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    results = run_suite(cases, jobs=max(1, int(args.jobs or 1)), progress=progress)
    wall = time.perf_counter() - t0
    out = {"scenarios_per_mission": n, "jobs": int(args.jobs or 1), "seed": args.seed,
           "worlds": worlds, "warmup_searches": getattr(args, "warmup", 20),
           "cases_run": len(results), "total_wall_s": round(wall, 1),
           "scenarios_per_s": round(len(results) / wall, 3) if wall > 0 else None,
           "load_average": [round(x, 2) for x in os.getloadavg()]}
    out.update(summarise(results))
    return out
