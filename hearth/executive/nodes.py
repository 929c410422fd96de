"""Hearth's own py_trees behaviours: what py_trees 2.6 lacks or does differently.

* Every decorator here halts **deepest first**: py_trees' ``Decorator.stop`` calls its own
  ``terminate`` before stopping its child; :class:`DeepestFirst` reverses that so a skill
  stops what it started on the robot before its parents clean up. (py_trees composites
  already stop children first.)
* :class:`Timeout` reads an injectable clock (py_trees' uses ``time.monotonic``).
* :class:`ThresholdParallel`: success when at least N children succeed.
* :class:`ForEach` (on py_trees' ForEach): literal, parameter or key source, ``until:
  success`` for search loops, and items that are ``None`` do not end the loop.
* :class:`Guard` is py_trees' EternalGuard with a parsed condition.
* :class:`Watch` halts and restarts its child when a watched runtime parameter changes.
* :class:`StateMachine`: SMACH-style container on a ``transitions`` machine.

Behaviours that need time or a clock get it from ``setup(clock=...)``.

Each node with its own ``tick()`` generator also has ``tick_into(seen)``, the same tick by
direct calls (hearth/executive/treetick.py): both share the code between the child ticks, so the
two differ only in how a child is ticked and how a visited node is reported.
"""
from __future__ import annotations

import operator
from typing import Any, Callable, Iterator

import py_trees
from py_trees import common
from py_trees.behaviour import Behaviour
from transitions import Machine

from hearth.executive import treetick
from hearth.executive.missionfile import Expr
from hearth.skills.base import Feedback, words

Status = common.Status
MISSING = object()

Reader = Callable[[Any], Any]   # Ref -> value, MISSING when a key is unset


class DeepestFirst:
    """Mixin for decorators: on stop, stop the child before terminating self."""

    def stop(self, new_status: Status) -> None:
        child = self.decorated
        if new_status == Status.INVALID and child.status != Status.INVALID:
            treetick.stop(child, Status.INVALID)
        elif child.status == Status.RUNNING:
            treetick.stop(child, Status.INVALID)
        self.terminate(new_status)
        self.status = new_status


class FreshStart:
    """Mixin for composites that tick their children themselves: ticked when not running, a
    composite starts afresh (what its children kept from its last run is reset, then it
    initialises)."""

    def _begin(self) -> None:
        if self.status != Status.RUNNING:
            for child in self.children:
                if child.status != Status.INVALID:
                    treetick.stop(child, Status.INVALID)
            self.current_child = None
            self.initialise()


class PassThrough(DeepestFirst, py_trees.decorators.PassThrough):
    """An include: the subtree's root under a node named after the include."""


class Retry(DeepestFirst, py_trees.decorators.Retry):
    """At most ``num_failures`` attempts: a failure before the last restarts the child."""


class Repeat(DeepestFirst, py_trees.decorators.Repeat):
    """Run the child to success ``num_success`` times (-1: forever); a failure fails."""


class Inverter(DeepestFirst, py_trees.decorators.Inverter):
    pass


class ForceSuccess(DeepestFirst, py_trees.decorators.FailureIsSuccess):
    """Failure becomes success; running stays running."""


class ForceFailure(DeepestFirst, py_trees.decorators.SuccessIsFailure):
    """Success becomes failure; running stays running."""


class Timeout(DeepestFirst, py_trees.decorators.Timeout):
    """Fail, halting the child, when it runs longer than ``duration`` seconds of clock time."""

    def __init__(self, name: str, child: Behaviour, duration: float):
        super().__init__(name=name, child=child, duration=duration)
        self.clock = None

    def setup(self, **kwargs: Any) -> None:
        self.clock = kwargs.get("clock") or self.clock

    def _now(self) -> float:
        if self.clock is None:
            from hearth.robot.clock import WallClock
            self.clock = WallClock()
        return self.clock.now()

    def initialise(self) -> None:
        self.finish_time = self._now() + self.duration
        self.feedback_message = ""

    def update(self) -> Status:
        now = self._now()
        if self.decorated.status == Status.RUNNING and now >= self.finish_time:
            self.feedback_message = f"timed out after {self.duration:g} s"
            treetick.stop(self.decorated, Status.INVALID)
            return Status.FAILURE
        if self.decorated.status == Status.RUNNING:
            self.feedback_message = f"{self.finish_time - now:.2f} s left"
        return self.decorated.status


