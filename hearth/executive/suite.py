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
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path, PurePosixPath
from typing import Any, Callable, Iterable, Optional

from hearth.util.errors import HearthError

ENGINES = ("local", "ray")
#: The default time limit of one scenario (wall seconds; a scenario takes 1-30 s here).
DEFAULT_TIMEOUT_S = 300.0
RAY_MISSING = "the ray engine needs Ray, which is not installed: pip install 'hearth[ray]'"
#: Result fields that may differ between two runs of the same case (engine, worker, speed).
VARYING = ("wall_time_s", "log_path", "worker", "engine", "code", "traceback")
#: The trained models the skills of a mission ask the model store for (hearth/skills/knob_models.py:
#: one knob reader per home; hearth/skills/segmentation_model.py: one forest for every home). A
#: mission not named here gets none shipped: a worker trains what it lacks (slowly).
MISSION_MODELS = {"turn_off_oven": ("knobs",), "fetch_object": ("segmentation",),
                  "search_object": ("segmentation",)}
#: Hearth's own packages: what a cluster gets through the runtime environment.
PACKAGES = ("hearth",)


class SuiteError(HearthError):
    """A suite that cannot run as asked (an engine missing, a cluster out of reach, a results
    file that is not one)."""

    file_line_optional = True


def hard_limit_s(timeout: float) -> float:
    """When a scenario's worker is killed: its alarm did not end it by then."""
    return timeout + max(2.0, min(30.0, 0.25 * timeout))


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


# ---------------------------------------------------------------------------------------
# Cases and results
# ---------------------------------------------------------------------------------------
def case_key(case) -> str:
    """A case's identity in a results file: a hash of all its fields."""
    d = case if isinstance(case, dict) else asdict(case)
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


def comparable(result: dict) -> dict:
    """A result without the fields that may differ between runs (``VARYING``)."""
    return {k: v for k, v in result.items() if k not in VARYING}


def failure(case: dict, kind: str, reason: str, tb: str = "", wall: float = 0.0) -> dict:
    """The result of a case that did not finish: ``error`` is "exception", "timeout" or
    "crashed" (the mission's own failures: ``outcome`` "error", counted against it by
    ``scenarios.summarise``), or "engine" (the engine could not deliver the case: a world
    that arrived incomplete or altered; kept out of the missions' figures, listed in
    ``engine_errors``, and the run exits 1)."""
    from hearth.executive.scenarios import Case, CaseResult
    c = Case(**case)
    r = asdict(CaseResult(mission=c.mission, seed=c.seed, achievable=c.achievable,
                          learned=c.learned, outcome="error", reason=reason, category="other",
                          correct=False, sim_time_s=0.0, wall_time_s=round(wall, 2),
                          world=c.world, target=c.target))
    r.update(error=kind, traceback=tb or None)
    return r


class ScenarioTimeout(BaseException):
    """Raised in a worker by the scenario's alarm. A BaseException, so that code catching
    Exception (a skill's own error handling) does not swallow it."""


def _alarm(signum, frame):
    raise ScenarioTimeout()


def execute(case: dict, runner: Optional[Callable] = None, world=None,
            timeout: Optional[float] = None) -> dict:
    """Run one case in this process: ``runner(Case, world=world)`` (default
    ``scenarios.run_case``) as a dict; an exception or the alarm after ``timeout`` seconds
    becomes a ``failure`` with its traceback."""
    import signal
    import threading

    from hearth.executive.scenarios import Case, run_case
    run = runner or run_case
    alarm = timeout is not None and threading.current_thread() is threading.main_thread()
    t0 = time.perf_counter()
    try:
        if alarm:
            previous = signal.signal(signal.SIGALRM, _alarm)
            signal.setitimer(signal.ITIMER_REAL, float(timeout))
        try:
            return asdict(run(Case(**case), world=world))
        finally:
            if alarm:
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, previous)
    except ScenarioTimeout:
        return failure(case, "timeout", f"timed out after {timeout:g} s",
                       traceback.format_exc(), time.perf_counter() - t0)
    except Exception as err:  # noqa: BLE001 - one broken case must not lose the others
        return failure(case, "exception", f"{type(err).__name__}: {err}",
                       traceback.format_exc(), time.perf_counter() - t0)


