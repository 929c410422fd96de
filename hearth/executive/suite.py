"""Scenario suites on this machine or on a Ray cluster: the engines, resuming, the report and
its picture.

A suite is a list of :class:`hearth.executive.scenarios.Case` run one by one by an **engine**:

- ``local``: worker processes on this machine (started with *spawn*: open3d's OpenMP pool
  deadlocks in forked children, open3d issues #1552, #6096, #7133), one scenario at a time
  each. They read the worlds and the trained models where this machine keeps them.
- ``ray``: one Ray task per scenario, on a Ray instance started here (``address=None``) or on
  a running cluster (``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:10001"``). Nothing a task
  needs is read from a path of the submitting machine: every world (the demo home, generated
  homes, world files) travels as a bundle of its bytes (the world file and the meshes and
  point clouds it refers to) through Ray's object store, and so does every trained model the
  scenarios ask the model store for (``MISSION_MODELS``: the knob reader of each home, the
  segmentation forest). A worker unpacks them into its own temporary folder and points
  ``$HEARTH_MODEL_DIR`` and ``$HEARTH_HOME_DIR`` there. Generated homes are made once, here
  (``suite_cases`` needs their maps to choose targets), and shipped like any world file: a
  worker never regenerates a home from its seed, so a cluster whose nodes have another numpy
  still runs the same home. Models this machine lacks are trained first, as Ray tasks, and
  kept here too. Joining a cluster also ships Hearth's own code and missions (zipped into the
  object store; each task unpacks it first, hearth/executive/suite_boot.py), so the cluster runs the
  submitter's version; the third-party dependencies must be installed on its nodes.

Both engines run each scenario with one thread for every numeric library (BLAS through
threadpoolctl, OpenMP through ``OMP_NUM_THREADS``, open3d's TBB pool through
``open3d.utility.set_max_threads``): the workers are the parallelism, and a parallel reduction
whose summation order depends on thread timing is what made two runs of one seed differ in
the last digits of an estimate, and now and then in a decision. With that, the same case gives
the same result on either engine and in any worker; what still differs is listed in
``VARYING``.

A scenario that raises is reported with its traceback; one that runs past the time limit gets
an alarm (``SIGALRM`` in the worker: the traceback says where it was) and, when even that does
not end it, its worker is killed ``hard_limit_s`` later; a worker that dies (a segfault, an
``os._exit``, the OOM killer) is reported as crashed. None of them stops the suite: a new
worker takes the next scenario. Results stream back as they finish; :class:`ResultsFile`
appends each as one JSON line (flushed and synced), so a suite that is interrupted, even by
``kill -9``, resumes where it stopped: the cases already in the file are not run again.

:func:`report` summarises (``scenarios.summarise`` plus per-home counts, wrong successes per
world and object type, the slowest scenarios, the problems with their tracebacks);
:func:`render_text` prints it for a person and :func:`render_png` draws success per home and
mission as a grid (OpenCV).

Importing this module is cheap (the standard library only): `hearth --help` registers its
options.

This module is the front door (``make_engine``, ``run_cases``, ``run_suite``, ``ResultsFile``,
``Progress``, the command-line options); its neighbours, each importing only the ones before it:
suite_worker.py (one case in a worker: ``execute``, ``failure``, the time limit, the suite's
constants and ``SuiteError``), suite_bundles.py (worlds and models as bytes),
suite_local.py and suite_ray.py (the two engines), suite_report.py (``report``,
``render_text``, ``render_png``) and suite_boot.py (the first thing a shipped Ray task runs).
"""
from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable, Optional

from hearth.executive.suite_local import LocalEngine
from hearth.executive.suite_ray import RayEngine
from hearth.executive.suite_worker import case_key, DEFAULT_TIMEOUT_S, ENGINES, SuiteError

if TYPE_CHECKING:
    from hearth.executive.scenarios import Case


# ---------------------------------------------------------------------------------------
# Command-line options shared by `hearth suite` and `hearth bench missions`
# ---------------------------------------------------------------------------------------
def add_engine_arguments(parser, several: bool = False) -> None:
    """``--engine``, ``--address``, ``--timeout`` (``several``: ``--engine local,ray`` runs
    the same suite on each)."""
    if several:
        parser.add_argument("--engine", default="local", type=_engine_list,
                            help="local (worker processes here) or ray (one Ray task per "
                                 "scenario); local,ray runs the suite on both and compares")
    else:
        parser.add_argument("--engine", default="local", choices=ENGINES,
                            help="local: worker processes on this machine (default); ray: one "
                                 "Ray task per scenario (pip install 'hearth[ray]')")
    parser.add_argument("--address", default=None, metavar="ADDR",
                        help="ray engine: the cluster to join ('auto': the one running here, "
                             "HOST:PORT, ray://HOST:10001); default: start a local Ray "
                             "instance with --jobs CPUs")
    parser.add_argument("--timeout", type=_positive, default=DEFAULT_TIMEOUT_S, metavar="S",
                        help=f"time limit of one scenario, wall seconds (default "
                             f"{DEFAULT_TIMEOUT_S:g}); it is reported as timed out")


def _engine_list(text: str) -> list[str]:
    import argparse
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in ENGINES]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"engines are {', '.join(ENGINES)} (comma-separated), "
                                         f"not {text!r}")
    return names


def _positive(text: str) -> float:
    import argparse
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, not {text!r}")
    return v


