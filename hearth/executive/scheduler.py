"""Which mission runs: submissions, their lifecycle, the priority queue and preemption.

One mission runs at a time. A submission waits in priority order, first come first served
among equals; a higher priority than the running mission's preempts it (with
``equal_priority="preempt"`` an equal one does too). Each submission's lifecycle is a model
of one shared ``transitions`` machine (:data:`MACHINE`)::

    queued --start--> running --succeed--> succeeded
       |                 |------fail-----> failed
       |                 `--halt--> halting --end_cancel--> cancelled
       |                                    `-end_preempt-> preempted
       `--cancel_queued--> cancelled

:class:`Submission` is the executive's record of one submitted mission (it changes it under
its lock); :class:`MissionHandle` is what a caller holds: it reads its submission and asks
the executive for everything else.
"""
from __future__ import annotations

import heapq
import itertools
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

from transitions import Machine

from hearth.executive.events import TERMINAL, Event, MissionResult, RunState
from hearth.executive.missionfile import Mission

if TYPE_CHECKING:
    from hearth.executive.executive import Executive

STATES = [s.value for s in RunState]


def _lifecycle_machine() -> Machine:
    m = Machine(model=None, states=STATES, initial=RunState.QUEUED.value,
                auto_transitions=False)
    m.add_transition("start", "queued", "running")
    m.add_transition("succeed", "running", "succeeded")
    m.add_transition("fail", ["queued", "running"], "failed")
    m.add_transition("halt", "running", "halting")
    m.add_transition("cancel_queued", "queued", "cancelled")
    m.add_transition("end_cancel", "halting", "cancelled")
    m.add_transition("end_preempt", "halting", "preempted")
    return m


#: The one ``transitions`` machine every mission's lifecycle runs on. Building a Machine per
#: submission (states, transitions, trigger methods bound onto the model) was the largest
#: share of a submit's CPU (0.19 ms of ~0.25 in ``Executive.submit``); the machine holds no
#: per-model state (not queued, no models registered), so its events are triggered with each
#: lifecycle as the model (``Event.trigger(model)``): the same checks, MachineError on a
#: trigger from a wrong state, the model's ``state`` set by the machine.
MACHINE = _lifecycle_machine()


def _trigger(name: str) -> Callable[["Lifecycle"], bool]:
    event = MACHINE.events[name]

    def trigger(self: "Lifecycle") -> bool:
        return event.trigger(self)
    trigger.__name__ = name
    trigger.__doc__ = f"The ``{name}`` trigger of :data:`MACHINE`."
    return trigger


class Lifecycle:
    """The ``transitions`` model of one mission (``state``; triggers ``start``, ``succeed``,
    ``fail``, ``halt``, ``cancel_queued``, ``end_cancel``, ``end_preempt``) on the shared
    :data:`MACHINE`."""

    __slots__ = ("state",)

    def __init__(self) -> None:
        self.state: str = MACHINE.initial

    start = _trigger("start")
    succeed = _trigger("succeed")
    fail = _trigger("fail")
    halt = _trigger("halt")
    cancel_queued = _trigger("cancel_queued")
    end_cancel = _trigger("end_cancel")
    end_preempt = _trigger("end_preempt")


@dataclass
class CancelRequest:
    """A cancel or preempt asked for and not yet carried out: the state the mission will
    end in (cancelled or preempted) and why."""
    final: RunState
    reason: str


@dataclass(eq=False)
class Submission:
    """The executive's record of one submitted mission."""
    id: str
    mission: Mission
    priority: int
    params: dict[str, Any]
    given: frozenset[str]          # parameters given to submit (not from runtime values)
    seq: int                       # submission order, for first come first served
    life: Lifecycle = field(default_factory=Lifecycle)
    cancel: CancelRequest | None = None
    subscribers: tuple[Callable[[Event], None], ...] = ()
    result: MissionResult | None = None
    log_path: str | None = None
    done: threading.Event = field(default_factory=threading.Event)
    handle: "MissionHandle | None" = None

    @property
    def state(self) -> RunState:
        return RunState(self.life.state)

    @property
    def ended(self) -> bool:
        return self.state in TERMINAL

    def request_cancel(self, final: RunState, reason: str) -> None:
        """Record a cancel or preempt; a user cancel turns a pending preempt into a cancel,
        never the reverse."""
        if self.cancel is None or (final is RunState.CANCELLED
                                   and self.cancel.final is RunState.PREEMPTED):
            self.cancel = CancelRequest(final, reason)