def prepare_process(isolated: bool = False) -> Optional[Path]:
    """Set up a worker process, before anything numeric is imported: one thread per numeric
    library (see the module docstring), open3d quiet. ``isolated`` (a Ray worker): a private
    temporary folder for the models and homes it is sent; returns it."""
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(1)
    except ImportError:  # pragma: no cover
        pass
    try:
        import open3d as o3d
        o3d.utility.set_max_threads(1)
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    except (ImportError, AttributeError):  # pragma: no cover
        pass
    if not isolated:
        return None
    if "dir" not in _WORKER:
        import atexit
        import shutil
        import tempfile
        d = Path(tempfile.mkdtemp(prefix="hearth-worker-"))
        atexit.register(shutil.rmtree, d, True)
        (d / "models").mkdir()
        (d / "homes").mkdir()
        os.environ["HEARTH_MODEL_DIR"] = str(d / "models")
        os.environ["HEARTH_HOME_DIR"] = str(d / "homes")
        _WORKER.update(dir=d, worlds={}, models={})
    return _WORKER["dir"]


#: This worker process's state (isolated workers): its folder, unpacked worlds, models.
_WORKER: dict = {}


# ---------------------------------------------------------------------------------------
# Worlds and models as bytes
# ---------------------------------------------------------------------------------------
WORLD_FILE = "world.xml"


def world_bundle(spec: str) -> dict[str, bytes]:
    """A world (``demo``, ``home:SEED``, a file) as ``{relative path: bytes}``: the world
    file as ``world.xml`` and every mesh and point cloud it refers to. References that lead
    out of the world's folder are copied in and the world is saved again pointing at them
    (``hearth.robot.scenario.copy_world_files``); otherwise the file travels as it is."""
    import tempfile

    from hearth.executive.scenarios import world_path
    from hearth.robot.scenario import copy_world_files
    from hearth.worldmodel.io import load_world, save_world
    path = world_path(spec)
    world = load_world(path)
    with tempfile.TemporaryDirectory(prefix="hearth-bundle-") as tmp:
        d = Path(tmp)
        copy_world_files([world], d)
        if (d / "files").exists():       # something outside the folder: rewritten
            save_world(world, d / WORLD_FILE)
        else:
            (d / WORLD_FILE).write_bytes(path.read_bytes())
        return {p.relative_to(d).as_posix(): p.read_bytes()
                for p in sorted(d.rglob("*")) if p.is_file()}


def bundle_fingerprint(bundle: dict[str, bytes]) -> str:
    h = hashlib.sha256()
    for name in sorted(bundle):
        h.update(name.encode() + b"\0" + hashlib.sha256(bundle[name]).digest())
    return h.hexdigest()[:16]


def unpack_world(bundle: dict[str, bytes], directory: Path) -> Path:
    """Write a bundle into ``directory``; the world file's path."""
    for name, data in bundle.items():
        rel = PurePosixPath(name)
        if rel.is_absolute() or ".." in rel.parts:
            raise SuiteError(f"world bundle: unsafe path {name!r}")
        dst = directory.joinpath(*rel.parts)
        dst.parent.mkdir(parents=True, exist_ok=True)
        _write_atomic(dst, data)
    return directory / WORLD_FILE


def arrived_world(bundle: dict[str, bytes], bundle_fp: str, directory: Path):
    """The world of a bundle as it arrived in a worker, checked: its contents hash to the
    fingerprint the sender computed (``bundle_fingerprint``), it unpacks under
    ``directory/<fingerprint>`` and loads (schema, semantics and every file it refers to:
    ``hearth.worldmodel.io.load_world``). A world loaded once per worker process is reused. Raises
    SuiteError or the world model's errors: the sender loaded the same world before
    bundling it, so any failure here is the transport's."""
    from hearth.worldmodel.io import load_world
    cache = _WORKER.setdefault("worlds", {})
    got = cache.get(bundle_fp)
    if got is not None:
        return load_world(got)
    if bundle_fingerprint(bundle) != bundle_fp:
        raise SuiteError(f"world bundle {bundle_fp}: contents differ from what was sent "
                         f"({len(bundle)} files)")
    world_file = unpack_world(bundle, directory / bundle_fp)
    world = load_world(world_file)
    cache[bundle_fp] = world_file
    return world


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


@dataclass(frozen=True)
class ModelNeed:
    """A trained model the cases need: ``name`` ("knobs", "segmentation") and the world it is
    trained for (None: one for every home)."""
    name: str
    world: Optional[str] = None


def model_needs(cases) -> list[ModelNeed]:
    """The models ``cases`` ask for (``MISSION_MODELS``), each once."""
    out: dict[ModelNeed, None] = {}
    for c in cases:
        for name in MISSION_MODELS.get(c.mission, ()):
            out[ModelNeed(name, c.world if name == "knobs" else None)] = None
    return list(out)


def stored_model(need: ModelNeed) -> Optional[tuple[str, bytes]]:
    """(file name, bytes) of the current stored model, or None when it is missing or stale."""
    loaded = _check_model(need)
    if not loaded.ok:
        return None
    return loaded.path.name, loaded.path.read_bytes()