class ThresholdParallel(FreshStart, py_trees.composites.Parallel):
    """Tick all children; success once ``threshold`` have succeeded, failure once that can no
    longer happen. Children that finished are not ticked again until the parallel restarts;
    still-running children are halted when it finishes."""

    def __init__(self, name: str, children: list[Behaviour], threshold: int):
        super().__init__(name=name, policy=common.ParallelPolicy.SuccessOnAll(synchronise=True),
                         children=children)
        self.threshold = threshold

    def tick(self) -> Iterator[Behaviour]:
        self._begin()
        for child in self._pending():
            yield from child.tick()
        self._finish()
        yield self

    def tick_into(self, seen: dict) -> None:
        self._begin()
        for child in self._pending():
            treetick.tick_node(child, seen)
        self._finish()
        seen[self] = self.status

    def _pending(self) -> Iterator[Behaviour]:
        """The children to tick, each checked as the previous one has been ticked."""
        for child in self.children:
            if child.status not in (Status.SUCCESS, Status.FAILURE):
                yield child

    def _finish(self) -> None:
        succeeded = sum(c.status == Status.SUCCESS for c in self.children)
        failed = sum(c.status == Status.FAILURE for c in self.children)
        self.feedback_message = f"{succeeded} of {self.threshold} needed succeeded, {failed} failed"
        new_status = Status.RUNNING
        if succeeded >= self.threshold:
            new_status = Status.SUCCESS
        elif len(self.children) - failed < self.threshold:
            new_status = Status.FAILURE
        self.current_child = self.children[-1]
        if new_status != Status.RUNNING:
            treetick.stop(self, new_status)
        self.status = new_status


class ForEach(DeepestFirst, py_trees.decorators.ForEach):
    """Run the child once per item of a list, writing the item to ``target_key`` first.

    ``until="failure"`` (py_trees' semantics): success when every item succeeded, failure at
    the first failure. ``until="success"`` (search loops, e.g. parking positions): success at
    the first item whose child succeeds, failure when every item failed. An empty list is
    success for ``failure`` and failure for ``success``; a source that is not a list is a
    failure that says what it is (the source as a value).
    """

    _DONE = object()

    def __init__(self, name: str, child: Behaviour, source: Callable[[], Any], target_key: str,
                 until: str = "failure"):
        py_trees.decorators.Decorator.__init__(self, name=name, child=child)
        self.source = source
        self.target_key = target_key
        self.until = until
        self.blackboard = self.attach_blackboard_client(name=name)
        self.blackboard.register_key(key=target_key, access=common.Access.WRITE)
        self.output_hook = None
        self._iterator = None
        self._current_item: Any = self._DONE
        self._not_a_list: Feedback | None = None
        self.index = -1

    def tick(self) -> Iterator[Behaviour]:
        # Like Decorator.tick, but an exhausted (or empty) list never ticks the child.
        if self.status != Status.RUNNING:
            self.initialise()
        if self._current_item is not self._DONE:
            yield from self.decorated.tick()
        self._finish()
        yield self

    def tick_into(self, seen: dict) -> None:
        if self.status != Status.RUNNING:
            self.initialise()
        if self._current_item is not self._DONE:
            treetick.tick_node(self.decorated, seen)
        self._finish()
        seen[self] = self.status

    def _finish(self) -> None:
        new_status = self.update()
        if new_status != Status.RUNNING:
            treetick.stop(self, new_status)
        self.status = new_status

    def initialise(self) -> None:
        items = self.source()
        if items is MISSING or items is None:
            items = []
        self._not_a_list = None
        if not isinstance(items, (list, tuple)):
            kind = ("a dict" if isinstance(items, dict) else "a string" if isinstance(items, str)
                    else "a number" if isinstance(items, (int, float)) else type(items).__name__)
            self._not_a_list = Feedback(f"the source is not a list but {kind}: {words(items)}",
                                        source=items)
            items = []
        self._iterator = iter(list(items))
        self.index = -1
        self._advance()

    def _advance(self) -> None:
        try:
            self._current_item = next(self._iterator)
        except StopIteration:
            self._current_item = self._DONE
            return
        self.index += 1
        self.blackboard.set(self.target_key, self._current_item)
        if self.output_hook is not None:
            self.output_hook(self, "as", self.target_key, self._current_item)
        # counted from 1 for a person; the item itself travels as a value
        self.feedback_message = Feedback(f"item {self.index + 1}: {words(self._current_item)}",
                                         item=self._current_item)

    def update(self) -> Status:
        stop_on = Status.SUCCESS if self.until == "success" else Status.FAILURE
        go_on = Status.FAILURE if self.until == "success" else Status.SUCCESS
        if self._not_a_list is not None:
            self.feedback_message = self._not_a_list
            return Status.FAILURE
        if self._current_item is self._DONE:
            return go_on
        child_status = self.decorated.status
        if child_status == stop_on:
            return stop_on
        if child_status == go_on:
            self._advance()
            return go_on if self._current_item is self._DONE else Status.RUNNING
        return child_status

    def terminate(self, new_status: Status) -> None:
        self._iterator = None
        self._current_item = self._DONE