def make_engine(name: str, jobs: int = 1, address: Optional[str] = None,
                timeout: float = DEFAULT_TIMEOUT_S, runner: Optional[Callable] = None):
    if name == "local":
        if address:
            raise SuiteError("--address is for the ray engine (--engine ray)")
        return LocalEngine(jobs, timeout, runner)
    if name == "ray":
        return RayEngine(address, jobs, timeout, runner)
    raise SuiteError(f"unknown engine {name!r}; engines: {', '.join(ENGINES)}")


def run_suite(cases: list[Case], jobs: int = 1,
              progress: Optional[Callable[[dict], None]] = None, engine: str = "local",
              address: Optional[str] = None, timeout: Optional[float] = None) -> list[dict]:
    """Run the cases on an engine (``local``: ``jobs`` spawned worker processes; ``ray``: one
    Ray task each, ``address`` the cluster) with a time limit per case (``timeout`` seconds,
    default ``DEFAULT_TIMEOUT_S``); ``progress`` gets each result as it arrives. The results in the order of ``cases``; a case that raised, hung or
    crashed its worker has outcome "error" (``error``: exception | timeout | crashed)."""
    eng = make_engine(engine, jobs=jobs, address=address, timeout=timeout or DEFAULT_TIMEOUT_S)
    got = run_cases(cases, eng, on_result=progress)
    return [got[case_key(c)] for c in cases]


# ---------------------------------------------------------------------------------------
# The results file and running a suite
# ---------------------------------------------------------------------------------------
class ResultsFile:
    """JSON lines, one result each, appended as results arrive. ``resume``: the results
    already there are kept (a last line cut short by a kill is dropped); otherwise the file
    starts empty."""

    def __init__(self, path, resume: bool = False):
        self.path = Path(path)
        self.results: dict[str, dict] = {}
        self.replaced = 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists() and not resume:
            self.replaced = len(self._read())
            self.results = {}
            self.path.write_bytes(b"")
        elif self.path.exists():
            self._read()
        self._fh = open(self.path, "ab")

    def _read(self) -> dict:
        try:
            data = self.path.read_bytes()
        except OSError as err:
            raise SuiteError(f"cannot read: {err.strerror or err}", file=str(self.path)) from None
        keep = data[:data.rfind(b"\n") + 1]      # a line cut short by a kill is not a result
        for n, line in enumerate(keep.splitlines(), 1):
            if not line.strip():
                continue
            try:
                r = json.loads(line)
                self.results[str(r["key"])] = r
            except (ValueError, KeyError, TypeError):
                raise SuiteError("not a results file of hearth suite (a line is not a "
                                 "result)", file=f"{self.path}:{n}") from None
        if len(keep) != len(data):
            with open(self.path, "r+b") as fh:
                fh.truncate(len(keep))
        return self.results

    def write(self, result: dict) -> None:
        self.results[result["key"]] = result
        self._fh.write(json.dumps(result, sort_keys=True, default=str).encode() + b"\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        self._fh.close()


class Progress:
    """A progress bar on ``stream``: one line rewriting itself on a terminal, one line per
    finished scenario elsewhere (a log, a pipe)."""

    def __init__(self, total: int, done: int = 0, stream=None, enabled: bool = True):
        self.stream = stream or sys.stderr
        self.total, self.done, self.start_done = total, done, done
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.counts = {"ok": 0, "failed": 0, "errors": 0}
        self.t0 = time.monotonic()

    def update(self, r: dict) -> None:
        self.done += 1
        if r.get("error"):
            self.counts["errors"] += 1
        elif r.get("correct"):
            self.counts["ok"] += 1
        else:
            self.counts["failed"] += 1
        if not self.enabled:
            return
        ran = self.done - self.start_done
        dt = time.monotonic() - self.t0
        rate = ran / dt if dt > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else math.inf
        if self.tty:
            width = 24
            fill = int(width * self.done / max(1, self.total))
            line = (f"[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total}  ok "
                    f"{self.counts['ok']}  failed {self.counts['failed']}  errors "
                    f"{self.counts['errors']}  {rate:.2f}/s"
                    + (f"  ETA {eta:.0f} s" if math.isfinite(eta) else ""))
            self.stream.write("\r" + line + "\x1b[K")
        else:
            what = r.get("error") or ("ok" if r.get("correct") else "failed")
            self.stream.write(f"[{self.done}/{self.total}] {what}: {r.get('world')} "
                              f"{r.get('mission')} {r.get('target') or ''} seed {r.get('seed')}"
                              f" -> {r.get('outcome')} ({r.get('wall_time_s')} s)\n")
        self.stream.flush()

    def finish(self) -> None:
        if self.enabled and self.tty and self.done > self.start_done:
            self.stream.write("\n")
            self.stream.flush()


def run_cases(cases: list, engine, on_result: Optional[Callable[[dict], None]] = None,
              done: Iterable[str] = (), log: Optional[Callable[[str], None]] = None
              ) -> dict[str, dict]:
    """Run the cases whose key is not in ``done`` on ``engine`` (started and closed here);
    ``on_result`` gets each result as it arrives. The results by key."""
    log = log or (lambda s: None)
    done = set(done)
    tasks = [{"key": case_key(c), "case": asdict(c)} for c in cases]
    tasks = [t for t in tasks if t["key"] not in done]
    out: dict[str, dict] = {}
    if not tasks:
        return out

    def got(r: dict) -> None:
        out[r["key"]] = r
        if on_result:
            on_result(r)
    todo_cases = [c for c in cases if case_key(c) not in done]
    try:
        engine.start()
        engine.prepare(todo_cases, log)
        engine.run(tasks, got)
    finally:
        engine.close()
    return out