def _check_model(need: ModelNeed, world=None):
    if need.name == "knobs":
        from hearth.executive.scenarios import resolve_world
        from hearth.skills.knob_models import check
        return check(world if world is not None else resolve_world(need.world))
    from hearth.skills.segmentation_model import check
    return check()


def train_model(need: ModelNeed, world=None) -> tuple[str, bytes]:
    """Train ``need`` in this process into the model store (``$HEARTH_MODEL_DIR``); its file
    (name, bytes)."""
    if need.name == "knobs":
        from hearth.executive.scenarios import resolve_world
        from hearth.skills.knob_models import load_or_train
        _, info = load_or_train(world if world is not None else resolve_world(need.world))
    else:
        from hearth.skills.segmentation_model import get
        _, info = get()
    return info.path.name, Path(info.path).read_bytes()


def keep_model(filename: str, data: bytes) -> Path:
    """Store a model file trained elsewhere in this machine's model store."""
    from hearth.worldmodel.io import atomic_write
    from hearth.worldmodel.model_store import model_dir
    path = model_dir() / filename
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, data)
    return path


def describe_need(need: ModelNeed) -> str:
    return f"knob models for {need.world}" if need.name == "knobs" else "the segmentation forest"


# ---------------------------------------------------------------------------------------
# The local engine: worker processes on this machine
# ---------------------------------------------------------------------------------------
def _local_worker(conn, runner, timeout) -> None:   # pragma: no cover - a child process
    prepare_process()
    import hearth.executive.scenarios  # noqa: F401 - the imports happen before the first case
    import hearth.executive.executive  # noqa: F401
    import hearth.robot.simulated  # noqa: F401
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        kind, payload = msg
        if kind == "train":
            try:
                train_model(payload)
                conn.send(("trained", None))
            except Exception:  # noqa: BLE001 - said in the parent
                conn.send(("trained", traceback.format_exc()))
            continue
        conn.send(("started", payload["key"]))
        conn.send(("result", execute(payload["case"], runner, timeout=timeout)))


def stop_worker(proc, conn, kill: bool = False) -> None:
    """End a worker process that serves requests on ``conn`` until it receives None: ask it
    (unless ``kill``), give it 5 s, then kill it; close the pipe."""
    if not kill:
        try:
            conn.send(None)
        except OSError:
            pass
        proc.join(5)
    if proc.is_alive():
        proc.kill()
    proc.join()
    conn.close()


class _Proc:
    def __init__(self, ctx, runner, timeout):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_local_worker, args=(child, runner, timeout),
                                daemon=True, name="hearth-suite-worker")
        self.proc.start()
        child.close()
        self.task: Optional[dict] = None
        self.deadline = math.inf

    def stop(self, kill: bool = False) -> None:
        stop_worker(self.proc, self.conn, kill)