# ---------------------------------------------------------------------------------------
# Conditions
# ---------------------------------------------------------------------------------------
_OPS: dict[str, Callable[[Any, Any], bool]] = {
    "==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le,
    ">": operator.gt, ">=": operator.ge,
    "in": lambda a, b: a in b, "not in": lambda a, b: a not in b,
}


def evaluate(expr: Expr, read: Reader) -> tuple[bool, str]:
    """Evaluate a parsed condition; an unset key or an impossible comparison is False.
    ``&&`` and ``||`` short-circuit left to right; the message is the part that decided."""
    if expr.either:
        message = ""
        for group in expr.either:
            ok = True
            for part in group:
                ok, message = evaluate(part, read)
                if not ok:
                    break
            if ok:
                return True, message
        return False, message
    left = read(expr.left)
    if left is MISSING:
        return False, f"{expr.text}: not set"
    if expr.op is None:
        value = bool(left) != expr.negate
        return value, Feedback(f"{expr.text}: {value}", value=left)
    right = read(expr.right)
    if right is MISSING:
        return False, f"{expr.text}: not set"
    try:
        value = bool(_OPS[expr.op](left, right))
    except TypeError:
        return False, Feedback(f"{expr.text}: cannot compare {_said(left)} and {_said(right)}",
                               left=left, right=right)
    return value, Feedback(f"{expr.text}: {_said(left)} {expr.op} {_said(right)} is {value}",
                           left=left, right=right)


def _said(value: Any) -> str:
    """An operand in a condition's message: a number or a string as the mission file writes
    it, a list or a dict in words within parentheses, an empty one ``nothing`` (never a
    Python repr)."""
    if value is None or isinstance(value, (str, int, float, bool)):
        return repr(value)
    if isinstance(value, (list, tuple, dict)) and not value:
        return "nothing"
    return f"({words(value)})" if isinstance(value, (list, tuple, dict)) else words(value)


class Condition(Behaviour):
    """Success when the condition holds, failure otherwise; never running."""

    def __init__(self, name: str, expr: Expr, read: Reader):
        super().__init__(name=name)
        self.expr = expr
        self.read = read

    def update(self) -> Status:
        ok, self.feedback_message = evaluate(self.expr, self.read)
        return Status.SUCCESS if ok else Status.FAILURE


class Guard(DeepestFirst, py_trees.decorators.EternalGuard):
    """Run the child while the condition holds; checked every tick, and when it stops
    holding the child is halted and the guard fails (py_trees' EternalGuard)."""

    def __init__(self, name: str, child: Behaviour, expr: Expr, read: Reader):
        self.expr = expr
        self.read = read
        super().__init__(name=name, child=child, condition=self._check)

    def _check(self) -> bool:
        ok, message = evaluate(self.expr, self.read)
        if not ok:
            self.feedback_message = message
        return ok


class Message(Behaviour):
    """``succeed``/``fail`` leaves: a fixed status and an optional feedback message."""

    def __init__(self, name: str, status: Status, message: str = ""):
        super().__init__(name=name)
        self.result = status
        self.message = message

    def update(self) -> Status:
        self.feedback_message = self.message
        return self.result


