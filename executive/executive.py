"""The Executive: runs missions one at a time, ticking a py_trees tree in a background thread.

    ex = Executive(world, robot, clock=SimClock(), tick_hz=10)
    h = ex.submit("missions/go_to_rest.yaml", presence="away")
    h.subscribe(print)                   # Event objects, from the tick thread
    ex.set_parameter("presence", "home") # a watch guard restarts what depends on it
    h.wait(5.0); h.result                # MissionResult(outcome, reason, outputs, ...)

Lifecycle (a ``transitions`` machine per mission): ``queued -> running -> succeeded |
failed``, ``running -> halting -> cancelled | preempted``, ``queued -> cancelled``.
``halting`` lasts while halted skills report ``is_halting()`` (bounded by their
HALT_TIMEOUT); the mission is reported cancelled only after it.

Concurrency: every decision is taken on the tick thread (or the caller of ``tick()`` when
``background=False``) under one lock. ``cancel()``, ``submit()`` and ``set_parameter()``
only record requests under that lock; the next step acts on them before ticking. A cancel
is therefore never lost: on a queued mission it takes effect at once; during start-up
(skill setup) or while halting it is recorded and honoured; after the end it returns False.

Time: with a simulated clock (``clock.simulated``) each tick advances it by ``1/tick_hz``
and the thread does not sleep, so runs are deterministic and fast; with a wall clock the
thread sleeps to keep the rate.
"""
from __future__ import annotations

import heapq
import itertools
import json
import logging
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from py_trees import common
from transitions import Machine

from executive import nodes, treetick
from executive.errors import MissionError, MissionValidationError
from executive.missionfile import Mission, load_mission, plain, skill_registry
from executive.tree import BuiltTree, SkillFactory, build_tree

Status = common.Status
log = logging.getLogger("hearth.executive")

STATES = ["queued", "running", "halting", "succeeded", "failed", "cancelled", "preempted"]
TERMINAL = ("succeeded", "failed", "cancelled", "preempted")
LOG_FORMAT = 1
_ns_counter = itertools.count(1)
_VALUE = {s: s.value for s in Status}
_PAIRS = {(a, b): f', "status": "{a.value}", "previous": "{b.value}"}}\n'
          for a in Status for b in Status}


@dataclass
class Event:
    """One thing that happened in a run.

    ``kind``: ``run`` (lifecycle; data ``state``, ``reason``), ``status`` (``status``,
    ``previous``; ``halted`` when a node was stopped from above), ``feedback``
    (``message``), ``write`` (``key``, ``value``, ``port``: a declared key written by
    ``path``), ``param`` (``name``, ``value``), ``restart`` (a watch guard restarted,
    ``changed``), ``map`` (``node``, ``field``, ``old``, ``new``, ``source``, ``map_time``),
    ``stopped`` (a halted skill no longer reports ``is_halting()``), ``halted``
    (mission-level halting finished; ``waited``, ``timed_out``), ``tick`` (wall-clock runs
    only: each tick's time).
    ``tick`` is the tick number (0-based), ``time`` the clock time in seconds.
    """
    kind: str
    run: str
    tick: int
    time: float
    path: str | None = None
    data: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out = {"e": self.kind, "run": self.run, "tick": self.tick, "t": round(self.time, 9)}
        if self.path is not None:
            out["path"] = self.path
        out.update(self.data)
        return out


@dataclass
class MissionResult:
    """How a mission ended: ``outcome`` is succeeded, failed, cancelled or preempted;
    ``reason`` says why in words; ``outputs`` are the mission's blackboard keys at the end;
    ``ticks`` the number of ticks; ``duration`` clock seconds from start to end."""
    outcome: str
    reason: str
    outputs: dict[str, Any]
    ticks: int = 0
    duration: float = 0.0
    log_path: str | None = None


class _Lifecycle:
    """The transitions model of one mission (attribute ``state``)."""


