"""What a run reports: event kinds, run states, events and results, and the outbox that
hands events to subscribers outside the executive's lock.

Kinds and states are ``str`` enums: they compare, hash and serialise as their values
(``EventKind.STATUS == "status"``, ``json.dumps`` writes ``"status"``), so logs and the HTTP
API read exactly as plain strings would.
"""
from __future__ import annotations

import logging
import queue
import threading
from collections import deque
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Callable, Iterable

log = logging.getLogger("hearth.executive")


class _StrEnum(str, Enum):
    """A str enum that prints, formats and hashes as its value (Python 3.10's enum.Enum
    would print ``EventKind.STATUS``)."""
    __str__ = str.__str__
    __format__ = str.__format__
    __hash__ = str.__hash__


class EventKind(_StrEnum):
    """``Event.kind`` (the ``e`` of a log line)."""
    #: lifecycle: data ``state``, ``reason`` (``final`` while halting; ``robot_stopped`` false
    #: when a halted skill never confirmed it had stopped)
    RUN = "run"
    #: a node's status changed: ``status``, ``previous``, ``halted`` (stopped from above)
    STATUS = "status"
    #: a node's ``feedback_message`` changed: ``message`` (the sentence) and, when the
    #: skill reported them (``Skill.report``), ``values`` (names -> JSON values)
    FEEDBACK = "feedback"
    #: a declared key written: ``key``, ``value``, ``port``
    WRITE = "write"
    #: a runtime parameter reached the run: ``name``, ``value``
    PARAM = "param"
    #: a watch guard restarted its child: ``changed``
    RESTART = "restart"
    #: a map change: ``node``, ``field``, ``old``, ``new``, ``source``, ``map_time``
    MAP = "map"
    #: a halted skill no longer reports ``is_halting()``
    STOPPED = "stopped"
    #: mission-level halting finished: ``waited``, ``timed_out``
    HALTED = "halted"
    #: wall-clock runs only: each tick's time
    TICK = "tick"


class RunState(_StrEnum):
    """A mission's lifecycle state (``MissionHandle.status``)."""
    QUEUED = "queued"
    RUNNING = "running"
    HALTING = "halting"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"
    PREEMPTED = "preempted"


TERMINAL = frozenset({RunState.SUCCEEDED, RunState.FAILED, RunState.CANCELLED,
                      RunState.PREEMPTED})


@dataclass
class Event:
    """One thing that happened in a run (see :class:`EventKind` for each kind's ``data``).

    ``tick`` is the tick number (0-based), ``time`` the clock time in seconds, ``path`` the
    tree path of the node it concerns (None for run-level events).
    """
    kind: EventKind
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


def json_default(value: Any) -> Any:
    """``json.dumps``' ``default`` for events (the execution log, the command API's stream):
    a value JSON has no word for as data where it has a plain form (a Pose its dict, numpy
    values their numbers, a set a list: hearth.skills.base.json_value), else its repr."""
    if hasattr(value, "as_dict") or hasattr(value, "tolist") or isinstance(value, (set, frozenset)):
        from hearth.skills.base import json_value
        return json_value(value)
    return repr(value)


def feedback_data(message: str) -> dict[str, Any]:
    """A FEEDBACK event's data for a node's ``feedback_message``: ``message``, the sentence as
    a plain str, and ``values`` when it is a hearth.skills.base.Feedback that carries some."""
    values = getattr(message, "values", None)
    text = str.__str__(message)
    return {"message": text, "values": values} if values else {"message": text}


@dataclass
class MissionResult:
    """How a mission ended: ``outcome`` is succeeded, failed, cancelled or preempted;
    ``reason`` says why in words; ``outputs`` are the mission's blackboard keys at the end;
    ``ticks`` the number of ticks; ``duration`` clock seconds from start to end;
    ``robot_stopped`` False when a halted skill still reported ``is_halting()`` after its
    HALT_TIMEOUT and ``robot.stop()`` (the reason then says "robot not confirmed stopped")."""
    outcome: str
    reason: str
    outputs: dict[str, Any]
    ticks: int = 0
    duration: float = 0.0
    log_path: str | None = None
    robot_stopped: bool = True


Subscriber = Callable[[Event], None]


class Outbox:
    """Events for subscribers: posted under the executive's lock, delivered outside it, in
    the order posted.

    ``threaded`` (a background executive): a delivery thread calls the subscribers, so a slow
    subscriber delays neither ticks nor callers waiting for the lock; otherwise
    :meth:`deliver` calls them in the thread that calls it (the executive does at the end of
    ``tick()``, ``cancel()`` and ``shutdown()``). :meth:`post_done` sets a
    ``threading.Event`` once every event posted before it has been delivered: a mission is
    ``done`` only when its subscribers have seen its last event.
    """

    def __init__(self, threaded: bool):
        self._threaded = threaded
        self._pending: deque = deque()
        self._delivering = threading.Lock()
        self._queue: queue.SimpleQueue | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue = queue.SimpleQueue()
            self._thread = threading.Thread(target=self._run, name="hearth-events", daemon=True)
            self._thread.start()

    def post(self, event: Event, subscribers: Iterable[Subscriber]) -> None:
        item = (event, subscribers)
        if self._queue is not None:
            self._queue.put(item)
        else:
            self._pending.append(item)

    def post_done(self, done: threading.Event) -> None:
        self.post(None, done)   # type: ignore[arg-type]

    def deliver(self) -> None:
        """Deliver what is pending, in this thread (not threaded). A call from a subscriber,
        or while another thread delivers, leaves the items to that delivery."""
        if self._queue is not None:
            return
        while self._pending:
            if not self._delivering.acquire(blocking=False):
                return
            try:
                while self._pending:
                    _deliver(*self._pending.popleft())
            finally:
                self._delivering.release()

    def close(self, timeout: float = 5.0) -> None:
        """Deliver what is pending, then stop the delivery thread (at most ``timeout`` s)."""
        if self._queue is not None and self._thread is not None:
            self._queue.put(_CLOSE)
            if threading.current_thread() is not self._thread:   # a subscriber may shut down
                self._thread.join(timeout)
        else:
            self.deliver()

    def _run(self) -> None:
        get = self._queue.get
        while True:
            item = get()
            if item is _CLOSE:
                return
            _deliver(*item)


_CLOSE = object()


def _deliver(event: Event | None, subscribers: Any) -> None:
    if event is None:
        subscribers.set()      # a post_done marker
        return
    for cb in subscribers:
        try:
            cb(event)
        except Exception:  # noqa: BLE001 - a broken subscriber must not stop the robot
            log.exception("event subscriber failed")