class MissionHandle:
    """What ``submit`` returns: watch, wait for and cancel one mission. Thread-safe."""

    def __init__(self, executive: "Executive", submission: Submission):
        self._ex = executive
        self._sub = submission
        submission.handle = self

    @property
    def id(self) -> str:
        return self._sub.id

    @property
    def mission(self) -> Mission:
        return self._sub.mission

    @property
    def priority(self) -> int:
        return self._sub.priority

    @property
    def params(self) -> dict[str, Any]:
        """Parameter values (runtime ones as they were when the mission started)."""
        return self._sub.params

    @property
    def result(self) -> MissionResult | None:
        return self._sub.result

    @property
    def log_path(self) -> str | None:
        return self._sub.log_path

    @property
    def status(self) -> RunState:
        """queued, running, halting, succeeded, failed, cancelled or preempted."""
        return self._sub.state

    @property
    def done(self) -> bool:
        """True once the mission has ended and its subscribers have had its last event."""
        return self._sub.done.is_set()

    def cancel(self, reason: str = "cancelled") -> bool:
        """Ask the mission to stop. True if it will end cancelled (or was already being
        halted); False if it had already ended. Never blocks on the robot."""
        return self._ex.cancel(self, reason)

    def wait(self, timeout: float | None = None) -> MissionResult | None:
        """Block until the mission is done (``timeout`` in real seconds); its result or None."""
        self._sub.done.wait(timeout)
        return self._sub.result if self._sub.done.is_set() else None

    def subscribe(self, callback: Callable[[Event], None]) -> Callable[[], None]:
        """Call ``callback(event)`` for each event of this mission (not from the thread
        holding the executive's lock). Returns a function that unsubscribes."""
        return self._ex.subscribe(callback, handle=self)

    def __repr__(self) -> str:
        return f"<MissionHandle {self.id} {self.mission.name} {self.status}>"


class Scheduler:
    """The queue of submissions waiting to run, by priority then submission order, and the
    preemption rule. Not thread-safe: the executive calls it under its lock."""

    def __init__(self, equal_priority: str = "queue"):
        if equal_priority not in ("queue", "preempt"):
            raise ValueError("equal_priority is 'queue' or 'preempt'")
        self.equal_priority = equal_priority
        self._heap: list[tuple[int, int, Submission]] = []
        self._seq = itertools.count()

    def next_seq(self) -> int:
        return next(self._seq)

    def push(self, sub: Submission) -> None:
        heapq.heappush(self._heap, (-sub.priority, sub.seq, sub))

    def pop(self) -> Submission | None:
        """The next queued submission to run (removed from the queue), or None."""
        while self._heap:
            _, _, sub = heapq.heappop(self._heap)
            if sub.state is RunState.QUEUED:
                return sub
        return None

    def remove(self, sub: Submission) -> None:
        self._heap = [q for q in self._heap if q[2] is not sub]
        heapq.heapify(self._heap)

    def waiting(self) -> list[Submission]:
        """Queued submissions in the order they would run."""
        return [s for _, _, s in sorted(self._heap, key=lambda q: q[:2])
                if s.state is RunState.QUEUED]

    def has_waiting(self) -> bool:
        return any(s.state is RunState.QUEUED for _, _, s in self._heap)

    def preempts(self, new: Submission, current: Submission | None) -> bool:
        """Whether ``new`` preempts the running (or starting) ``current``."""
        if current is None or current.ended:
            return False
        return new.priority > current.priority or (
            new.priority == current.priority and self.equal_priority == "preempt")