class MissionHandle:
    """What ``submit`` returns: watch, wait for and cancel one mission. Thread-safe."""

    def __init__(self, executive: "Executive", run_id: str, mission: Mission, priority: int,
                 params: dict[str, Any]):
        self._ex = executive
        self.id = run_id
        self.mission = mission
        self.priority = priority
        self.params = params
        self.result: MissionResult | None = None
        self.log_path: str | None = None
        self._done = threading.Event()
        self._subscribers: list[Callable[[Event], None]] = []
        self._life = _Lifecycle()
        self._machine = Machine(model=self._life, states=STATES, initial="queued",
                                auto_transitions=False)
        m = self._machine
        m.add_transition("start", "queued", "running")
        m.add_transition("succeed", "running", "succeeded")
        m.add_transition("fail", ["queued", "running"], "failed")
        m.add_transition("halt", "running", "halting")
        m.add_transition("cancel_queued", "queued", "cancelled")
        m.add_transition("end_cancel", "halting", "cancelled")
        m.add_transition("end_preempt", "halting", "preempted")
        self._given: set[str] = set()   # parameters given to submit (not from runtime values)
        # Requests recorded by other threads, acted on by the tick thread.
        self._cancel_request: tuple[str, str] | None = None   # (final state, reason)

    @property
    def status(self) -> str:
        """queued, running, halting, succeeded, failed, cancelled or preempted."""
        return self._life.state

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def cancel(self, reason: str = "cancelled") -> bool:
        """Ask the mission to stop. True if it will end cancelled (or was already being
        halted); False if it had already ended. Never blocks on the robot."""
        return self._ex._request_cancel(self, "cancelled", reason)

    def wait(self, timeout: float | None = None) -> MissionResult | None:
        """Block until the mission ends (``timeout`` in real seconds); its result or None."""
        self._done.wait(timeout)
        return self.result

    def subscribe(self, callback: Callable[[Event], None]) -> Callable[[], None]:
        """Call ``callback(event)`` for each event of this mission (from the tick thread).
        Returns a function that unsubscribes."""
        with self._ex._lock:
            self._subscribers.append(callback)

        def unsubscribe() -> None:
            with self._ex._lock:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)
        return unsubscribe

    def __repr__(self) -> str:
        return f"<MissionHandle {self.id} {self.mission.name} {self.status}>"


class _Run:
    """A started mission: its tree, tick counter, log, change tracking and halting state."""

    def __init__(self, ex: "Executive", handle: MissionHandle):
        self.ex = ex
        self.handle = handle
        self.tree: BuiltTree | None = None
        self.tick = 0
        self.t0 = 0.0
        self.last: dict[Any, Status] = {}
        self.running: dict = {}
        self.feedback: dict[Any, str] = {}
        self.halting: list = []
        self.halt_deadline = 0.0
        self.halt_started = 0.0
        self.logfile = None
        self.now = 0.0              # clock time of the current tick
        self.now_json = "0.0"
        self.quiet = True           # no subscribers: log lines are written directly
        self.path_json: dict[int, str] = {}
        self.run_json = json.dumps(handle.id)


