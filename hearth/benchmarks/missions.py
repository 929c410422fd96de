"""`hearth bench missions --json --scenarios N [--jobs J]`: the named missions on N seeded
simulated homes each (executive/scenarios.py), in spawned worker processes.

Prints one JSON object: per mission ``success_rate`` (achievable cases), ``failure_reasons``
(counts of the sentences the missions ended with), ``unachievable_correct_rate`` (object
absent / knob stuck ending with "no ... at the N places searched" / "I cannot ..."),
``sim_time_s_mean``, ``wall_time_s_mean``; for fetch ``positions_visited_mean_learned`` and
``positions_visited_mean_fixed`` (after 20 warm-up searches); for localisation the residual
error. Wall times are inflated when other work shares the CPU.

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
    parser.add_argument("--verbose", action="store_true", help="per-case lines on stderr")


def run(args) -> dict:
    from executive.scenarios import run_suite, suite_cases, summarise

    n = args.scenarios or (2 if args.quick else 8)
    missions = tuple(m.strip() for m in getattr(args, "missions",
                     "fetch_object,turn_off_oven,refine_localisation").split(",") if m.strip())
    cases = suite_cases(n, seed=args.seed, missions=missions,
                        warmup=getattr(args, "warmup", 20))
    verbose = getattr(args, "verbose", False) or bool(os.environ.get("HEARTH_BENCH_VERBOSE"))

    def progress(r):
        if verbose:
            print(f"{r['mission']} seed {r['seed']} {'learned' if r['learned'] else 'fixed'}"
                  f"{'' if r['achievable'] else ' (unachievable)'}: {r['outcome']} "
                  f"({r['reason']}) {r['sim_time_s']} s sim, {r['wall_time_s']} s wall, "
                  f"visited {r['positions_visited']}", file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    results = run_suite(cases, jobs=max(1, int(args.jobs or 1)), progress=progress)
    out = {"scenarios_per_mission": n, "jobs": int(args.jobs or 1), "seed": args.seed,
           "warmup_searches": getattr(args, "warmup", 20), "cases_run": len(results),
           "total_wall_s": round(time.perf_counter() - t0, 1),
           "load_average": [round(x, 2) for x in os.getloadavg()]}
    out.update(summarise(results))
    return out
