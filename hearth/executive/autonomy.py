"""Operator autonomy levels: ask before a skill acts on the home above the granted level.

Every skill declares ``AUTONOMY`` (hearth/skills/base.py: 0 observes, 1 moves the base, 2 acts on
the home, 3 handles objects near the user). FlexBE-style, the operator grants a level; a
skill above it does not start until someone approves it through the command API (or the
monitor page), and fails with the reason when they refuse or nobody answers in time.

The gate never blocks: while a request is pending the skill reports RUNNING with feedback
"waiting for approval ...", so the executive keeps ticking (parallel branches go on,
cancels, preempts and new submissions are handled as usual). A halted skill withdraws its
request.

Wiring (no change to the Executive)::

    approvals = Approvals(granted=1, timeout=120.0)
    ex = Executive(world, robot, make_skill=gated_factory(inner_factory),
                   setup_kwargs={"approvals": approvals})

``gated_factory`` gives what the inner factory makes (the real skill, or a scripted stand-in)
the gate on that instance, so the node keeps its place, class, NAME and ports in the tree.
(``Executive(autonomy=N)`` is different: it refuses such missions at submit.)
"""
from __future__ import annotations

import itertools
import threading
import types
from collections import deque
from dataclasses import asdict, dataclass
from typing import Any, Callable

from py_trees import common

from hearth.executive.tree import SkillFactory, default_factory
from hearth.util.subscribers import Subscribers

Status = common.Status
PENDING, APPROVED, REFUSED, EXPIRED, WITHDRAWN = (
    "pending", "approved", "refused", "expired", "withdrawn")


@dataclass
class ApprovalRequest:
    """One question to the operator. Times are executive clock seconds."""
    id: str
    run: str | None
    path: str
    skill: str
    level: int
    granted: int
    asked_at: float
    deadline: float
    state: str = PENDING
    decided_by: str = ""
    reason: str = ""

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


class Approvals:
    """The granted level and the pending/decided requests; thread-safe.

    ``subscribe(cb)``: ``cb(kind, data)`` with kind ``approval`` (a request dict, on every
    change of state) or ``autonomy`` (``{"granted": level}``)."""

    def __init__(self, granted: int = 3, timeout: float = 120.0, keep: int = 200):
        self._lock = threading.Lock()
        self._granted = int(granted)
        self.timeout = float(timeout)
        self._ids = itertools.count(1)
        self._requests: dict[str, ApprovalRequest] = {}
        self._done: deque[str] = deque(maxlen=keep)
        self._subscribers: Subscribers[Callable[[str, dict], None]] = Subscribers()

    @property
    def granted(self) -> int:
        return self._granted

    def set_granted(self, level: int) -> None:
        with self._lock:
            self._granted = int(level)
        self._notify("autonomy", {"granted": int(level)})

    def subscribe(self, cb: Callable[[str, dict], None]) -> Callable[[], None]:
        return self._subscribers.add(cb)

    def _notify(self, kind: str, data: dict) -> None:
        for cb in self._subscribers:
            try:
                cb(kind, data)
            except Exception:  # noqa: BLE001 - a broken listener must not stop the robot
                pass

    def request(self, run: str | None, path: str, skill: str, level: int,
                now: float) -> ApprovalRequest:
        with self._lock:
            req = ApprovalRequest(id=f"a{next(self._ids)}", run=run, path=path, skill=skill,
                                  level=level, granted=self._granted, asked_at=now,
                                  deadline=now + self.timeout)
            self._requests[req.id] = req
        self._notify("approval", req.to_json())
        return req

    def _close(self, req: ApprovalRequest, state: str, by: str, reason: str) -> None:
        req.state, req.decided_by, req.reason = state, by, reason
        self._done.append(req.id)
        # Bounded memory: decided requests drop out once they leave the ``keep`` most recent.
        for rid in list(self._requests):
            if self._requests[rid].state != PENDING and rid not in self._done:
                del self._requests[rid]

    def decide(self, request_id: str, approve: bool, by: str = "operator",
               reason: str = "") -> ApprovalRequest:
        """Approve or refuse a pending request. KeyError: unknown id; ValueError: it is no
        longer pending (its state says why)."""
        with self._lock:
            req = self._requests[request_id]
            if req.state != PENDING:
                raise ValueError(f"request {request_id} is already {req.state}")
            self._close(req, APPROVED if approve else REFUSED, by,
                        reason or ("approved" if approve else "refused"))
            data = req.to_json()
        self._notify("approval", data)
        return req

    def poll(self, req: ApprovalRequest, now: float) -> str:
        """The request's state at clock time ``now`` (expires it past its deadline; a
        granted level raised to its level approves it)."""
        changed = None
        with self._lock:
            if req.state == PENDING:
                if req.level <= self._granted:
                    self._close(req, APPROVED, "autonomy", f"granted level is {self._granted}")
                    changed = req.to_json()
                elif now >= req.deadline:
                    self._close(req, EXPIRED, "timeout",
                                f"no answer within {self.timeout:g} s")
                    changed = req.to_json()
            state = req.state
        if changed:
            self._notify("approval", changed)
        return state

    def withdraw(self, req: ApprovalRequest, reason: str = "halted") -> None:
        with self._lock:
            if req.state != PENDING:
                return
            self._close(req, WITHDRAWN, "executive", reason)
            data = req.to_json()
        self._notify("approval", data)

    def get(self, request_id: str) -> ApprovalRequest:
        with self._lock:
            return self._requests[request_id]

    def list(self, pending_only: bool = False) -> list[ApprovalRequest]:
        with self._lock:
            reqs = list(self._requests.values())
        return [r for r in reqs if not pending_only or r.state == PENDING]