class LocalEngine:
    """``jobs`` worker processes on this machine; ``runner`` replaces ``run_case`` (it must be
    importable by the spawned workers)."""

    name = "local"

    def __init__(self, jobs: int = 1, timeout: float = DEFAULT_TIMEOUT_S,
                 runner: Optional[Callable] = None):
        import multiprocessing
        self.jobs = max(1, int(jobs))
        self.timeout = float(timeout)
        self.runner = runner
        self.ctx = multiprocessing.get_context("spawn")
        self.procs: list[_Proc] = []

    def describe(self) -> str:
        return f"local, {self.jobs} worker process{'es' if self.jobs > 1 else ''}"

    def start(self) -> None:
        pass

    def _proc(self, i: int) -> _Proc:
        while len(self.procs) <= i:
            self.procs.append(_Proc(self.ctx, self.runner, self.timeout))
        return self.procs[i]

    def _replace(self, i: int) -> None:
        self.procs[i].stop(kill=True)
        self.procs[i] = _Proc(self.ctx, self.runner, self.timeout)

    def prepare(self, cases, log: Callable[[str], None]) -> None:
        """Train the models the cases need and this machine lacks, in the workers, before any
        case runs (a case that trained its own model would run into its time limit)."""
        from multiprocessing.connection import wait
        missing = [n for n in model_needs(cases) if stored_model(n) is None]
        for n in missing:
            log(f"training {describe_need(n)} (a minute or more) ...")
        busy: dict[int, ModelNeed] = {}
        while missing or busy:
            for i in range(self.jobs):
                if i not in busy and missing:
                    busy[i] = missing.pop(0)
                    self._proc(i).conn.send(("train", busy[i]))
            for conn in wait([self.procs[i].conn for i in busy]):
                i = next(j for j in busy if self.procs[j].conn is conn)
                need = busy.pop(i)
                try:
                    _, err = conn.recv()
                except (EOFError, OSError):
                    err = f"the worker died (exit {self.procs[i].proc.exitcode})"
                    self._replace(i)
                if err:
                    log(f"training {describe_need(need)} failed; its scenarios will try "
                        f"again:\n{err}")

    def run(self, tasks: list[dict], on_result: Callable[[dict], None]) -> None:
        """Run ``tasks`` (``{"key", "case"}``), calling ``on_result`` with each result as it
        comes."""
        from multiprocessing.connection import wait
        todo = list(tasks)
        busy: set[int] = set()
        hard = hard_limit_s(self.timeout)
        while todo or busy:
            for i in range(self.jobs):
                if i not in busy and todo:
                    p = self._proc(i)
                    p.task, p.deadline = todo.pop(0), math.inf
                    p.conn.send(("case", p.task))
                    busy.add(i)
            now = time.monotonic()
            soonest = min(self.procs[i].deadline for i in busy)
            ready = wait([self.procs[i].conn for i in busy],
                         timeout=None if soonest == math.inf else max(0.0, soonest - now))
            for i in sorted(busy):
                p = self.procs[i]
                if p.conn in ready:
                    try:
                        kind, value = p.conn.recv()
                    except (EOFError, OSError):
                        p.proc.join(5)
                        res = failure(p.task["case"], "crashed",
                                      f"the worker process died (exit status "
                                      f"{p.proc.exitcode}) while running this scenario")
                        self._finish(i, busy, res, on_result, replace=True)
                        continue
                    if kind == "started":
                        p.deadline = time.monotonic() + hard
                    else:
                        self._finish(i, busy, value, on_result)
                elif time.monotonic() >= p.deadline:
                    res = failure(p.task["case"], "timeout",
                                  f"timed out after {self.timeout:g} s; its worker did not "
                                  f"answer the alarm and was killed after {hard:g} s", "",
                                  hard)
                    self._finish(i, busy, res, on_result, replace=True)

    def _finish(self, i, busy, res, on_result, replace=False) -> None:
        p = self.procs[i]
        task = p.task
        p.task, p.deadline = None, math.inf
        busy.discard(i)
        if replace:
            self._replace(i)
        res.update(key=task["key"], case=task["case"], engine=self.name,
                   worker=f"{os.uname().nodename}:{p.proc.pid}")
        on_result(res)

    def close(self) -> None:
        for p in self.procs:
            p.stop()
        self.procs = []


# ---------------------------------------------------------------------------------------
# The Ray engine: one task per scenario
# ---------------------------------------------------------------------------------------
def _ray_case(case: dict, key: str, runner, timeout: float, bundle_fp: str,
              bundle: dict, *models) -> dict:   # pragma: no cover - runs in a Ray worker
    d = prepare_process(isolated=True)
    for filename, data in models:
        if _WORKER["models"].get(filename) != len(data):
            _write_atomic(Path(os.environ["HEARTH_MODEL_DIR"]) / filename, data)
            _WORKER["models"][filename] = len(data)
    runs_dir = case.get("runs_dir")
    run = dict(case, runs_dir=str(d / "runs" / key)) if runs_dir else case
    try:
        world = arrived_world(bundle, bundle_fp, d / "worlds")
    except Exception as err:  # noqa: BLE001 - reported as the engine's fault, not the mission's
        res = failure(case, "engine", f"world {case.get('world')!r} did not arrive whole: "
                      f"{type(err).__name__}: {err}", traceback.format_exc())
    else:
        res = execute(run, runner, world, timeout)
    res["worker"] = f"{os.uname().nodename}:{os.getpid()}"
    res["code"] = str(Path(sys.modules["hearth"].__file__).parent)   # where it ran from
    if runs_dir and res.get("log_path"):
        log = Path(res["log_path"])
        res["log_file"] = (log.name, log.read_bytes()) if log.is_file() else None
    return res


def _ray_train(need: ModelNeed, bundle: Optional[dict]) -> tuple[str, bytes]:  # pragma: no cover
    d = prepare_process(isolated=True)
    world = None
    if bundle is not None:
        from hearth.worldmodel.io import load_world
        world = load_world(unpack_world(bundle, d / "worlds" / bundle_fingerprint(bundle)))
    return train_model(need, world)


def _staged_code() -> list[str]:
    """Hearth's packages copied into a temporary folder, the missions and the demo home
    inside ``hearth`` (as a wheel has them)."""
    import shutil
    import tempfile

    import hearth
    out = Path(tempfile.mkdtemp(prefix="hearth-code-"))
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    paths = []
    for name in PACKAGES:
        src = Path(sys.modules[name].__file__ if name in sys.modules
                   else __import__(name).__file__).parent
        shutil.copytree(src, out / name, ignore=ignore)
        paths.append(str(out / name))
    for res in ("missions", "data"):
        if not (out / "hearth" / res).is_dir():
            shutil.copytree(hearth.resource_dir(res), out / "hearth" / res, ignore=ignore)
    return paths


