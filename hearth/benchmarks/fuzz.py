"""Hostile and careless files: fuzzing the world, mission and recording loaders.

Each case is a small folder written to a temporary directory: the shipped demo world
(``data/demo_home/world.xml``) or the shipped missions (``missions/*.yaml`` with
``missions/subtrees/``) mutated by a seeded generator (attribute and value replacements with
NaN, infinities, 1e308, zero sizes, escaping paths; deleted, duplicated, moved and renamed
elements and keys; nodes wrapped in retries and timeouts; YAML anchors, aliases and tags;
truncations and flipped bytes), or a small recording written per docs/recording-format.md
with its manifest and frames mutated. Next to the file each world case has planted
neighbours: a regular mesh, a directory, a FIFO and a symbolic link to /etc/passwd.

A case is run in a worker process (killed and restarted when it overstays ``--timeout``) and
ends as one of:

- ``refused``: the loader's own error (WorldError, MissionError, RobotError);
- ``accepted``, then checked independently of the loader: a world is saved, loaded again
  (and again after a joint, a knob and an object are updated), compared with the original,
  turned into meshes and every node's world pose computed; a mission's tree is built with
  its parameters and every number in it is checked; a recording's every frame is read.
  A failure there is ``accepted_then_unloadable``; a number the format does not allow
  (non-finite, beyond its bound) is ``accepted_out_of_bounds``; a mesh, point cloud,
  include or frame outside the case's folder (or not a regular file) counts in
  ``paths_outside_world``;
- ``traceback`` (any other exception), ``hang`` (over the time limit), ``crash`` (the worker
  died, e.g. in open3d).

The hand-made cases of issues 19 and 44 run as fixed cases with an expected outcome
(``fixed``); issue 44's carry a class (``CLASSES``: mesh-content, fifo, nul, huge-integer,
template, size, ...) and are counted by class (``fixed_by_class``). A fourth loader, ``bag``,
runs hand-made ROS 2 bag cases (when the ``ros`` extra is installed). Accepted missions also
have their utterance templates compiled and matched against the worst known utterance.

The ``http`` block sends hostile requests to a real server over the demo home (issue 44):
hand-made ones by class (cross-site POST/PUT with foreign ``Origin`` or ``Sec-Fetch-Site``,
malformed ``Host``, bodies with Infinity, NaN, 1e400, 5,000-digit integers, lone surrogates,
a key twice, the worst template's utterance) with the answer each must get, and
``--http-requests`` schema-generated ones (hearth/executive/command/fuzz.py) with hostile bodies and
foreign origins mixed in; it counts ``5xx`` and ``cross_site_accepted`` and reports how long
``/api/health`` took while the worst template was matched.

Targets: ``tracebacks``, ``hangs``, ``crashes``, ``accepted_then_unloadable``,
``accepted_out_of_bounds``, ``paths_outside_world``, ``5xx``, ``cross_site_accepted`` all 0,
per loader and in total.

``tests/fuzz/test_fuzz_loaders.py`` runs the same generators in-process on a few hundred cases.

This module runs the benchmark (worker processes, the report, ``run``); its neighbours:
fuzz_case.py (``Case``, ``Verdict``, the loaders and failure classes), fuzz_checks.py (one case
in-process and the independent checks), fuzz_generate.py (base files, mutators, generated
cases), fuzz_fixed.py (the hand-made cases) and fuzz_http.py (the HTTP block).
"""
from __future__ import annotations

import itertools
import multiprocessing
import os
import statistics
import tempfile
import time
from multiprocessing.connection import wait
from typing import Any, Iterable

from hearth.benchmarks.fuzz_case import Case, FAILURES, LOADERS, _OUTCOME_KEY, Verdict
from hearth.benchmarks.fuzz_checks import _describe, _registry, run_case
from hearth.benchmarks.fuzz_fixed import fixed_cases
from hearth.benchmarks.fuzz_generate import generated_cases
from hearth.benchmarks.fuzz_http import check_http


def add_arguments(parser) -> None:
    parser.add_argument("--cases", type=int, default=None,
                        help="mutated cases per world and mission loader (default 2000; "
                             "--quick 200); recordings get a quarter")
    parser.add_argument("--timeout", type=float, default=60.0,
                        help="seconds a case may take before it counts as a hang")
    parser.add_argument("--http-requests", type=int, default=None,
                        help="schema-generated requests to the HTTP API (default 500; --quick "
                             "100), besides the hand-made hostile ones")


# ---------------------------------------------------------------------------------------------
# Running cases in worker processes

def _worker(conn, timeout: float) -> None:   # pragma: no cover - runs in a child process
    import resource
    os.chdir(tempfile.gettempdir())
    _registry()                                  # import the skills once, before timing
    import hearth.worldmodel.geometry  # noqa: F401
    import hearth.robot.recording  # noqa: F401
    try:    # a memory bomb ends as MemoryError (a traceback) rather than swapping
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = 6 * 1024 ** 3
        if hard == resource.RLIM_INFINITY or hard > limit:
            resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ValueError, OSError):
        pass
    conn.send("ready")
    while True:
        try:
            case = conn.recv()
        except EOFError:
            return
        if case is None:
            return
        try:
            verdict = run_case(case, timeout)
        except BaseException as err:  # noqa: BLE001 - report, keep serving
            verdict = Verdict("traceback", "in the fuzz harness: " + _describe(err))
        conn.send(verdict)


class _Worker:
    def __init__(self, ctx, timeout: float):
        self.ctx, self.timeout = ctx, timeout
        self.start()

    def start(self) -> None:
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_worker, args=(child, self.timeout), daemon=True)
        self.proc.start()
        child.close()
        if not self.conn.poll(600) or self.conn.recv() != "ready":   # imports: seconds
            raise RuntimeError("fuzz worker did not start")

    def restart(self) -> None:
        from hearth.executive.suite_local import stop_worker
        stop_worker(self.proc, self.conn, kill=True)
        self.start()

    def close(self) -> None:
        from hearth.executive.suite_local import stop_worker
        stop_worker(self.proc, self.conn)


