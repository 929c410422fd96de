"""The Executive: runs missions one at a time, ticking a py_trees tree in a background thread.

    ex = Executive(world, robot, clock=SimClock(), tick_hz=10)
    h = ex.submit("missions/go_to_rest.yaml", presence="away")
    h.subscribe(print)                   # Event objects, outside the executive's lock
    ex.set_parameter("presence", "home") # a watch guard restarts what depends on it
    h.wait(5.0); h.result                # MissionResult(outcome, reason, outputs, ...)

The pieces: hearth/executive/scheduler.py (submissions, lifecycle, queue, priority, preemption),
hearth/executive/ticking.py (the tick loop and a started mission's tick and status diffing),
hearth/executive/treetick.py (ticking a tree without generators), hearth/executive/runlog.py (execution
logs), hearth/executive/events.py (event kinds, events, results, delivery to subscribers). This
module decides: when a mission starts, how requests are applied, how halting ends.

Concurrency: every decision is taken on the tick thread (or the caller of ``tick()`` when
``background=False``) under one lock. ``cancel()``, ``submit()`` and ``set_parameter()``
only record requests under that lock; the next step acts on them before ticking. A cancel
is therefore never lost: on a queued mission it takes effect at once; during start-up
(skill setup) or while halting it is recorded and honoured; after the end it returns False.
Subscribers are never called with the lock held: events are posted to an outbox and
delivered by a delivery thread (background) or at the end of ``tick()``.

The cancel promise: a cancel or preempt is reported (the mission ends cancelled or
preempted) only after every halted skill has stopped what it started on the robot (it no
longer reports ``is_halting()``) and ``robot.stop()`` has been called. The wait is bounded by
the largest HALT_TIMEOUT of the halted skills (5 s by default); a skill still stopping after
it ends the mission with reason "cancelled, robot not confirmed stopped (...)" and
``robot_stopped: false`` in its run event, its log's end line and its result. Every submitted
mission, queued ones included, ends with a log (``runs_dir``) that says how it ended.

Time: with a simulated clock (``clock.simulated``) each tick advances it by ``1/tick_hz``
and the thread does not sleep, so runs are deterministic and fast; with a wall clock the
thread sleeps to keep the rate.
"""
from __future__ import annotations

import contextlib
import itertools
import logging
import math
import os
import threading
import time as _time
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable

from py_trees import common

from hearth.executive.errors import MissionError, MissionValidationError
from hearth.executive.events import TERMINAL, Event, EventKind, MissionResult, Outbox, RunState
from hearth.executive.missionfile import Mission, load_mission, plain, skill_registry
from hearth.executive.runlog import LOG_FORMAT, RunLog, header_fields
from hearth.executive.scheduler import STATES, MissionHandle, Scheduler, Submission
from hearth.executive.ticking import Run, TickLoop, halt_tree
from hearth.executive.tree import BuiltTree, SkillFactory, build_tree

#: Ended runs whose handles ``Executive.handle_of`` still finds.
RECENT = 64

__all__ = ["Executive", "Event", "EventKind", "MissionHandle", "MissionResult", "RunState",
           "STATES", "TERMINAL", "LOG_FORMAT"]

Status = common.Status
log = logging.getLogger("hearth.executive")
_ns_counter = itertools.count(1)
Subscriber = Callable[[Event], None]