# ---------------------------------------------------------------------------------------
# Halting helpers and the watch guard
# ---------------------------------------------------------------------------------------
def running_skills(node: Behaviour) -> list[Behaviour]:
    """Running behaviours under ``node`` (inclusive) that can report halting."""
    return [n for n in node.iterate() if n.status == Status.RUNNING and hasattr(n, "is_halting")]


def still_halting(skills: list[Behaviour],
                  on_stopped: Callable[[Behaviour], None] | None = None) -> list[Behaviour]:
    """The skills still reporting ``is_halting()``; ``on_stopped(skill)`` for the others."""
    out = []
    for s in skills:
        try:
            halting = bool(s.is_halting())
        except Exception:  # noqa: BLE001 - a broken skill must not block a cancel
            halting = False
        if halting:
            out.append(s)
        elif on_stopped is not None:
            on_stopped(s)
    return out


def halt_timeout(skills: list[Behaviour]) -> float:
    return max((float(getattr(s, "HALT_TIMEOUT", 0.0)) for s in skills), default=0.0)


class Watch(DeepestFirst, py_trees.decorators.Decorator):
    """Halt and restart the child when a watched runtime parameter changes.

    Each tick compares the parameters' values with those the child started with. On a
    change it halts the child (deepest first), waits while halted skills report
    ``is_halting()`` (at most their HALT_TIMEOUT of clock time), then starts the child again,
    so the child's inputs see the new value. ``restarts`` counts restarts.
    """

    def __init__(self, name: str, child: Behaviour, keys: dict[str, str],
                 read_key: Callable[[str], Any]):
        super().__init__(name=name, child=child)
        self.keys = keys                # param name -> blackboard key
        self.read_key = read_key
        self.clock = None
        self.seen: dict[str, Any] = {}
        self.restarts = 0
        self._halting: list[Behaviour] = []
        self._halt_deadline = 0.0
        self.on_restart: Callable[[Behaviour, dict], None] | None = None
        self.on_stopped: Callable[[Behaviour], None] | None = None

    def setup(self, **kwargs: Any) -> None:
        self.clock = kwargs.get("clock") or self.clock

    def _now(self) -> float:
        return self.clock.now() if self.clock is not None else 0.0

    def _snapshot(self) -> dict[str, Any]:
        return {p: self.read_key(k) for p, k in self.keys.items()}

    def initialise(self) -> None:
        self.seen = self._snapshot()
        self._halting = []

    def tick(self) -> Iterator[Behaviour]:
        if self._before():
            yield from self.decorated.tick()
            self._finish()
        yield self

    def tick_into(self, seen: dict) -> None:
        if self._before():
            treetick.tick_node(self.decorated, seen)
            self._finish()
        seen[self] = self.status

    def _before(self) -> bool:
        """Restart on a changed parameter; False while halted skills are still stopping
        (the watch stays RUNNING without ticking its child)."""
        if self.status != Status.RUNNING:
            self.initialise()
        else:
            now = self._snapshot()
            changed = {p: (self.seen[p], v) for p, v in now.items() if v != self.seen[p]}
            if changed:
                self.seen = now
                self.restarts += 1
                what = ", ".join(f"{p} {_said(o)} -> {_said(n)}" for p, (o, n) in changed.items())
                self.feedback_message = Feedback(f"restarting: {what}",
                                                 {p: [o, n] for p, (o, n) in changed.items()})
                running = running_skills(self.decorated)
                if self.decorated.status != Status.INVALID:
                    treetick.stop(self.decorated, Status.INVALID)
                self._halting = still_halting(running, self.on_stopped)
                self._halt_deadline = self._now() + halt_timeout(self._halting)
                if self.on_restart is not None:
                    self.on_restart(self, changed)
        if self._halting:
            self._halting = still_halting(self._halting, self.on_stopped)
            if self._halting and self._now() < self._halt_deadline:
                self.feedback_message = f"waiting for {len(self._halting)} skill(s) to stop"
                self.status = Status.RUNNING
                return False
            self._halting = []
        return True

    def _finish(self) -> None:
        new_status = self.decorated.status
        if new_status != Status.RUNNING:
            treetick.stop(self, new_status)
        self.status = new_status

    def update(self) -> Status:
        return self.decorated.status


# ---------------------------------------------------------------------------------------
# State machines
# ---------------------------------------------------------------------------------------
class _Model:
    """The ``transitions`` model of one state-machine block (holds ``state``)."""


