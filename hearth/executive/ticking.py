"""Ticking: the tick loop with its rate keeping, and a started mission's tick with its
status diffing.

:class:`TickLoop` is the one loop the executive runs, in its background thread or in
``run_until_idle``: a simulated clock is advanced by one period after each step that did
something (nothing sleeps, runs are deterministic); on a wall clock the loop sleeps until the
next tick is due, and a late tick starts the schedule afresh (no burst of ticks to catch up).

:class:`Run` is a started mission: its tree, tick counter, what was last reported of each
node, and its halting state. :meth:`Run.tick_tree` ticks the tree once (hearth/executive/treetick.py)
and reports what changed.
"""
from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any, Callable

from py_trees import common

import logging

from hearth.executive import nodes, treetick
from hearth.executive.events import EventKind, feedback_data
from hearth.executive.missionfile import plain
from hearth.executive.runlog import RunLog
from hearth.executive.tree import BuiltTree

if TYPE_CHECKING:
    from hearth.executive.scheduler import Submission

Status = common.Status
RUNNING, INVALID = Status.RUNNING, Status.INVALID
log = logging.getLogger("hearth.executive")


class TickLoop:
    """Steps at ``1 / period`` Hz on ``clock`` (see the module docstring)."""

    def __init__(self, clock: Any, period: float):
        self.clock = clock
        self.period = period
        self.simulated = bool(getattr(clock, "simulated", False))
        self._next = 0.0

    def advance(self, did: bool) -> None:
        """After a step: a simulated clock moves on one period if the step did something."""
        if did and self.simulated:
            self.clock.advance(self.period)

    def run(self, step: Callable[[], bool], wait_for_work: Callable[[], bool] | None = None,
            max_ticks: int | None = None) -> int:
        """Call ``step()`` (which advances the clock, see :meth:`advance`) at the tick rate;
        the number of steps that did something.

        Without ``wait_for_work`` it returns at the first step that did nothing, or after
        ``max_ticks``. With it (the background thread) it first calls ``wait_for_work()``,
        which blocks while there is nothing to do and returns False to stop the loop."""
        n = 0
        self._next = self.clock.now()
        while max_ticks is None or n < max_ticks:
            if wait_for_work is not None and not wait_for_work():
                break
            if step():
                n += 1
            elif wait_for_work is None:
                break
            self._pace()
        return n

    def _pace(self) -> None:
        if self.simulated:
            return
        self._next += self.period
        delay = self._next - self.clock.now()
        if delay > 0:
            self.clock.sleep(delay)
        else:
            self._next = self.clock.now()


Emit = Callable[..., None]   # emit(run, kind, path, **data)
Notify = Callable[["Run", EventKind, "str | None", dict], None]


