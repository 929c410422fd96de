"""One scenario in a suite's worker process (hearth/executive/suite.py): the suite's constants
and error, a case's key and its result without what varies between runs, running a case under
its time limit (``execute``: the alarm), the result of a case that did not finish
(``failure``) and a worker's set-up (``prepare_process``: one thread per numeric library, a
private folder for an isolated worker)."""
from __future__ import annotations

import hashlib
import json
import os
import time
import traceback
from dataclasses import asdict
from pathlib import Path
from typing import Callable, Optional

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
# Cases and results
# ---------------------------------------------------------------------------------------
def case_key(case) -> str:
    """A case's identity in a results file: a hash of all its fields."""
    d = case if isinstance(case, dict) else asdict(case)
    if not d.get("models"):     # the drawn models: the key cases had before there was a choice
        d = {k: v for k, v in d.items() if k != "models"}
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