def run_cases(cases: Iterable[Case], jobs: int = 1, timeout: float = 30.0
              ) -> list[tuple[Case, Verdict]]:
    """(case, verdict) for every case, run in ``jobs`` worker processes; a case's files are
    dropped once it has run."""
    ctx = multiprocessing.get_context("spawn")
    workers = [_Worker(ctx, timeout) for _ in range(max(1, jobs))]
    todo = iter(cases)
    results: list[tuple[Case, Verdict]] = []
    busy: dict[int, tuple[Case, float]] = {}
    more = True

    def done(wi: int, verdict: Verdict) -> None:
        case, _ = busy.pop(wi)
        case.files = {}
        results.append((case, verdict))
    try:
        while more or busy:
            for wi, w in enumerate(workers):
                if wi not in busy and more:
                    case = next(todo, None)
                    if case is None:
                        more = False
                        break
                    w.conn.send(case)
                    busy[wi] = (case, time.monotonic())
            ready = wait([workers[wi].conn for wi in busy], timeout=0.5) if busy else []
            for wi in list(busy):
                w = workers[wi]
                if w.conn in ready:
                    try:
                        done(wi, w.conn.recv())
                    except (EOFError, OSError):
                        done(wi, Verdict("crash", f"worker died (exit {w.proc.exitcode})"))
                        w.restart()
                elif not w.proc.is_alive():
                    done(wi, Verdict("crash", f"worker died (exit {w.proc.exitcode})"))
                    w.restart()
                elif time.monotonic() - busy[wi][1] > timeout + 15:   # where no alarm reaches
                    done(wi, Verdict("hang", f"over {timeout + 15:g} s (worker killed)"))
                    w.restart()
    finally:
        for w in workers:
            w.close()
    return results


# ---------------------------------------------------------------------------------------------
# Report

def summarise(results: list[tuple[Case, Verdict]]) -> dict:
    counts = {"cases": len(results), "accepted": 0, "refused": 0, **{k: 0 for k in FAILURES}}
    ms = []
    for _, v in results:
        if v.outcome in ("accepted", "refused"):
            counts[v.outcome] += 1
        else:
            counts[_OUTCOME_KEY[v.outcome]] += 1
        if v.outside:
            counts["paths_outside_world"] += 1
        ms.append(v.ms)
    counts["median_ms"] = round(statistics.median(ms), 2) if ms else 0.0
    return counts


def failures(results: list[tuple[Case, Verdict]], limit: int = 12) -> list[dict]:
    out = []
    for c, v in results:
        if v.outcome not in ("accepted", "refused") or v.outside:
            out.append({"loader": c.loader, "case": c.name[:120], "outcome": v.outcome,
                        "detail": v.detail[:240], "paths_outside": v.outside})
    return out[:limit]


def by_class(results: list[tuple[Case, Verdict]]) -> dict:
    """The fixed cases by class: cases, and those that did not end as expected."""
    out: dict[str, dict[str, int]] = {}
    for c, v in results:
        if c.expect is None or not c.klass:
            continue
        row = out.setdefault(c.klass, {"cases": 0, "failed": 0})
        row["cases"] += 1
        row["failed"] += v.outcome != c.expect or bool(v.outside)
    return out


def run(args) -> dict:
    quick = getattr(args, "quick", False)
    n = getattr(args, "cases", None) or (200 if quick else 2000)
    seed = getattr(args, "seed", 0) or 0
    jobs = max(1, getattr(args, "jobs", 1) or 1)
    timeout = getattr(args, "timeout", 60.0) or 60.0
    t0 = time.perf_counter()
    sizes = {"world": n, "mission": n, "recording": max(50, n // 4), "bag": 0}
    fixed = fixed_cases()
    cases = itertools.chain(*(generated_cases(l, sizes[l], seed) for l in LOADERS), fixed)
    results = run_cases(cases, jobs=jobs, timeout=timeout)
    out: dict[str, Any] = {"seed": seed, "timeout_s": timeout}
    for loader in LOADERS:
        out[loader] = summarise([(c, v) for c, v in results if c.loader == loader])
        out[loader]["fixed_cases"] = sum(c.loader == loader and c.expect is not None
                                         for c, _ in results)
    out["total"] = {k: sum(out[l][k] for l in LOADERS)
                    for k in ("cases", "accepted", "refused", *FAILURES)}
    out["world_and_mission"] = {k: out["world"][k] + out["mission"][k] for k in FAILURES}
    fixed_report, fixed_failed = {}, []
    for c, v in results:
        if c.expect is None:
            continue
        fixed_report[f"{c.loader}/{c.name}"] = {"expected": c.expect, "outcome": v.outcome,
                                                "ms": round(v.ms, 1), "message": v.detail[:160]}
        if v.outcome != c.expect or v.outside:
            fixed_failed.append(f"{c.loader}/{c.name}")
    out["fixed"] = fixed_report
    out["fixed_failed"] = fixed_failed
    out["fixed_by_class"] = by_class(results)
    http_n = getattr(args, "http_requests", None) or (100 if quick else 500)
    out["http"] = check_http(http_n, seed)
    out["total"]["5xx"] = out["http"]["5xx"]
    out["total"]["cross_site_accepted"] = out["http"]["cross_site_accepted"]
    out["failures"] = failures(results, limit=40)
    out["targets"] = {**{k: 0 for k in FAILURES}, "5xx": 0, "cross_site_accepted": 0}
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out