def _code_zip() -> tuple[str, bytes]:
    """(fingerprint, zip) of Hearth's staged code, for hearth/executive/suite_boot.py."""
    import hashlib
    import io
    import shutil
    import zipfile
    paths = _staged_code()
    root = Path(paths[0]).parent
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(root.rglob("*")):
            if f.is_file():
                z.write(f, f.relative_to(root).as_posix())
    shutil.rmtree(root, ignore_errors=True)
    data = buf.getvalue()
    return hashlib.sha256(data).hexdigest()[:16], data


class RayEngine:
    """One Ray task per scenario (see the module docstring). ``address``: None starts a local
    instance with ``jobs`` CPUs (or uses the one this process already joined); otherwise
    ``ray.init(address)``. ``ship_code``: send Hearth's code with the tasks (default: when
    joining a cluster)."""

    name = "ray"

    def __init__(self, address: Optional[str] = None, jobs: Optional[int] = None,
                 timeout: float = DEFAULT_TIMEOUT_S, runner: Optional[Callable] = None,
                 ship_code: Optional[bool] = None):
        try:
            import ray
        except ImportError:
            raise SuiteError(RAY_MISSING) from None
        self.ray = ray
        self.address = address
        self.jobs = jobs
        self.timeout = float(timeout)
        self.runner = runner
        self.ship_code = (address is not None) if ship_code is None else ship_code
        self.owned = False
        self.slots = 1
        self.refs: dict = {}
        self.where = ""

    def describe(self) -> str:
        return f"ray, {self.where}, {self.slots} CPU{'s' if self.slots > 1 else ''}"

    def start(self) -> None:
        import logging
        ray = self.ray
        if not ray.is_initialized():
            kw: dict[str, Any] = dict(logging_level=logging.ERROR, log_to_driver=False,
                                      include_dashboard=False)
            try:
                if self.address is None:
                    ray.init(num_cpus=self.jobs or os.cpu_count() or 1, **kw)
                else:
                    ray.init(address=self.address, **kw)
            except (ConnectionError, RuntimeError, ValueError) as err:
                first = (str(err).strip().splitlines() or [type(err).__name__])[0]
                raise SuiteError(f"ray: cannot {'start' if self.address is None else 'join'} "
                                 f"{self.address or 'a local instance'}: {first}") from None
            self.owned = True
        self.where = ("local instance" if self.address is None
                      else f"cluster at {self.address}")
        self.slots = max(1, int(ray.cluster_resources().get("CPU", 1)))
        opts: dict[str, Any] = dict(num_cpus=1, max_retries=0)
        self._boot = None
        if self.ship_code:
            # Ray takes a folder of code only at ray.init (a job's runtime environment): the
            # code goes through the object store and each task unpacks it first.
            from hearth.executive import suite_boot
            ray.cloudpickle.register_pickle_by_value(suite_boot)
            fp, data = _code_zip()
            self._code = (fp, ray.put(data))
            self._boot = ray.remote(suite_boot.boot).options(**opts)
        self._case = ray.remote(_ray_case).options(**opts)
        self._train = ray.remote(_ray_train).options(**opts)
        mod = sys.modules.get(getattr(self.runner, "__module__", "") or "")
        if mod is not None and mod.__name__.split(".")[0] not in PACKAGES:
            # A runner of one's own (a test's stand-in) travels by value with the tasks.
            ray.cloudpickle.register_pickle_by_value(mod)

    def _bundle(self, world: str):
        key = ("world", world)
        if key not in self.refs:
            bundle = world_bundle(world)
            self.refs[key] = (bundle_fingerprint(bundle), self.ray.put(bundle))
        return self.refs[key]

    def prepare(self, cases, log: Callable[[str], None]) -> None:
        """Put every world and model the cases need in the object store; train the models
        this machine lacks as Ray tasks (and keep them here too)."""
        ray = self.ray
        for w in dict.fromkeys(c.world for c in cases):
            self._bundle(w)
        training = {}
        for need in model_needs(cases):
            stored = stored_model(need)
            if stored is not None:
                self.refs[need] = ray.put(stored)
                continue
            log(f"training {describe_need(need)} on Ray (a minute or more) ...")
            bundle = self._bundle(need.world)[1] if need.world else None
            if self._boot is not None:
                call = self.ray.cloudpickle.dumps(("_ray_train", (need,)))
                training[need] = self._boot.remote(*self._code, call, bundle)
            else:
                training[need] = self._train.remote(need, bundle)
        for need, ref in training.items():
            try:
                filename, data = ray.get(ref)
            except ray.exceptions.RayError as err:
                log(f"training {describe_need(need)} failed; its scenarios will try again: "
                    f"{str(err).strip().splitlines()[0]}")
                continue
            keep_model(filename, data)
            self.refs[need] = ref

    def _submit(self, task: dict):
        case = task["case"]
        fp, bundle = self._bundle(case["world"])
        models = [self.refs[n] for n in model_needs([_Case(case)]) if n in self.refs]
        if self._boot is not None:
            call = self.ray.cloudpickle.dumps(
                ("_ray_case", (case, task["key"], self.runner, self.timeout, fp)))
            return self._boot.remote(*self._code, call, bundle, *models)
        return self._case.remote(case, task["key"], self.runner, self.timeout, fp, bundle,
                                 *models)

    def run(self, tasks: list[dict], on_result: Callable[[dict], None]) -> None:
        """As many tasks in flight as the cluster has CPUs (so a task in flight is a task
        running, and its time limit means what it says); results in the order they end."""
        ray = self.ray
        todo = list(tasks)
        running: dict = {}
        hard = hard_limit_s(self.timeout) + 30.0     # a task's clock starts before its imports
        while todo or running:
            while todo and len(running) < self.slots:
                task = todo.pop(0)
                running[self._submit(task)] = (task, time.monotonic())
            soonest = min(t0 for _, t0 in running.values()) + hard
            ready, _ = ray.wait(list(running), num_returns=1,
                                timeout=max(0.0, soonest - time.monotonic()))
            for ref in ready:
                task, _ = running.pop(ref)
                try:
                    res = ray.get(ref)
                except ray.exceptions.RayTaskError as err:
                    res = failure(task["case"], "exception", str(err).strip().splitlines()[0],
                                  str(err))
                except ray.exceptions.RayError as err:
                    res = failure(task["case"], "crashed",
                                  f"the Ray worker died while running this scenario "
                                  f"({type(err).__name__})", str(err))
                self._finish(task, res, on_result)
            now = time.monotonic()
            for ref, (task, t0) in list(running.items()):
                if now - t0 >= hard:
                    ray.cancel(ref, force=True)
                    del running[ref]
                    res = failure(task["case"], "timeout",
                                  f"timed out after {self.timeout:g} s; its worker did not "
                                  f"answer the alarm and was killed", "", now - t0)
                    self._finish(task, res, on_result)

    def _finish(self, task: dict, res: dict, on_result) -> None:
        log_file = res.pop("log_file", None)
        runs_dir = task["case"].get("runs_dir")
        if runs_dir and log_file:
            dst = Path(runs_dir) / log_file[0]
            dst.parent.mkdir(parents=True, exist_ok=True)
            dst.write_bytes(log_file[1])
            res["log_path"] = str(dst)
        res.setdefault("worker", "")
        res.update(key=task["key"], case=task["case"], engine=self.name)
        on_result(res)

    def close(self) -> None:
        if self.owned and self.ray.is_initialized():
            self.ray.shutdown()
        self.owned = False