class Run:
    """A started mission (see the module docstring). The executive changes it under its lock.

    ``emit(run, kind, path, **data)`` reports an event (log and subscribers);
    ``notify(run, kind, path, data)`` gives one to the subscribers only. Status changes, most
    events, are written to the log by its hot path and, unless ``quiet`` (nobody subscribes),
    also made Events for the subscribers.
    """

    def __init__(self, sub: "Submission", emit: Emit, notify: Notify):
        self.sub = sub
        self.id = sub.id
        self.emit = emit
        self.notify = notify
        self.tree: BuiltTree | None = None
        self.log: RunLog | None = None
        self.tick = 0
        self.t0 = 0.0
        self.now = 0.0                   # clock time of the current tick
        self.quiet = True
        self.running: dict[Any, None] = {}      # nodes RUNNING after the last tick, deepest first
        self.halting: list = []                  # halted skills still reporting is_halting()
        self.halt_started = 0.0
        self.halt_deadline = 0.0

    def prepare(self, tree: BuiltTree) -> None:
        """Take the built tree: what the diff needs on each node, the hooks that report
        outputs, watch restarts and stopped skills, and the direct tick."""
        self.tree = tree
        for node in tree.root.iterate():
            node.hearth_leaf = not node.children
            node.hearth_path_json = json.dumps(node.hearth_path)
            node.hearth_last = INVALID       # the last status reported
            node.hearth_feedback = ""        # the last feedback reported
            if hasattr(node, "output_hook"):
                node.output_hook = self._on_output
            if isinstance(node, nodes.Watch):
                node.on_restart = self._on_restart
                node.on_stopped = self._on_stopped
        treetick.direct(tree.root)

    def _on_output(self, node: Any, port: str, key: str, value: Any) -> None:
        self.emit(self, EventKind.WRITE, self.tree.path_of.get(id(node)), port=port,
                  key=self.tree.short_key(key), value=plain(value))

    def _on_stopped(self, node: Any) -> None:
        self.emit(self, EventKind.STOPPED, self.tree.path_of.get(id(node)))

    def _on_restart(self, node: Any, changed: dict) -> None:
        self.emit(self, EventKind.RESTART, self.tree.path_of.get(id(node)),
                  changed={k: [plain(o), plain(n)] for k, (o, n) in changed.items()})

    # -- halting ---------------------------------------------------------------------------
    def halt(self, now: float) -> None:
        """Halt the tree (deepest first), report what stopped, and start waiting for the
        halted skills that report ``is_halting()`` (at most their largest HALT_TIMEOUT)."""
        running = nodes.running_skills(self.tree.root)
        halt_tree(self.tree.root)
        self.diff({})
        self.halting = nodes.still_halting(running, self._on_stopped)
        self.halt_started = now
        self.halt_deadline = now + nodes.halt_timeout(self.halting)

    def poll_halting(self) -> list:
        """The halted skills still stopping (a ``stopped`` event for each that has stopped)."""
        self.halting = nodes.still_halting(self.halting, self._on_stopped)
        return self.halting

    def begin_step(self, now: float, quiet: bool) -> None:
        self.now = now
        self.quiet = quiet
        if self.log is not None:
            self.log.begin_tick(self.tick, now)

    def tick_tree(self) -> None:
        """Tick the tree once and report what changed (exceptions propagate: a crashing
        skill fails the mission)."""
        self.diff(treetick.tick(self.tree.root))

    def diff(self, visited: dict) -> None:
        """Status and feedback events for what changed in this tick.

        ``visited`` maps each node ticked to its status as it was yielded. A visited leaf
        that starts again (previous status not RUNNING) is reported even when its status
        repeats, so replay sees every activation. Nodes stopped from above (halted) without
        being ticked, or changed after being yielded, are reported with ``halted``.

        What was last reported of a node lives on the node (``hearth_last``,
        ``hearth_feedback``, set by :meth:`prepare`): this loop runs for every node of every
        tick, and attribute reads are its cheapest lookups."""
        log = self.log
        status_line = log.status if log is not None else None
        tell = None if self.quiet else self._tell
        running: dict = {}   # ordered as ticked: children before parents, deepest first
        running_add = running.setdefault
        changed_after = []
        for node, st in visited.items():
            prev = node.hearth_last
            if st is not prev or (prev is not RUNNING and node.hearth_leaf):
                if status_line is not None:
                    status_line(node.hearth_path_json, st, prev)
                if tell is not None:
                    tell(node, st, prev)
                node.hearth_last = st
            fb = node.feedback_message
            # a new sentence, or the same one with other values (a Feedback's)
            if fb and fb is not node.hearth_feedback and (
                    fb != node.hearth_feedback
                    or getattr(fb, "values", None) != getattr(node.hearth_feedback, "values", None)):
                node.hearth_feedback = fb
                self.emit(self, EventKind.FEEDBACK, node.hearth_path, **feedback_data(fb))
            if node.status is not st:
                changed_after.append(node)
            elif st is RUNNING:
                running_add(node)
        for node in self.running:
            if node not in visited:
                final = node.status
                prev = node.hearth_last
                if final is not prev:
                    self._status(node, final, prev, True)
                    node.hearth_last = final
                if final is RUNNING:
                    running_add(node)
        for node in changed_after:
            final = node.status
            self._status(node, final, node.hearth_last, True)
            node.hearth_last = final
            if final is RUNNING:
                running_add(node)
        if log is not None:
            log.flush()
        self.running = running

    def _status(self, node: Any, st: Status, prev: Status, halted: bool = False) -> None:
        if self.log is not None:
            self.log.status(node.hearth_path_json, st, prev, halted)
        if not self.quiet:
            self._tell(node, st, prev, halted)

    def _tell(self, node: Any, st: Status, prev: Status, halted: bool = False) -> None:
        data = {"status": st._value_, "previous": prev._value_}
        if halted:
            data["halted"] = True
        self.notify(self, EventKind.STATUS, node.hearth_path, data)

    def reason(self, status: Status) -> str:
        """In words: the deepest failing node's feedback, or 'completed'."""
        if status == Status.SUCCESS:
            return "completed"
        node = self.tree.root
        while True:
            failed = [c for c in node.children if c.status == Status.FAILURE]
            if not failed:
                break
            node = failed[-1]
        path = self.tree.path_of.get(id(node), node.name)
        return f"{path} failed" + (f": {node.feedback_message}" if node.feedback_message else "")


def halt_tree(root: Any) -> None:
    """Halt every running node, deepest first; a terminate that raises does not keep the
    others from being halted."""
    try:
        if root.status != Status.INVALID:
            treetick.stop(root, Status.INVALID)
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
