"""The local engine of hearth/executive/suite.py: spawned worker processes on this machine, one
scenario at a time each; a worker that does not answer its scenario's alarm is killed and
replaced."""
from __future__ import annotations

import math
import os
import time
import traceback
from typing import Callable, Optional

from hearth.executive.suite_bundles import (
    describe_need, model_needs, ModelNeed, stored_model, train_model,
)
from hearth.executive.suite_worker import (
    DEFAULT_TIMEOUT_S, execute, failure, hard_limit_s, prepare_process,
)


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