class _Case:
    """The fields of a case dict ``model_needs`` reads."""

    def __init__(self, d: dict):
        self.mission, self.world = d["mission"], d["world"]


def make_engine(name: str, jobs: int = 1, address: Optional[str] = None,
                timeout: float = DEFAULT_TIMEOUT_S, runner: Optional[Callable] = None):
    if name == "local":
        if address:
            raise SuiteError("--address is for the ray engine (--engine ray)")
        return LocalEngine(jobs, timeout, runner)
    if name == "ray":
        return RayEngine(address, jobs, timeout, runner)
    raise SuiteError(f"unknown engine {name!r}; engines: {', '.join(ENGINES)}")


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


# ---------------------------------------------------------------------------------------
# The report
# ---------------------------------------------------------------------------------------
def report(results: list[dict], cases: Optional[list] = None) -> dict:
    """What a suite found: ``summary`` (``scenarios.summarise``), per mission and per home
    the counts behind the success rates (learned search order, as ``summarise``), wrong
    successes per world and per object type, the ten slowest scenarios and every problem
    (crashed, timed out, raised) with its traceback."""
    from collections import Counter, defaultdict

    from hearth.executive.scenarios import summarise
    order = {case_key(c): i for i, c in enumerate(cases)} if cases is not None else {}
    rs = sorted(results, key=lambda r: order.get(r.get("key"), len(order)))
    main = [r for r in rs if r.get("learned", True)]
    per_home: dict[str, dict] = defaultdict(dict)
    per_mission: dict[str, dict] = {}
    for m in sorted({r["mission"] for r in rs}):
        rm = [r for r in main if r["mission"] == m]
        per_mission[m] = _counts(rm)
        for w in dict.fromkeys(r.get("world", "demo") for r in rm):
            per_home[w][m] = _counts([r for r in rm if r.get("world", "demo") == w])
    wrong = [r for r in rs if r.get("wrong_success")]
    problems = [dict(key=r.get("key"), world=r.get("world"), mission=r["mission"],
                     seed=r["seed"], target=r.get("target"), error=r.get("error"),
                     reason=r["reason"], traceback=r.get("traceback"),
                     wall_time_s=r.get("wall_time_s"))
                for r in rs if r.get("error") or r["outcome"] == "error"]
    slowest = sorted((r for r in rs if not r.get("error")), key=lambda r: -r["wall_time_s"])[:10]
    return {
        "scenarios": len(cases) if cases is not None else len(rs),
        "results": len(rs),
        # Warm-up runs (learned: false) fill the learned search order; the tables count
        # the others.
        "warmup_runs": len(rs) - len(main),
        "per_mission": per_mission,
        "per_home": dict(per_home),
        "wrong_success": {
            "total": len(wrong),
            "by_world": dict(Counter(r.get("world", "demo") for r in wrong)),
            "by_object_type": dict(Counter(r.get("target_type") or "?" for r in wrong)),
            "by_mission": dict(Counter(r["mission"] for r in wrong)),
        },
        "problems": problems,
        "problem_counts": dict(Counter(p["error"] or "error" for p in problems)),
        "slowest": [dict(world=r.get("world"), mission=r["mission"], target=r.get("target"),
                         seed=r["seed"], learned=r.get("learned", True), outcome=r["outcome"],
                         wall_time_s=r["wall_time_s"], sim_time_s=r.get("sim_time_s"))
                    for r in slowest],
        "summary": summarise(rs) if rs else {},
    }