class Executive:
    """Owns a world model and a robot adapter; runs submitted missions.

    ``world``: the belief map (if it has ``subscribe(callback) -> unsubscribe``, its changes
    become ``map`` events). ``robot``: the robot adapter (``robot.stop()`` is called after a
    cancel or preempt if it exists). ``clock``: WallClock (default) or SimClock.
    ``tick_hz``: ticks per second. ``runs_dir``: where execution logs go (None: no logs).
    ``skills``: name -> Skill class (default: the ``skills`` package registry).
    ``equal_priority``: "queue" (default) or "preempt" (a new mission of the same priority
    preempts the running one). ``make_skill``: how skill nodes are instantiated (skill
    substitution; see hearth.executive.testing). ``background``: run the tick thread (False: call
    ``tick()`` yourself, as tests and ``hearth step`` do). ``autonomy``: the highest skill
    AUTONOMY level granted (None: no limit); ``submit`` refuses a mission using a skill above
    it, naming each such skill with file and line.
    """

    def __init__(self, world: Any = None, robot: Any = None, clock: Any = None,
                 tick_hz: float = 10.0, runs_dir: str | os.PathLike | None = "runs",
                 skills: dict[str, type] | None = None, equal_priority: str = "queue",
                 make_skill: SkillFactory | None = None, background: bool = True,
                 setup_kwargs: dict[str, Any] | None = None, autonomy: int | None = None):
        if not (tick_hz > 0 and math.isfinite(tick_hz)):
            raise ValueError("tick_hz must be a positive number")
        if clock is None:
            from hearth.robot.clock import WallClock
            clock = WallClock()
        self.world = world
        self.robot = robot
        self.clock = clock
        self.tick_hz = float(tick_hz)
        self.period = 1.0 / self.tick_hz
        self.runs_dir = Path(runs_dir) if runs_dir is not None else None
        self.skills = skills
        self.make_skill = make_skill
        self.setup_kwargs = dict(setup_kwargs or {})
        self.autonomy = autonomy
        self._scheduler = Scheduler(equal_priority)
        self._loop = TickLoop(clock, self.period)
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self._outbox = Outbox(threaded=background)
        self._live: dict[str, Submission] = {}      # submitted and not ended, by run id
        self._ended: "OrderedDict[str, Submission]" = OrderedDict()   # the last RECENT ended
        self._current: Run | None = None
        self._starting: Submission | None = None
        self._params: dict[str, Any] = {}
        self._param_changes: list[tuple[str, Any]] = []
        self._subscribers: tuple[Subscriber, ...] = ()
        self._map_events: list[dict[str, Any]] = []
        self._closed = False
        self._unsubscribe_world = None
        if world is not None and callable(getattr(world, "subscribe", None)):
            self._unsubscribe_world = world.subscribe(self._on_map_change)
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._run_thread, name="hearth-tick",
                                            daemon=True)
            self._thread.start()

    @property
    def equal_priority(self) -> str:
        return self._scheduler.equal_priority

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
        parameter (a parameter declaring ``kinds`` is checked against the map). A higher
        ``priority`` preempts the running mission; equal priorities queue (or preempt, see
        ``equal_priority``)."""
        handle = self._submit(mission, priority, params, blocking=True)
        assert handle is not None
        return handle

    def try_submit(self, mission: str | os.PathLike | Mission, priority: int = 0,
                   params: dict[str, Any] | None = None) -> MissionHandle | None:
        """:meth:`submit`, or None without having done anything when the map's or the
        executive's lock is held by another thread (a tick, a skill moving things): for a
        caller that must never wait on them, such as the HTTP API's event loop, which then
        submits from a worker thread. Errors are raised as by :meth:`submit`."""
        return self._submit(mission, priority, dict(params or {}), blocking=False)

    def _submit(self, mission: str | os.PathLike | Mission, priority: int,
                params: dict[str, Any], blocking: bool) -> MissionHandle | None:
        mission = self.load(mission)
        self._check_autonomy(mission)
        with contextlib.ExitStack() as held:
            if not blocking:
                # Both re-entrant; taken without waiting, so the order cannot deadlock.
                for lock in (getattr(self.world, "lock", None), self._lock):
                    if lock is None:
                        continue
                    if not lock.acquire(blocking=False):
                        return None
                    held.callback(lock.release)
            # node kinds, words; reads the map
            params = mission.resolve_in_map(params, self.world)
            with self._lock:
                if self._closed:
                    raise MissionError("the executive has been shut down")
                values = mission.resolve_parameters(params, self._params)
                run_id = self._new_run_id(mission.name, self._scheduler.next_seq())
                sub = Submission(id=run_id, mission=mission, priority=priority, params=values,
                                 given=frozenset(params), seq=self._scheduler.next_seq())
                handle = MissionHandle(self, sub)
                self._live[sub.id] = sub
                self._scheduler.push(sub)
                current = self._current.sub if self._current is not None else self._starting
                if self._scheduler.preempts(sub, current):
                    self._request_cancel(current, RunState.PREEMPTED,
                                         f"preempted by {mission.name} ({sub.id})")
                self._wake.notify_all()
        return handle

    def cancel(self, handle: MissionHandle, reason: str = "cancelled",
               outcome: str = "cancelled") -> bool:
        """Ask a mission to stop; it ends ``outcome`` (cancelled, or preempted as a higher
        priority mission would make it). True if it will (or was already being halted);
        False if it had already ended. Never blocks on the robot."""
        final = RunState(outcome)
        if final not in (RunState.CANCELLED, RunState.PREEMPTED):
            raise ValueError("a mission is cancelled or preempted")
        with self._lock:
            sub = self._live.get(handle.id)
            accepted = sub is not None and self._request_cancel(sub, final, reason)
        self._outbox.deliver()
        return accepted

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
            missions = [s.mission for s in self._scheduler.waiting()]
            if self._current is not None:
                missions.append(self._current.sub.mission)
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

    def subscribe(self, callback: Subscriber, handle: MissionHandle | None = None
                  ) -> Callable[[], None]:
        """Call ``callback(event)`` for the events of every mission (or of ``handle``'s),
        from the delivery thread (background) or the caller of ``tick()``, never with the
        executive's lock held. Returns an unsubscribe function."""
        with self._lock:
            sub = None
            if handle is not None:
                sub = self._live.get(handle.id)
                if sub is None:
                    return lambda: None     # it has ended: there is nothing more to hear
                sub.subscribers += (callback,)
            else:
                self._subscribers += (callback,)

        def unsubscribe() -> None:
            with self._lock:
                if sub is not None:
                    sub.subscribers = tuple(c for c in sub.subscribers if c is not callback)
                else:
                    self._subscribers = tuple(c for c in self._subscribers if c is not callback)
        return unsubscribe

    def handle_of(self, run_id: str) -> MissionHandle | None:
        """The handle of a run submitted here: live, or among the last ``RECENT`` ended
        (subscribers hear of a run after the fact, when it may have ended already)."""
        with self._lock:
            sub = self._live.get(run_id) or self._ended.get(run_id)
            return sub.handle if sub is not None else None

    @property
    def current(self) -> MissionHandle | None:
        with self._lock:
            return self._current.sub.handle if self._current is not None else None

    @property
    def current_tree(self) -> BuiltTree | None:
        with self._lock:
            return self._current.tree if self._current is not None else None

    @property
    def current_tick(self) -> int | None:
        """The running mission's tick number (the next tick to run), None when none runs."""
        with self._lock:
            return self._current.tick if self._current is not None else None

    @property
    def queued(self) -> list[MissionHandle]:
        with self._lock:
            return [s.handle for s in self._scheduler.waiting()]

    def idle(self) -> bool:
        with self._lock:
            return (self._current is None and self._starting is None
                    and not self._scheduler.has_waiting())

    def tick(self) -> bool:
        """One executive step: start a queued mission, apply parameter changes and cancel
        requests, then tick (or keep halting), and deliver the step's events. Returns False
        when there was nothing to do. Only for ``background=False``; the tick thread calls it
        otherwise."""
        if self._thread is not None and threading.current_thread() is not self._thread:
            raise RuntimeError("Executive.tick() is for background=False executives")
        return self._tick()

    def run_until_idle(self, max_ticks: int = 1_000_000) -> int:
        """Tick (background=False) until no mission is running or queued; ticks done.
        With a wall clock it keeps the tick rate (sleeps between ticks)."""
        if self._thread is not None:
            raise RuntimeError("Executive.run_until_idle() is for background=False executives")
        return self._loop.run(self._tick, max_ticks=max_ticks)

    def shutdown(self, timeout: float = 5.0) -> None:
        """Cancel everything, wait (``timeout`` real seconds) for the tick thread and the
        event delivery, detach from the world."""
        with self._lock:
            self._closed = True
            for sub in list(self._live.values()):
                self._request_cancel(sub, RunState.CANCELLED, "executive shut down")
            self._wake.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
        else:
            self._outbox.deliver()
            self.run_until_idle(max_ticks=100_000)
        self._outbox.close(timeout)
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
    def _request_cancel(self, sub: Submission, final: RunState, reason: str) -> bool:
        """Lock held. A queued mission ends at once; a starting, running or halting one is
        halted by the next step."""
        if sub.ended:
            return False
        if sub.state is RunState.QUEUED and sub is not self._starting:
            sub.life.cancel_queued()
            self._scheduler.remove(sub)
            self._end_unstarted(sub, RunState.CANCELLED, reason)
            return True
        sub.request_cancel(final, reason)
        self._wake.notify_all()
        return True

    def _on_map_change(self, change: Any) -> None:
        data = {a: plain(getattr(change, a, None)) for a in ("node", "field", "old", "new",
                                                              "source")}
        data["map_time"] = getattr(change, "time", None)
        with self._lock:
            self._map_events.append(data)

    # -- the loop ------------------------------------------------------------------------
    def _run_thread(self) -> None:
        self._loop.run(self._tick_guarded, wait_for_work=self._wait_for_work)

    def _wait_for_work(self) -> bool:
        with self._lock:
            while not self._closed and self.idle():
                self._wake.wait(0.5)
            return not (self._closed and self.idle())

    def _tick_guarded(self) -> bool:
        try:
            return self._tick()
        except Exception:  # noqa: BLE001 - the thread must survive anything
            log.exception("executive step failed")
            self._loop.advance(True)
            return True

    def _tick(self) -> bool:
        did = self._step()
        self._outbox.deliver()
        self._loop.advance(did)
        return did

    def _step(self) -> bool:
        with self._lock:
            run = self._current
            if run is not None:
                return self._step_run(run)
            sub = self._scheduler.pop()
            if sub is None:
                self._param_changes.clear()
                self._map_events.clear()
                return False
            self._starting = sub
        run = self._start(sub)   # outside the lock: skill setup may take a while
        with self._lock:
            self._starting = None
            if run is None:
                return True
            self._current = run
            return self._step_run(run)

    def _step_run(self, run: Run) -> bool:
        """Apply requests, then tick once or poll halting skills once (lock held). Anything
        unexpected ends the mission (halting the tree, stopping the robot): never a run that
        hangs."""
        try:
            run.begin_step(self.clock.now(),
                           quiet=not (run.sub.subscribers or self._subscribers))
            self._apply_requests(run)
            if run.sub.state is RunState.HALTING:
                self._poll_halting(run)
            else:
                self._tick_tree(run)
        except Exception as err:  # noqa: BLE001
            log.exception("executive step failed")
            self._abort(run, f"internal error: {type(err).__name__}: {err}")
        run.tick += 1
        return True

    def _start(self, sub: Submission) -> Run | None:
        run = Run(sub, self._emit, self._notify)
        run.t0 = run.now = self.clock.now()
        try:
            with self._lock:
                sub.life.start()
                # Runtime values may have changed while the mission was queued.
                for name in sub.mission.runtime_parameters():
                    if name not in sub.given and name in self._params:
                        sub.params[name] = self._params[name]
                ns = f"/hearth/r{next(_ns_counter)}"
                self._open_log(run, ns)
                run.prepare(build_tree(sub.mission, sub.params, ns, self.make_skill))
                self._emit(run, EventKind.RUN, None, state=RunState.RUNNING, reason="started")
            # run_memory: what the run's skills share for the length of the run (e.g.
            # ReadKnobs' and TurnKnob's "off from two places", hearth/skills/knobs.py)
            run.tree.setup(world=self.world, robot=self.robot, clock=self.clock,
                           executive=self, **{"run_memory": {}, **self.setup_kwargs})
        except Exception as err:  # noqa: BLE001 - a skill that cannot set up fails the mission
            with self._lock:
                if sub.state is RunState.QUEUED:
                    sub.life.start()
                sub.life.fail()
                reason = f"setup failed: {err}"
                self._emit(run, EventKind.RUN, None, state=RunState.FAILED, reason=reason)
                self._end(run, RunState.FAILED, reason)
            return None
        return run

    def _apply_requests(self, run: Run) -> None:
        tree = run.tree
        if self._param_changes:
            declared = run.sub.mission.parameters
            for name, value in self._param_changes:
                spec = declared.get(name)
                if spec is not None and spec.runtime:
                    tree.write_param(name, value)
                    self._emit(run, EventKind.PARAM, None, name=name, value=plain(value))
            self._param_changes.clear()
        if self._map_events:
            for data in self._map_events:
                self._emit(run, EventKind.MAP, None, **data)
            self._map_events.clear()
        req = run.sub.cancel
        if req is not None and run.sub.state is RunState.RUNNING:
            run.sub.life.halt()
            self._emit(run, EventKind.RUN, None, state=RunState.HALTING, reason=req.reason,
                       final=req.final)
            run.halt(self.clock.now())

    def _stop_robot(self) -> None:
        stop = getattr(self.robot, "stop", None)
        if callable(stop):
            try:
                stop()
            except Exception:  # noqa: BLE001 - a failing stop must not wedge the executive
                log.exception("robot.stop() failed")

    def _poll_halting(self, run: Run) -> None:
        run.poll_halting()
        now = self.clock.now()
        if run.halting and now < run.halt_deadline:
            return
        self._stop_robot()
        if run.halting:
            # Past HALT_TIMEOUT: robot.stop() may still have stopped them; ask once more.
            run.poll_halting()
        req = run.sub.cancel
        waited = round(now - run.halt_started, 9)
        timed_out = [run.tree.path_of.get(id(s), s.name) for s in run.halting]
        self._emit(run, EventKind.HALTED, None, waited=waited, timed_out=timed_out)
        reason = req.reason
        extra: dict[str, Any] = {}
        if timed_out:
            log.warning("gave up waiting for %s to stop", ", ".join(timed_out))
            reason = (f"{req.final}, robot not confirmed stopped ({', '.join(timed_out)} still "
                      f"stopping after {waited:g} s): {req.reason}")
            extra["robot_stopped"] = False
        if req.final is RunState.PREEMPTED:
            run.sub.life.end_preempt()
        else:
            run.sub.life.end_cancel()
        self._emit(run, EventKind.RUN, None, state=req.final, reason=reason, **extra)
        self._end(run, req.final, reason, robot_stopped=not timed_out)

    def _tick_tree(self, run: Run) -> None:
        root = run.tree.root
        if not self._loop.simulated:
            self._emit(run, EventKind.TICK, None)
        try:
            run.tick_tree()
        except Exception as err:  # noqa: BLE001 - a crashing skill fails the mission
            log.exception("tick failed")
            halt_tree(root)
            self._stop_robot()
            run.sub.life.fail()
            reason = f"{type(err).__name__}: {err}"
            self._emit(run, EventKind.RUN, None, state=RunState.FAILED, reason=reason)
            self._end(run, RunState.FAILED, reason)
            return
        status = root.status
        if status in (Status.SUCCESS, Status.FAILURE):
            reason = run.reason(status)
            if status == Status.SUCCESS:
                run.sub.life.succeed()
                final = RunState.SUCCEEDED
            else:
                run.sub.life.fail()
                final = RunState.FAILED
            self._emit(run, EventKind.RUN, None, state=final, reason=reason)
            self._end(run, final, reason)

    def _abort(self, run: Run, error: str) -> None:
        """End a run after an unexpected error in the executive itself (lock held)."""
        if run.sub.ended:
            return
        try:
            if run.tree is not None:
                halt_tree(run.tree.root)
        finally:
            self._stop_robot()
        req = run.sub.cancel
        if run.sub.state is RunState.HALTING and req is not None:
            final = req.final
            reason = f"{final}, robot not confirmed stopped ({error}): {req.reason}"
            if final is RunState.PREEMPTED:
                run.sub.life.end_preempt()
            else:
                run.sub.life.end_cancel()
            robot_stopped = False
        else:
            final, reason, robot_stopped = RunState.FAILED, error, True
            run.sub.life.fail()
        try:
            self._emit(run, EventKind.RUN, None, state=final, reason=reason,
                       **({} if robot_stopped else {"robot_stopped": False}))
        except Exception:  # noqa: BLE001 - e.g. the log's disk is full: still end the run
            log.exception("reporting the end of %s failed", run.id)
        self._end(run, final, reason, robot_stopped=robot_stopped)

    # -- events and logs -------------------------------------------------------------------
    def _emit(self, run: Run, kind: EventKind, path: str | None, **data: Any) -> None:
        """Log an event of ``run`` and post it to its subscribers (lock held)."""
        subscribers = run.sub.subscribers + self._subscribers
        if run.log is None and not subscribers:
            return
        ev = Event(kind, run.id, run.tick, run.now, path, data)
        if run.log is not None:
            run.log.event(ev)
        if subscribers:
            self._outbox.post(ev, subscribers)

    def _notify(self, run: Run, kind: EventKind, path: str | None, data: dict[str, Any]) -> None:
        """Post an event of ``run`` to its subscribers only (it is logged already)."""
        subscribers = run.sub.subscribers + self._subscribers
        if subscribers:
            self._outbox.post(Event(kind, run.id, run.tick, run.now, path, data), subscribers)

    def _header(self, sub: Submission, t0: float, ns: str | None) -> dict[str, Any]:
        return header_fields(sub.id, sub.mission, sub.params, sub.priority, t0,
                             self.clock.wall(), self.tick_hz, self._loop.simulated, ns)

    def _open_log(self, run: Run, ns: str) -> None:
        if self.runs_dir is not None:
            run.log = RunLog.create(self.runs_dir, run.id, self._header(run.sub, run.t0, ns))
            run.sub.log_path = str(run.log.path)

    def _end(self, run: Run, outcome: RunState, reason: str, robot_stopped: bool = True) -> None:
        """Close the run: result, log end line, teardown (lock held; never raises)."""
        sub = run.sub
        try:
            outputs = plain(run.tree.outputs()) if run.tree is not None else {}
        except Exception:  # noqa: BLE001
            log.exception("reading the outputs of %s failed", run.id)
            outputs = {}
        now = self.clock.now()
        result = MissionResult(outcome=outcome.value, reason=reason, outputs=outputs,
                               ticks=run.tick + (1 if outcome in (RunState.SUCCEEDED,
                                                                  RunState.FAILED) else 0),
                               duration=now - run.t0, log_path=sub.log_path,
                               robot_stopped=robot_stopped)
        if run.log is not None:
            run.log.finish(run.id, run.tick, now, outcome, reason, result.outputs,
                           None if robot_stopped else {"robot_stopped": False})
        if run.tree is not None:
            run.tree.teardown()
        if self._current is run:
            self._current = None
        self._finish(sub, result)

    def _end_unstarted(self, sub: Submission, outcome: RunState, reason: str) -> None:
        """A mission that ended before it started (lock held): it is logged all the same."""
        now = self.clock.now()
        ev = Event(EventKind.RUN, sub.id, 0, now, None, {"state": outcome, "reason": reason})
        if self.runs_dir is not None:
            path = RunLog.write_unstarted(self.runs_dir, sub.id, self._header(sub, now, None),
                                          ev, outcome, reason)
            sub.log_path = str(path) if path is not None else None
        subscribers = sub.subscribers + self._subscribers
        if subscribers:
            self._outbox.post(ev, subscribers)
        self._finish(sub, MissionResult(outcome=outcome.value, reason=reason, outputs={},
                                        log_path=sub.log_path))

    def _finish(self, sub: Submission, result: MissionResult) -> None:
        sub.result = result
        self._live.pop(sub.id, None)
        self._ended[sub.id] = sub
        while len(self._ended) > RECENT:
            self._ended.popitem(last=False)
        self._outbox.post_done(sub.done)
        self._wake.notify_all()

    def _new_run_id(self, name: str, n: int) -> str:
        # The date a person ran it (a simulated clock's wall() is a fixed epoch).
        stamp = _time.strftime("%Y%m%dT%H%M%S", _time.gmtime(_time.time()))
        rid = f"{stamp}-{name}-{n}"
        if self.runs_dir is not None:
            while (self.runs_dir / f"{rid}.jsonl").exists():
                n = self._scheduler.next_seq()
                rid = f"{stamp}-{name}-{n}"
        return rid
