"""`hearth suite`: the scenario suite on generated homes, on this machine or on Ray, with a
report a person reads (text, JSON, a PNG grid) and a results file that a later run resumes.

`hearth bench missions` runs the same cases on the same engines and prints only the JSON
figures; this command is the one to run after changing a skill (docs/suite.md).
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from hearth.cli.util import integer_in, seed, suite_missions


def register(sub) -> None:
    from hearth.executive.suite import add_engine_arguments
    p = sub.add_parser(
        "suite", help="run the mission suite on generated homes (locally or on Ray) and report",
        description="Run the named missions on the demo home and generated homes, several "
                    "seeded scenarios each, on worker processes here (--engine local) or as "
                    "Ray tasks (--engine ray). Results are appended to DIR/results.jsonl as "
                    "they arrive (--resume continues an interrupted suite); the report goes "
                    "to stdout, DIR/report.json and DIR/summary.png. Exit status 1 when a "
                    "scenario raised, hung or crashed its worker.")
    p.add_argument("--homes", type=integer_in(0, 100_000, "--homes"), default=6,
                   help="generated homes home:SEED for seeds --seed .. --seed+N-1 (default 6)")
    p.add_argument("--world", action="append", default=None, metavar="WORLD",
                   help="a world file to run on instead of generated homes (repeatable)")
    p.add_argument("--no-demo", action="store_true", help="leave the demo home out")
    p.add_argument("--missions", type=suite_missions,
                   default=("fetch_object", "turn_off_oven", "refine_localisation"),
                   help="comma-separated missions (default: the three named ones)")
    p.add_argument("--scenarios", type=integer_in(1, 100_000, "--scenarios"), default=4,
                   help="scenarios per home and mission (fetch: at least one per kind of "
                        "object; default 4)")
    p.add_argument("--seed", type=seed, default=0, help="base seed of homes and scenarios")
    p.add_argument("--warmup", type=integer_in(0, 10_000, "--warmup"), default=20,
                   help="map-level warm-up searches before each fetch case (default 20)")
    p.add_argument("--jobs", type=integer_in(1, 1024, "--jobs"), default=os.cpu_count() or 1,
                   help="worker processes (local), or CPUs of the local Ray instance "
                        "(default: this machine's CPUs)")
    add_engine_arguments(p)
    p.add_argument("--out", default="out/suite", metavar="DIR",
                   help="where results.jsonl, report.json and summary.png go (default "
                        "out/suite)")
    p.add_argument("--resume", action="store_true",
                   help="keep the results in DIR/results.jsonl and run only the rest")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.executive import suite, suite_report
    from hearth.executive.scenarios import suite_cases
    from hearth.benchmarks.missions import worlds_of

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        print(f"{out}: not a directory", file=sys.stderr)
        return 2
    args.quick = False
    worlds = worlds_of(args)
    missions = args.missions
    err = sys.stderr

    def say(text: str) -> None:
        if not args.quiet:
            print(text, file=err, flush=True)
    engine = suite.make_engine(args.engine, jobs=args.jobs, address=args.address,
                               timeout=args.timeout)
    say(f"suite: preparing {len(worlds)} world(s) ({', '.join(worlds[:6])}"
        f"{' ...' if len(worlds) > 6 else ''})")
    cases = suite_cases(args.scenarios, seed=args.seed, missions=missions,
                        warmup=args.warmup, worlds=worlds)
    keys = {suite.case_key(c) for c in cases}
    results = suite.ResultsFile(out / "results.jsonl", resume=args.resume)
    done = keys & set(results.results)
    say(f"suite: {len(cases)} scenarios, {len(done)} already done; engine {args.engine}; "
        f"results -> {results.path}"
        + (f" (replaced {results.replaced} earlier results; --resume keeps them)"
           if results.replaced else ""))
    progress = suite.Progress(len(cases), len(done), stream=err, enabled=not args.quiet)

    def got(r: dict) -> None:
        results.write(r)
        progress.update(r)
    t0 = time.perf_counter()
    try:
        suite.run_cases(cases, engine, on_result=got, done=done, log=say)
    except KeyboardInterrupt:
        progress.finish()
        n = len(keys & set(results.results))
        print(f"interrupted: {n} of {len(cases)} results in {results.path}; "
              f"--resume runs the rest", file=err)
        return 130
    finally:
        results.close()
    progress.finish()
    wall = time.perf_counter() - t0
    ran = progress.done - progress.start_done
    rep = suite_report.report([r for k, r in results.results.items() if k in keys], cases)
    rep.update(engine=engine.describe(), ran=ran, resumed=len(done), wall_s=round(wall, 1),
               scenarios_per_s=round(ran / wall, 3) if ran and wall > 0 else None)
    png = suite_report.render_png(rep, out / "summary.png")
    rep["files"] = {"results": str(results.path), "report": str(out / "report.json"),
                    "summary_png": str(png)}
    from hearth.worldmodel.io import atomic_write
    atomic_write(out / "report.json",
                 (json.dumps(rep, indent=1, sort_keys=True, default=str) + "\n").encode())
    if args.json:
        print(json.dumps(rep, sort_keys=True, default=str))
    else:
        print(suite_report.headline(rep, ran, wall, len(done)))
        print(suite_report.render_text(rep))
        print(f"\nWrote {results.path}, {out / 'report.json'}, {png}")
    return 1 if rep["problems"] else 0