def _counts(rs: list[dict]) -> dict:
    ach = [r for r in rs if r["achievable"]]
    una = [r for r in rs if not r["achievable"]]
    ok = sum(bool(r["correct"]) for r in rs)
    return {"scenarios": len(rs), "correct": ok,
            "rate": round(ok / len(rs), 3) if rs else None,
            "achievable": len(ach), "succeeded": sum(bool(r["correct"]) for r in ach),
            "success_rate": round(sum(bool(r["correct"]) for r in ach) / len(ach), 3)
            if ach else None,
            "unachievable": len(una), "unachievable_correct": sum(bool(r["correct"]) for r in una),
            "wrong_success": sum(bool(r.get("wrong_success")) for r in rs),
            "errors": sum(bool(r.get("error")) or r["outcome"] == "error" for r in rs)}


def headline(rep: dict, ran: int, wall_s: float, resumed: int = 0) -> str:
    """The first line of a suite's report: the scenarios its tables count (warm-up runs
    apart), how many ran now, where and how long."""
    warm = rep.get("warmup_runs", 0)
    return (f"{rep['results'] - warm} scenarios" + (f" and {warm} warm-up runs" if warm else "")
            + f" ({ran} run now on {rep['engine']} in {wall_s:.1f} s"
            + (f", {resumed} from the results file" if resumed else "") + ")")


def render_text(rep: dict, top: int = 5) -> str:
    """The report for a person."""
    lines = []
    missions = list(rep["per_mission"])
    lines.append("Per mission (success: achievable scenarios that succeeded, learned order; "
                 "unachievable: ended with the right failure)")
    lines.append(f"  {'mission':<22}{'scenarios':>10}{'success':>14}{'unachievable':>15}"
                 f"{'wrong':>7}{'errors':>8}")
    for m, c in rep["per_mission"].items():
        lines.append(f"  {m:<22}{c['scenarios']:>10}{_frac(c['succeeded'], c['achievable']):>14}"
                     f"{_frac(c['unachievable_correct'], c['unachievable']):>15}"
                     f"{c['wrong_success']:>7}{c['errors']:>8}")
    lines.append("")
    lines.append("Per home (scenarios that ended right / scenarios; ! wrong successes, "
                 "E errors)")
    width = max([len(w) for w in rep["per_home"]] + [6]) + 2
    lines.append("  " + "home".ljust(width) + "".join(f"{m:>22}" for m in missions))
    for w, ms in rep["per_home"].items():
        cells = []
        for m in missions:
            c = ms.get(m)
            if c is None:
                cells.append(f"{'-':>22}")
                continue
            mark = (f" !{c['wrong_success']}" if c["wrong_success"] else "") + \
                   (f" E{c['errors']}" if c["errors"] else "")
            cells.append(f"{_frac(c['correct'], c['scenarios']) + mark:>22}")
        lines.append("  " + w.ljust(width) + "".join(cells))
    ws = rep["wrong_success"]
    lines.append("")
    if ws["total"]:
        lines.append(f"Wrong successes: {ws['total']} (by home: {_pairs(ws['by_world'])}; by "
                     f"object type: {_pairs(ws['by_object_type'])})")
    else:
        lines.append("Wrong successes: none")
    if rep["slowest"]:
        lines.append("")
        lines.append("Slowest scenarios (wall seconds)")
        for s in rep["slowest"][:top]:
            lines.append(f"  {s['wall_time_s']:>7.1f} s  {s['world']} {s['mission']} "
                         f"{s['target'] or ''} seed {s['seed']}"
                         f"{'' if s['learned'] else ' (fixed order)'}: {s['outcome']}")
    if rep["problems"]:
        lines.append("")
        lines.append(f"Problems: {_pairs(rep['problem_counts'])}")
        for p in rep["problems"]:
            lines.append(f"  {p['world']} {p['mission']} {p['target'] or ''} seed {p['seed']}: "
                         f"{p['error'] or 'error'}: {p['reason']}")
            for tl in (p["traceback"] or "").rstrip().splitlines()[-12:]:
                lines.append(f"      {tl}")
    return "\n".join(lines)