class StateMachine(FreshStart, py_trees.composites.Composite):
    """A SMACH-style state machine as one tree node.

    Each state runs one child node to completion. Its outcome (``success``/``failure``, a
    nested state machine's own outcome name, or, when the state names an outcome key, that
    key's value after a success) is fed to a ``transitions`` machine as a trigger; the machine moves to the next state or to one of the container's outcomes,
    which ends the block with success or failure (``outcomes`` maps each). Instantly finishing
    states chain within one tick, up to one pass over all states, then the block yields.
    Halting halts the current state's node. ``outcome`` is the container outcome reached.
    """

    def __init__(self, name: str, states: list[tuple[str, Behaviour, dict[str, str]]],
                 initial: str, outcomes: dict[str, str],
                 outcome_readers: dict[str, Callable[[], Any]] | None = None):
        super().__init__(name=name, children=[child for _, child, _ in states])
        self.outcome_readers = outcome_readers or {}
        self.tables = {state: table for state, _, table in states}
        self.initial = initial
        self.outcomes = outcomes
        self.by_state = {state: child for state, child, _ in states}
        self.model = _Model()
        self.machine = Machine(model=self.model, states=list(self.by_state) + list(outcomes),
                               initial=initial, auto_transitions=False)
        for state, _, table in states:
            for outcome, target in table.items():
                self.machine.add_transition(trigger=f"on_{outcome}", source=state, dest=target)
        self.outcome: str | None = None
        self.history: list[tuple[str, str, str]] = []

    @property
    def state(self) -> str:
        return self.model.state

    def initialise(self) -> None:
        self.machine.set_state(self.initial)
        self.outcome = None
        self.history = []

    def tick(self) -> Iterator[Behaviour]:
        self._begin()
        for _ in range(len(self.children) + 1):
            child = self._enter()
            yield from child.tick()
            if self._after(child):
                yield self
                return
        self.status = Status.RUNNING
        yield self

    def tick_into(self, seen: dict) -> None:
        self._begin()
        for _ in range(len(self.children) + 1):
            child = self._enter()
            treetick.tick_node(child, seen)
            if self._after(child):
                seen[self] = self.status
                return
        self.status = Status.RUNNING
        seen[self] = self.status

    def _enter(self) -> Behaviour:
        """The current state's node, ready to tick."""
        child = self.by_state[self.model.state]
        self.current_child = child
        if child.status in (Status.SUCCESS, Status.FAILURE):
            treetick.stop(child, Status.INVALID)   # a state entered again starts afresh
        return child

    def _after(self, child: Behaviour) -> bool:
        """Follow the ticked state's outcome; True when the block yields for this tick
        (the state is running, or the block has ended)."""
        state = self.model.state
        if child.status == Status.RUNNING:
            self.status = Status.RUNNING
            return True
        if isinstance(child, StateMachine):
            outcome = child.outcome or "failure"
        elif child.status != Status.SUCCESS:
            outcome = "failure"
        elif state in self.outcome_readers:
            outcome = self.outcome_readers[state]()
            if outcome is MISSING or outcome not in self.tables[state]:
                # SMACH raises on an unmapped outcome; here the block fails, saying why.
                self.feedback_message = Feedback(
                    f"state {state}: unmapped outcome {_said(outcome)}", outcome=outcome) \
                    if outcome is not MISSING else f"state {state}: outcome key not set"
                self.outcome = None
                treetick.stop(self, Status.FAILURE)
                return True
        else:
            outcome = "success"
        self.model.trigger(f"on_{outcome}")
        self.history.append((state, outcome, self.model.state))
        self.feedback_message = f"{state} --{outcome}--> {self.model.state}"
        if self.model.state in self.outcomes:
            self.outcome = self.model.state
            final = Status.SUCCESS if self.outcomes[self.outcome] == "success" else Status.FAILURE
            treetick.stop(self, final)
            return True
        return False

    def stop(self, new_status: Status = Status.INVALID) -> None:
        for child in self.children:
            if child.status == Status.RUNNING:
                treetick.stop(child, Status.INVALID)
        treetick.composite_stop(self, new_status)


for _node in (ThresholdParallel, ForEach, Watch, StateMachine):
    treetick.register(_node.tick, _node.tick_into)
