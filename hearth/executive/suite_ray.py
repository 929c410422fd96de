"""The ray engine of hearth/executive/suite.py: one Ray task per scenario; worlds and models
travel through the object store and, when joining a cluster, Hearth's own code too (each task
starts in hearth/executive/suite_boot.py)."""
from __future__ import annotations

import os
import sys
import time
import traceback
from pathlib import Path
from typing import Any, Callable, Optional

from hearth.executive.suite_bundles import (
    arrived_world, bundle_fingerprint, describe_need, keep_model, model_needs, ModelNeed,
    stored_model, train_model, unpack_world, world_bundle, _write_atomic,
)
from hearth.executive.suite_worker import (
    DEFAULT_TIMEOUT_S, execute, failure, hard_limit_s, PACKAGES, prepare_process,
    RAY_MISSING, SuiteError, _WORKER,
)


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
                call = self.ray.cloudpickle.dumps((_ray_train, (need,)))
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
                (_ray_case, (case, task["key"], self.runner, self.timeout, fp)))
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