def _frac(k: int, n: int) -> str:
    return f"{k}/{n} {k / n:.2f}" if n else "-"


def _pairs(d: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(d.items())) or "none"


def render_png(rep: dict, path) -> Path:
    """Success per home (rows) and mission (columns) as a grid: each cell coloured from red
    (none ended right) to green (all did), with the count; ``!N`` wrong successes, ``EN``
    errors (crashed, timed out, raised). OpenCV, no plotting library."""
    import cv2
    import numpy as np
    missions = list(rep["per_mission"])
    homes = list(rep["per_home"])
    font, cell_w, cell_h, pad = cv2.FONT_HERSHEY_SIMPLEX, 190, 44, 12
    label_w = max([cv2.getTextSize(h, font, 0.5, 1)[0][0] for h in homes] + [60]) + 2 * pad
    top, bottom = 70, 70
    total = sum(c["scenarios"] for c in rep["per_mission"].values())
    ok = sum(c["correct"] for c in rep["per_mission"].values())
    title = (f"hearth suite: {ok}/{total} scenarios ended right, "
             f"{rep['wrong_success']['total']} wrong successes, {len(rep['problems'])} errors")
    legend = "0 % ... 100 % ended right;  !N wrong successes;  EN errors"
    W = max(label_w + cell_w * max(1, len(missions)),
            cv2.getTextSize(title, font, 0.55, 1)[0][0],
            250 + cv2.getTextSize(legend, font, 0.45, 1)[0][0]) + 2 * pad
    H = top + cell_h * max(1, len(homes)) + bottom
    img = np.full((H, W, 3), 255, np.uint8)
    cv2.putText(img, title, (pad, 26), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for j, m in enumerate(missions):
        x = label_w + j * cell_w
        cv2.putText(img, m, (x + 6, top - 12), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    for i, h in enumerate(homes):
        y = top + i * cell_h
        cv2.putText(img, h, (pad, y + cell_h // 2 + 5), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        for j, m in enumerate(missions):
            x = label_w + j * cell_w
            c = rep["per_home"][h].get(m)
            if c is None or not c["scenarios"]:
                colour, text = (235, 235, 235), "-"
            else:
                colour = _colour(c["correct"] / c["scenarios"])
                text = f"{c['correct']}/{c['scenarios']}"
                if c["wrong_success"]:
                    text += f"  !{c['wrong_success']}"
                if c["errors"]:
                    text += f"  E{c['errors']}"
            cv2.rectangle(img, (x, y), (x + cell_w - 2, y + cell_h - 2), colour, -1)
            cv2.putText(img, text, (x + 10, y + cell_h // 2 + 6), font, 0.55, (20, 20, 20), 1,
                        cv2.LINE_AA)
    y = H - bottom + 22
    for k in range(11):
        x = pad + k * 22
        cv2.rectangle(img, (x, y), (x + 20, y + 14), _colour(k / 10), -1)
    cv2.putText(img, legend, (pad + 250, y + 12), font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _, png = cv2.imencode(".png", img)
    _write_atomic(path, png.tobytes())
    return path


def _colour(f: float) -> tuple[int, int, int]:
    """Red (0) through yellow to green (1), BGR."""
    f = min(1.0, max(0.0, f))
    r = 220 if f < 0.5 else int(220 - (f - 0.5) * 2 * 150)
    g = int(80 + f * 2 * 120) if f < 0.5 else 200
    return (90, g, r)