class Executive:
    """Owns a world model and a robot adapter; runs submitted missions.

    ``world``: the belief map (if it has ``subscribe(callback) -> unsubscribe``, its changes
    become ``map`` events). ``robot``: the robot adapter (``robot.stop()`` is called after a
    cancel or preempt if it exists). ``clock``: WallClock (default) or SimClock.
    ``tick_hz``: ticks per second. ``runs_dir``: where execution logs go (None: no logs).
    ``skills``: name -> Skill class (default: the ``skills`` package registry).
    ``equal_priority``: "queue" (default) or "preempt" (a new mission of the same priority
    preempts the running one). ``make_skill``: how skill nodes are instantiated (skill
    substitution; see executive.testing). ``background``: run the tick thread (False: call
    ``tick()`` yourself, as tests and ``hearth step`` do). ``autonomy``: the highest skill
    AUTONOMY level granted (None: no limit); ``submit`` refuses a mission using a skill above
    it, naming each such skill with file and line.
    """

    def __init__(self, world: Any = None, robot: Any = None, clock: Any = None,
                 tick_hz: float = 10.0, runs_dir: str | os.PathLike | None = "runs",
                 skills: dict[str, type] | None = None, equal_priority: str = "queue",
                 make_skill: SkillFactory | None = None, background: bool = True,
                 setup_kwargs: dict[str, Any] | None = None, autonomy: int | None = None):
        if tick_hz <= 0:
            raise ValueError("tick_hz must be positive")
        if equal_priority not in ("queue", "preempt"):
            raise ValueError("equal_priority is 'queue' or 'preempt'")
        if clock is None:
            from hearth.robot.clock import WallClock
            clock = WallClock()
        self.world = world
        self.robot = robot
        self.clock = clock
        self._simulated = bool(getattr(clock, "simulated", False))
        self.tick_hz = float(tick_hz)
        self.period = 1.0 / self.tick_hz
        self.runs_dir = Path(runs_dir) if runs_dir is not None else None
        self.skills = skills
        self.equal_priority = equal_priority
        self.make_skill = make_skill
        self.setup_kwargs = dict(setup_kwargs or {})
        self.autonomy = autonomy
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self._queue: list[tuple[int, int, MissionHandle]] = []
        self._seq = itertools.count()
        self._current: _Run | None = None
        self._starting: MissionHandle | None = None
        self._params: dict[str, Any] = {}
        self._param_changes: list[tuple[str, Any]] = []
        self._subscribers: list[Callable[[Event], None]] = []
        self._map_events: list[dict[str, Any]] = []
        self._closed = False
        self._unsubscribe_world = None
        if world is not None and callable(getattr(world, "subscribe", None)):
            self._unsubscribe_world = world.subscribe(self._on_map_change)
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._loop, name="hearth-tick", daemon=True)
            self._thread.start()

    # -- public API ----------------------------------------------------------------------
    def load(self, mission: str | os.PathLike | Mission) -> Mission:
        if isinstance(mission, Mission):
            return mission
        if self.skills is None:
            self.skills = skill_registry()
        return load_mission(mission, self.skills)

    def submit(self, mission: str | os.PathLike | Mission, priority: int = 0,
               **params: Any) -> MissionHandle:
        """Queue a mission (a path or a loaded Mission) with parameter values.

        Raises MissionValidationError / MissionError(param=) at once for a bad mission or
        parameter. A higher ``priority`` preempts the running mission; equal priorities
        queue (or preempt, see ``equal_priority``)."""
        mission = self.load(mission)
        self._check_autonomy(mission)
        with self._lock:
            if self._closed:
                raise MissionError("the executive has been shut down")
            values = mission.resolve_parameters(params, self._params)
            run_id = self._new_run_id(mission.name)
            handle = MissionHandle(self, run_id, mission, priority, values)
            handle._given = set(params)
            heapq.heappush(self._queue, (-priority, next(self._seq), handle))
            cur = self._current.handle if self._current is not None else self._starting
            if cur is not None and not cur.done and (
                    priority > cur.priority
                    or (priority == cur.priority and self.equal_priority == "preempt")):
                self._request_cancel(cur, "preempted", f"preempted by {mission.name} ({run_id})")
            self._wake.notify_all()
        return handle

    def _check_autonomy(self, mission: Mission) -> None:
        if self.autonomy is None:
            return
        problems = [MissionError(f"skill {n.skill_name} acts with autonomy {n.skill.AUTONOMY}, "
                                 f"above the granted level {self.autonomy}", file=n.file,
                                 line=n.line)
                    for n in mission.nodes()
                    if n.kind == "skill" and getattr(n.skill, "AUTONOMY", 0) > self.autonomy]
        if problems:
            raise MissionValidationError(problems)

    def set_parameter(self, name: str, value: Any) -> None:
        """Set a runtime parameter (e.g. ``presence``) for this and later missions. A running
        mission that declares it with ``runtime: true`` sees the new value from its next
        tick; watch guards on it restart their subtree."""
        with self._lock:
            missions = [h.mission for _, _, h in self._queue]
            if self._current is not None:
                missions.append(self._current.handle.mission)
            for mission in missions:
                spec = mission.parameters.get(name)
                if spec is not None and spec.runtime:
                    spec.check(value)
            self._params[name] = value
            self._param_changes.append((name, value))
            self._wake.notify_all()

    @property
    def parameters(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._params)

    def subscribe(self, callback: Callable[[Event], None]) -> Callable[[], None]:
        """Events of every mission. Returns an unsubscribe function."""
        with self._lock:
            self._subscribers.append(callback)

        def unsubscribe() -> None:
            with self._lock:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)
        return unsubscribe

    @property
    def current(self) -> MissionHandle | None:
        with self._lock:
            return self._current.handle if self._current is not None else None

    @property
    def current_tree(self) -> BuiltTree | None:
        with self._lock:
            return self._current.tree if self._current is not None else None

    @property
    def queued(self) -> list[MissionHandle]:
        with self._lock:
            return [h for _, _, h in sorted(self._queue) if h.status == "queued"]

    def idle(self) -> bool:
        with self._lock:
            return self._current is None and self._starting is None and not any(
                h.status == "queued" for _, _, h in self._queue)

    def tick(self) -> bool:
        """One executive step: start a queued mission, apply parameter changes and cancel
        requests, then tick (or keep halting). Returns False when there was nothing to do.
        Only for ``background=False``; the tick thread calls it otherwise."""
        if self._thread is not None and threading.current_thread() is not self._thread:
            raise RuntimeError("Executive.tick() is for background=False executives")
        did = self._step()
        if did and self._simulated:
            self.clock.advance(self.period)
        return did

    def run_until_idle(self, max_ticks: int = 1_000_000) -> int:
        """Tick (background=False) until no mission is running or queued; ticks done.
        With a wall clock it keeps the tick rate (sleeps between ticks)."""
        n = 0
        next_tick = self.clock.now()
        while n < max_ticks and self.tick():
            n += 1
            if not self._simulated:
                next_tick += self.period
                delay = next_tick - self.clock.now()
                if delay > 0:
                    self.clock.sleep(delay)
                else:
                    next_tick = self.clock.now()
        return n

    def shutdown(self, timeout: float = 5.0) -> None:
        """Cancel everything, wait (``timeout`` real seconds) for the tick thread, detach."""
        with self._lock:
            self._closed = True
            for _, _, h in self._queue:
                self._request_cancel(h, "cancelled", "executive shut down")
            if self._current is not None:
                self._request_cancel(self._current.handle, "cancelled", "executive shut down")
            self._wake.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
        else:
            self.run_until_idle(max_ticks=100_000)
        if self._unsubscribe_world is not None:
            try:
                self._unsubscribe_world()
            except Exception:  # noqa: BLE001
                pass
            self._unsubscribe_world = None

    def __enter__(self) -> "Executive":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.shutdown()

    # -- requests ------------------------------------------------------------------------
    def _request_cancel(self, handle: MissionHandle, final: str, reason: str) -> bool:
        with self._lock:
            state = handle.status
            if state in TERMINAL:
                return False
            if state == "queued" and handle is not self._starting:
                handle._life.cancel_queued()
                self._queue = [q for q in self._queue if q[2] is not handle]
                heapq.heapify(self._queue)
                self._finish(handle, None, "cancelled", reason)
                return True
            if handle._cancel_request is None or (
                    final == "cancelled" and handle._cancel_request[0] == "preempted"):
                # A user cancel during a preempt turns it into a cancel; never the reverse.
                handle._cancel_request = (final, reason)
            self._wake.notify_all()
            return True

    def _on_map_change(self, change: Any) -> None:
        data = {a: plain(getattr(change, a, None)) for a in ("node", "field", "old", "new",
                                                              "source")}
        data["map_time"] = getattr(change, "time", None)
        with self._lock:
            self._map_events.append(data)

    # -- the loop ------------------------------------------------------------------------
    def _loop(self) -> None:
        simulated = getattr(self.clock, "simulated", False)
        next_tick = self.clock.now()
        while True:
            with self._lock:
                while not self._closed and self.idle():
                    self._wake.wait(0.5)
                if self._closed and self.idle():
                    return
            try:
                did = self._step()
            except Exception:  # noqa: BLE001 - the thread must survive a broken skill
                log.exception("executive step failed")
                did = True
            if simulated:
                if did:
                    self.clock.advance(self.period)
            else:
                next_tick += self.period
                delay = next_tick - self.clock.now()
                if delay > 0:
                    self.clock.sleep(delay)
                else:
                    next_tick = self.clock.now()

    def _step(self) -> bool:
        with self._lock:
            run = self._current
            if run is not None:
                return self._step_run(run)
            handle = self._pop_next()
            if handle is None:
                self._param_changes.clear()
                self._map_events.clear()
                return False
            self._starting = handle
        run = self._start(handle)   # outside the lock: skill setup may take a while
        with self._lock:
            self._starting = None
            if run is None:
                return True
            self._current = run
            return self._step_run(run)

    def _step_run(self, run: _Run) -> bool:
        """Apply requests, then tick once or poll halting skills once (lock held)."""
        run.now = self.clock.now()
        run.now_json = repr(round(run.now, 9))
        run.quiet = not (run.handle._subscribers or self._subscribers)
        self._apply_requests(run)
        if run.handle.status == "halting":
            self._poll_halting(run)
        else:
            self._tick(run)
        run.tick += 1
        return True

    def _pop_next(self) -> MissionHandle | None:
        while self._queue:
            _, _, h = heapq.heappop(self._queue)
            if h.status == "queued":
                return h
        return None

    def _start(self, handle: MissionHandle) -> _Run | None:
        run = _Run(self, handle)
        run.t0 = run.now = self.clock.now()
        run.now_json = json.dumps(round(run.now, 9))
        try:
            with self._lock:
                handle._life.start()
                # Runtime values may have changed while the mission was queued.
                for name in handle.mission.runtime_parameters():
                    if name not in handle._given and name in self._params:
                        handle.params[name] = self._params[name]
                ns = f"/hearth/r{next(_ns_counter)}"
                run.tree = build_tree(handle.mission, handle.params, ns, self.make_skill)
                for node in run.tree.root.iterate():
                    if hasattr(node, "output_hook"):
                        node.output_hook = self._make_output_hook(run)
                    if isinstance(node, nodes.Watch):
                        node.on_restart = self._make_restart_hook(run)
                        node.on_stopped = self._make_stopped_hook(run)
                    node.hearth_leaf = not node.children
                    node.hearth_path_json = json.dumps(run.tree.path_of[id(node)])
                    run.path_json[id(node)] = node.hearth_path_json
                self._open_log(run)
                self._emit(run, "run", None, state="running", reason="started")
            run.tree.setup(world=self.world, robot=self.robot, clock=self.clock,
                           executive=self, **self.setup_kwargs)
        except Exception as err:  # noqa: BLE001 - a skill that cannot set up fails the mission
            with self._lock:
                if handle.status == "running":
                    handle._life.fail()
                else:
                    handle._life.start()
                    handle._life.fail()
                reason = f"setup failed: {err}"
                self._emit(run, "run", None, state="failed", reason=reason)
                self._end(run, "failed", reason)
            return None
        return run

    def _apply_requests(self, run: _Run) -> None:
        tree = run.tree
        if self._param_changes:
            declared = run.handle.mission.parameters
            for name, value in self._param_changes:
                spec = declared.get(name)
                if spec is not None and spec.runtime:
                    tree.write_param(name, value)
                    self._emit(run, "param", None, name=name, value=plain(value))
            self._param_changes.clear()
        if self._map_events:
            for data in self._map_events:
                self._emit(run, "map", None, **data)
            self._map_events.clear()
        req = run.handle._cancel_request
        if req is not None and run.handle.status == "running":
            final, reason = req
            run.handle._life.halt()
            self._emit(run, "run", None, state="halting", reason=reason, final=final)
            running = nodes.running_skills(tree.root)
            self._halt_tree(tree.root)
            self._diff(run, {})
            run.halting = nodes.still_halting(running, self._make_stopped_hook(run))
            run.halt_started = self.clock.now()
            run.halt_deadline = run.halt_started + nodes.halt_timeout(run.halting)

    @staticmethod
    def _halt_tree(root: Any) -> None:
        """Halt every running node, deepest first; a terminate that raises does not keep the
        others from being halted."""
        try:
            if root.status != Status.INVALID:
                root.stop(Status.INVALID)
            return
        except Exception:  # noqa: BLE001
            log.exception("halting the tree failed; halting node by node")
        for node in root.iterate():          # children before parents
            if node.status != Status.INVALID:
                try:
                    node.stop(Status.INVALID)
                except Exception:  # noqa: BLE001
                    log.exception("terminate failed on %s", node.name)
                    node.status = Status.INVALID

    def _stop_robot(self) -> None:
        stop = getattr(self.robot, "stop", None)
        if callable(stop):
            try:
                stop()
            except Exception:  # noqa: BLE001 - a failing stop must not wedge the executive
                log.exception("robot.stop() failed")

    def _poll_halting(self, run: _Run) -> None:
        run.halting = nodes.still_halting(run.halting, self._make_stopped_hook(run))
        now = self.clock.now()
        if run.halting and now < run.halt_deadline:
            return
        if run.halting:
            names = ", ".join(run.tree.path_of.get(id(s), s.name) for s in run.halting)
            log.warning("gave up waiting for %s to stop", names)
        final, reason = run.handle._cancel_request
        self._emit(run, "halted", None, waited=round(now - run.halt_started, 9),
                   timed_out=[run.tree.path_of.get(id(s), s.name) for s in run.halting])
        self._stop_robot()
        if final == "preempted":
            run.handle._life.end_preempt()
        else:
            run.handle._life.end_cancel()
        self._emit(run, "run", None, state=final, reason=reason)
        self._end(run, final, reason)

    def _tick(self, run: _Run) -> None:
        root = run.tree.root
        if not self._simulated:
            self._emit(run, "tick", None)
        try:
            # Each node's status as it is yielded (a parent may still stop it later on).
            visited = treetick.tick(root)
        except Exception as err:  # noqa: BLE001 - a crashing skill fails the mission
            log.exception("tick failed")
            self._halt_tree(root)
            self._stop_robot()
            run.handle._life.fail()
            reason = f"{type(err).__name__}: {err}"
            self._emit(run, "run", None, state="failed", reason=reason)
            self._end(run, "failed", reason)
            return
        self._diff(run, visited)
        status = root.status
        if status in (Status.SUCCESS, Status.FAILURE):
            reason = self._reason(run, status)
            if status == Status.SUCCESS:
                run.handle._life.succeed()
                final = "succeeded"
            else:
                run.handle._life.fail()
                final = "failed"
            self._emit(run, "run", None, state=final, reason=reason)
            self._end(run, final, reason)

    def _reason(self, run: _Run, status: Status) -> str:
        """In words: the deepest failing node's feedback, or 'completed'."""
        if status == Status.SUCCESS:
            return "completed"
        node = run.tree.root
        while True:
            failed = [c for c in node.children if c.status == Status.FAILURE]
            if not failed:
                break
            node = failed[-1]
        path = run.tree.path_of.get(id(node), node.name)
        return f"{path} failed" + (f": {node.feedback_message}" if node.feedback_message else "")

    def _status_event(self, run: _Run, node: Any, st: Status, prev: Status,
                      halted: bool = False) -> None:
        if run.quiet:
            # The hot path (no subscribers): format the log line directly.
            if run.logfile is not None:
                run.logfile.write(
                    f'{{"e": "status", "run": {run.run_json}, "tick": {run.tick}, '
                    f'"t": {run.now_json}, "path": {run.path_json[id(node)]}, '
                    f'"status": "{_VALUE[st]}", "previous": "{_VALUE[prev]}"'
                    + (', "halted": true}\n' if halted else "}\n"))
            return
        data = {"status": st.value, "previous": prev.value}
        if halted:
            data["halted"] = True
        self._emit(run, "status", run.tree.path_of[id(node)], **data)

    def _diff(self, run: _Run, visited: dict) -> None:
        """Status and feedback events for what changed in this tick.

        ``visited`` maps each node ticked to its status as it was yielded. A visited leaf
        that starts again (previous status not RUNNING) is reported even when its status
        repeats, so replay sees every activation. Nodes stopped from above (halted) without
        being ticked, or changed after being yielded, are reported with ``halted``."""
        last, feedback = run.last, run.feedback
        RUNNING, INVALID = Status.RUNNING, Status.INVALID
        # Hot path: no subscribers, so status lines are formatted straight into the log.
        buffered = run.quiet and run.logfile is not None
        out: list[str] = []
        if buffered:
            head = (f'{{"e": "status", "run": {run.run_json}, "tick": {run.tick}, '
                    f'"t": {run.now_json}, "path": ')
            pairs = _PAIRS
        emit = self._status_event
        running: dict = {}   # ordered as ticked: children before parents, deepest first
        running_add = running.setdefault
        changed_after = []
        for node, st in visited.items():
            prev = last.get(node, INVALID)
            if st is not prev or (prev is not RUNNING and node.hearth_leaf):
                if buffered:
                    out.append(head + node.hearth_path_json + pairs[st, prev])
                else:
                    emit(run, node, st, prev)
                last[node] = st
            fb = node.feedback_message
            if fb and fb != feedback.get(node):
                feedback[node] = fb
                if out:
                    run.logfile.write("".join(out))
                    out.clear()
                self._emit(run, "feedback", run.tree.path_of[id(node)], message=fb)
            if node.status is not st:
                changed_after.append(node)
            elif st is RUNNING:
                running_add(node)
        if out:
            run.logfile.write("".join(out))
        for node in run.running:
            if node not in visited:
                final = node.status
                prev = last.get(node, INVALID)
                if final is not prev:
                    emit(run, node, final, prev, True)
                    last[node] = final
                if final is RUNNING:
                    running_add(node)
        for node in changed_after:
            final = node.status
            emit(run, node, final, last[node], True)
            last[node] = final
            if final is RUNNING:
                running_add(node)
        run.running = running

    def _make_output_hook(self, run: _Run) -> Callable:
        def hook(node: Any, port: str, key: str, value: Any) -> None:
            self._emit(run, "write", run.tree.path_of.get(id(node)), port=port,
                       key=run.tree.short_key(key), value=plain(value))
        return hook

    def _make_stopped_hook(self, run: _Run) -> Callable:
        def hook(node: Any) -> None:
            self._emit(run, "stopped", run.tree.path_of.get(id(node)))
        return hook

    def _make_restart_hook(self, run: _Run) -> Callable:
        def hook(node: Any, changed: dict) -> None:
            self._emit(run, "restart", run.tree.path_of.get(id(node)),
                       changed={k: [plain(o), plain(n)] for k, (o, n) in changed.items()})
        return hook

    # -- events and logs -------------------------------------------------------------------
    def _emit(self, run: _Run, kind: str, path: str | None, **data: Any) -> None:
        if not (run.logfile or run.handle._subscribers or self._subscribers):
            return
        ev = Event(kind, run.handle.id, run.tick, run.now, path, data)
        if run.logfile is not None:
            run.logfile.write(json.dumps(ev.to_json(), default=repr) + "\n")
        for cb in list(run.handle._subscribers) + list(self._subscribers):
            try:
                cb(ev)
            except Exception:  # noqa: BLE001 - a broken subscriber must not stop the robot
                log.exception("event subscriber failed")

    def _open_log(self, run: _Run) -> None:
        if self.runs_dir is None:
            return
        self.runs_dir.mkdir(parents=True, exist_ok=True)
        path = self.runs_dir / f"{run.handle.id}.jsonl"
        run.logfile = open(path, "w", encoding="utf-8")  # noqa: SIM115 - closed in _end
        run.handle.log_path = str(path)
        m = run.handle.mission
        sources = {}
        for f in m.files:
            try:
                sources[f] = Path(f).read_text(encoding="utf-8")
            except OSError:
                pass
        header = {"e": "start", "format": LOG_FORMAT, "run": run.handle.id, "tick": 0,
                  "t": run.t0, "wall": self.clock.wall(), "mission": m.name, "file": m.file,
                  "sources": sources, "params": plain(run.handle.params),
                  "priority": run.handle.priority, "tick_hz": self.tick_hz,
                  "clock": "sim" if getattr(self.clock, "simulated", False) else "wall",
                  "ns": run.tree.ns}
        run.logfile.write(json.dumps(header, default=repr) + "\n")

    def _end(self, run: _Run, outcome: str, reason: str) -> None:
        outputs = run.tree.outputs() if run.tree is not None else {}
        result = MissionResult(outcome=outcome, reason=reason, outputs=plain(outputs),
                               ticks=run.tick + (1 if outcome in ("succeeded", "failed") else 0),
                               duration=self.clock.now() - run.t0,
                               log_path=run.handle.log_path)
        if run.logfile is not None:
            run.logfile.write(json.dumps({"e": "end", "run": run.handle.id, "tick": run.tick,
                                          "t": self.clock.now(), "outcome": outcome,
                                          "reason": reason, "outputs": result.outputs},
                                         default=repr) + "\n")
            run.logfile.close()
            run.logfile = None
        if run.tree is not None:
            run.tree.teardown()
        if self._current is run:
            self._current = None
        self._finish(run.handle, run, outcome, reason, result)

    def _finish(self, handle: MissionHandle, run: _Run | None, outcome: str, reason: str,
                result: MissionResult | None = None) -> None:
        handle.result = result or MissionResult(outcome=outcome, reason=reason, outputs={})
        handle._done.set()
        if run is None:
            ev = Event("run", handle.id, 0, self.clock.now(), None,
                       {"state": outcome, "reason": reason})
            for cb in list(handle._subscribers) + list(self._subscribers):
                try:
                    cb(ev)
                except Exception:  # noqa: BLE001
                    log.exception("event subscriber failed")
        self._wake.notify_all()

    def _new_run_id(self, name: str) -> str:
        import time as _time
        stamp = _time.strftime("%Y%m%dT%H%M%S", _time.gmtime(self.clock.wall()))
        n = next(self._seq)
        rid = f"{stamp}-{name}-{n}"
        if self.runs_dir is not None:
            while (self.runs_dir / f"{rid}.jsonl").exists():
                n = next(self._seq)
                rid = f"{stamp}-{name}-{n}"
        return rid