class _Gate:
    """The approval gate's methods, bound onto one skill instance (``gate(node)``); the
    skill's own methods are kept in ``node._gate_orig`` and called once the gate opens."""

    @staticmethod
    def setup(self, **kwargs: Any) -> None:
        self._gate_orig["setup"](**kwargs)
        self._approvals = kwargs.get("approvals")
        self._executive = kwargs.get("executive")

    @staticmethod
    def _now(self) -> float:
        clock = getattr(self, "clock", None)
        return clock.now() if clock is not None else 0.0

    @staticmethod
    def initialise(self) -> None:
        self._gate_req = None
        self._gate_open = False
        ap = getattr(self, "_approvals", None)
        if ap is None or self.AUTONOMY <= ap.granted:
            self._gate_open = True
            self._gate_orig["initialise"]()
            return
        ex = getattr(self, "_executive", None)
        current = getattr(ex, "current", None) if ex is not None else None
        self._gate_req = ap.request(run=getattr(current, "id", None),
                                    path=getattr(self, "hearth_path", self.name),
                                    skill=self.NAME, level=self.AUTONOMY, now=_Gate._now(self))
        self.feedback_message = (f"waiting for approval: {self.NAME} acts with autonomy "
                                 f"{self.AUTONOMY}, above the granted level {ap.granted} "
                                 f"(request {self._gate_req.id})")

    @staticmethod
    def update(self) -> Status:
        if not self._gate_open:
            req = self._gate_req
            state = self._approvals.poll(req, _Gate._now(self))
            if state == PENDING:
                return Status.RUNNING
            if state != APPROVED:
                who = "the operator refused" if state == REFUSED else f"approval {state}"
                self.feedback_message = f"{self.NAME} not started: {who} ({req.reason})"
                return Status.FAILURE
            self._gate_open = True
            self._gate_orig["initialise"]()
        return self._gate_orig["update"]()

    @staticmethod
    def terminate(self, new_status: Status) -> None:
        if self._gate_open:
            self._gate_orig["terminate"](new_status)
        elif self._gate_req is not None:
            self._approvals.withdraw(self._gate_req)

    @staticmethod
    def is_halting(self) -> bool:
        return self._gate_open and self._gate_orig["is_halting"]()


_GATED_METHODS = ("setup", "initialise", "update", "terminate", "is_halting")


def gate(node: Any) -> Any:
    """Give one skill instance the approval gate (its class is left alone, so stand-ins
    from a Substitution keep being the objects it recorded)."""
    node._gate_orig = {m: getattr(node, m) for m in _GATED_METHODS}
    node._gate_open = True     # until initialise decides
    node._gate_req = None
    node._approvals = None
    node._executive = None
    for m in _GATED_METHODS:
        setattr(node, m, types.MethodType(getattr(_Gate, m), node))
    return node


def gated_factory(inner: SkillFactory | None = None) -> SkillFactory:
    """A ``make_skill`` that gives every skill with AUTONOMY > 0 the approval gate."""
    inner = inner or default_factory

    def make(spec: Any, bindings: Any) -> Any:
        node = inner(spec, bindings)
        if getattr(node, "AUTONOMY", 0) > 0:
            gate(node)
        return node
    return make
