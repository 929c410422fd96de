"""Tick a py_trees tree by direct calls instead of nested generators.

py_trees ticks a tree through nested generators: every node a tick visits is yielded up
through each of its ancestors' generators, and every ``tick()`` and ``stop()`` formats a
debug message (with enum formatting) whether or not debug logging is on. For the 200-node
benchmark tree that is most of a tick's cost (see docs/missions.md, "Performance"). No
library offers a cheaper tick, so this module transcribes py_trees 2.6's ``tick()`` and
``stop()`` of the classes Hearth builds (Behaviour, Sequence, Selector, Parallel, Decorator,
EternalGuard) as plain functions; Hearth's own nodes (hearth/executive/nodes.py) register their
direct ticks here beside their generator ticks.

    seen = tick(root)     # {node: status as py_trees would have yielded it}, in yield order

The result is what ``{n: n.status for n in root.tick()}`` gives: the same calls of
``initialise``/``update``/``terminate`` in the same order, the same statuses and feedback.
A tree holding a node whose class overrides ``tick`` with code this module does not know is
ticked by py_trees' generators; a class with its own ``stop`` is stopped by that method. The
direct path is used only with the py_trees versions it was transcribed from and only while
py_trees' debug logging is off (with it on, py_trees' own methods run, printing their
messages).
tests/executive/test_treetick.py checks equality against py_trees' generators on random
trees of every node kind.
"""
from __future__ import annotations

from importlib import metadata
from typing import Any, Callable

import py_trees
from py_trees import common
from py_trees.behaviour import Behaviour
from py_trees.composites import Composite, Parallel, Selector, Sequence
from py_trees.decorators import Decorator, EternalGuard

Status = common.Status
RUNNING, SUCCESS, FAILURE, INVALID = Status.RUNNING, Status.SUCCESS, Status.FAILURE, Status.INVALID
_STATUSES = tuple(Status)

#: py_trees versions whose tick()/stop() code is transcribed below.
TRANSCRIBED = ("2.6.",)
try:
    ENABLED = metadata.version("py_trees").startswith(TRANSCRIBED)
except metadata.PackageNotFoundError:  # pragma: no cover - py_trees vendored without metadata
    ENABLED = False

Seen = dict
TickFn = Callable[[Any, Seen], None]
StopFn = Callable[[Any, Status], None]

_TICKS: dict[Any, TickFn] = {}      # a class's tick function -> its direct tick
_STOPS: dict[Any, StopFn] = {}      # a class's stop function -> its direct stop


def register(tick_fn: Any = None, direct_tick: TickFn | None = None, stop_fn: Any = None,
             direct_stop: StopFn | None = None) -> None:
    """Declare ``direct_tick(node, seen)`` equivalent to the generator ``tick_fn`` (and
    ``direct_stop(node, status)`` to ``stop_fn``) for classes whose method is that function."""
    if tick_fn is not None:
        _TICKS[tick_fn] = direct_tick
    if stop_fn is not None:
        _STOPS[stop_fn] = direct_stop
        _generation[0] += 1


# Each class caches its direct stop in its own __dict__ (no global cache keeping classes
# alive: replay and substitution make classes per run), tagged with the registry generation.
_generation = [0]


_INFO = py_trees.logging.Level.INFO


def _debug_on() -> bool:
    return py_trees.logging.level < _INFO


def direct(root: Behaviour) -> bool:
    """Whether every node under ``root`` has a known direct tick (and if so, give each node
    its direct tick and stop, ``_treetick`` and ``_treestop``, for the tick functions below). Decided once per root: Hearth builds a run's tree once; a tree changed
    after its first tick keeps the first answer."""
    ok = root.__dict__.get("_treetick_direct")
    if ok is None:
        nodes = list(root.iterate())
        ok = ENABLED and all(_known(n) for n in nodes)
        if ok:
            for n in nodes:
                n._treetick = _TICKS[type(n).tick]
                n._treestop = _STOPS.get(type(n).stop, _stop_method)
        root._treetick_direct = ok
    return ok


def _known(node: Any) -> bool:
    cls = type(node)
    if cls.tick not in _TICKS:
        return False
    if isinstance(node, Parallel) and cls.tick is Parallel.tick:
        return (isinstance(node.policy, (common.ParallelPolicy.SuccessOnAll,
                                         common.ParallelPolicy.SuccessOnOne))
                and cls.validate_policy_configuration is Parallel.validate_policy_configuration)
    return True


def tick(root: Behaviour) -> Seen:
    """Tick ``root`` once; each node visited with its status as py_trees yields it.

    A tree with a node this module does not know (its class has its own ``tick``) is ticked
    by py_trees' generators throughout: a parent reacts to a child's every yield of itself,
    which only generators reproduce for code that may yield itself before its end."""
    seen: Seen = {}
    if not direct(root) or _debug_on():
        for node in root.tick():
            seen[node] = node.status
        return seen
    root._treetick(root, seen)
    return seen


def tick_node(node: Any, seen: Seen) -> None:
    """Tick one node (and what it ticks below it) into ``seen``; only within :func:`tick`
    of a tree that :func:`direct` accepted."""
    node._treetick(node, seen)


def stop(node: Any, new_status: Status) -> None:
    """``node.stop(new_status)`` without py_trees' debug formatting (when it is off)."""
    cls = type(node)
    cached = cls.__dict__.get("_treetick_stop")
    if cached is None or cached[0] != _generation[0]:
        cached = (_generation[0], _STOPS.get(cls.stop, _stop_method) if ENABLED else _stop_method)
        cls._treetick_stop = cached
    fn = cached[1]
    if fn is not _stop_method and _debug_on():
        fn = _stop_method
    fn(node, new_status)


def _stop_method(node: Any, new_status: Status) -> None:
    node.stop(new_status)


def _checked(node: Any, new_status: Any) -> Status:
    if new_status not in _STATUSES:
        node.logger.error(f"A behaviour returned an invalid status, setting to INVALID "
                          f"[{new_status}][{node.name}]")
        return INVALID
    return new_status


# -- py_trees 2.6, transcribed (behaviour.py, composites.py, decorators.py) ------------------
def _behaviour_tick(node: Any, seen: Seen) -> None:
    if node.status is not RUNNING:
        node.initialise()
    new_status = node.update()
    if new_status not in _STATUSES:
        new_status = _checked(node, new_status)
    if new_status is not RUNNING:
        node._treestop(node, new_status)
    node.status = new_status
    seen[node] = new_status


def _behaviour_stop(node: Any, new_status: Status) -> None:
    # py_trees also sets ``node.iterator = node.tick()``, a fresh generator nothing reads.
    node.terminate(new_status)
    node.status = new_status


def composite_stop(node: Any, new_status: Status) -> None:
    """py_trees' ``Composite.stop``, stopping children through :func:`stop` (and without
    recreating ``node.iterator``)."""
    if not ENABLED:
        Composite.stop(node, new_status)
        return
    if new_status is INVALID:
        node.current_child = None
        for child in node.children:
            if child.status is not INVALID:
                stop(child, new_status)
    node.terminate(new_status)
    node.status = new_status


def _parallel_stop(node: Any, new_status: Status) -> None:
    for child in node.children:
        if child.status is RUNNING:
            stop(child, INVALID)
    composite_stop(node, new_status)


def _decorator_stop(node: Any, new_status: Status) -> None:
    node.terminate(new_status)
    child = node.decorated
    if new_status is INVALID:
        stop(child, new_status)
    if child.status is RUNNING:
        stop(child, INVALID)
    node.status = new_status


def _sequence_tick(node: Any, seen: Seen) -> None:
    children = node.children
    index = 0
    if node.status is not RUNNING:
        node.current_child = children[0] if children else None
        for child in children:
            if child.status is not INVALID:
                child._treestop(child, INVALID)
        node.initialise()
    elif node.memory and node.current_child is not None:
        index = children.index(node.current_child)
    else:
        node.current_child = children[0] if children else None
    if not children:
        node.current_child = None
        node._treestop(node, SUCCESS)
        seen[node] = node.status
        return
    n = len(children)
    for child in children[index:]:
        child._treetick(child, seen)
        status = child.status
        if status is not SUCCESS:
            if not node.memory:
                for later in children[index + 1:]:
                    if later.status is not INVALID:
                        later._treestop(later, INVALID)
            if status is not RUNNING:
                node._treestop(node, status)
            else:
                node.status = status
            seen[node] = node.status
            return
        if index + 1 < n:
            node.current_child = children[index + 1]
            index += 1
    node._treestop(node, SUCCESS)
    seen[node] = node.status


def _selector_tick(node: Any, seen: Seen) -> None:
    children = node.children
    if node.status is not RUNNING:
        node.current_child = children[0] if children else None
        node.initialise()
    if not children:
        node.current_child = None
        node._treestop(node, FAILURE)
        seen[node] = node.status
        return
    if node.memory:
        index = children.index(node.current_child)
        for child in children[:index]:
            if child.status is not INVALID:
                child._treestop(child, INVALID)
    else:
        index = 0
    previous = node.current_child
    for child in children[index:]:
        child._treetick(child, seen)
        status = child.status
        if status is RUNNING or status is SUCCESS:
            node.current_child = child
            if previous is None or previous != child:
                passed = False
                for other in children:
                    if passed and other.status is not INVALID:
                        other._treestop(other, INVALID)
                    passed = True if other == child else passed
            if status is SUCCESS:
                node._treestop(node, status)
            else:
                node.status = status
            seen[node] = node.status
            return
    node._treestop(node, FAILURE)
    node.current_child = children[-1] if children else None
    seen[node] = node.status


def _parallel_tick(node: Any, seen: Seen) -> None:
    # SuccessOnAll or SuccessOnOne (see _known): validate_policy_configuration checks nothing
    policy = node.policy
    children = node.children
    if node.status is not RUNNING:
        for child in children:
            if child.status is not INVALID:
                child._treestop(child, INVALID)
        node.current_child = None
        node.initialise()
    if not children:
        node.current_child = None
        node._treestop(node, SUCCESS)
        seen[node] = node.status
        return
    synchronise = policy.synchronise
    for child in children:
        if synchronise and child.status is SUCCESS:
            continue
        child._treetick(child, seen)
    new_status = RUNNING
    node.current_child = children[-1]
    all_succeeded = True       # one pass: the first failure, else whether all succeeded
    for child in children:
        status = child.status
        if status is FAILURE:
            node.current_child = child
            new_status = FAILURE
            break
        if status is not SUCCESS:
            all_succeeded = False
    else:
        if isinstance(policy, common.ParallelPolicy.SuccessOnAll):
            if all_succeeded:
                new_status = SUCCESS
                node.current_child = children[-1]
        else:
            for child in reversed(children):
                if child.status is SUCCESS:
                    new_status = SUCCESS
                    node.current_child = child
                    break
    if new_status is not RUNNING:
        node._treestop(node, new_status)
    node.status = new_status
    seen[node] = new_status


def _decorator_tick(node: Any, seen: Seen) -> None:
    if node.status is not RUNNING:
        node.initialise()
    child = node.decorated
    child._treetick(child, seen)
    new_status = node.update()
    if new_status not in _STATUSES:
        new_status = _checked(node, new_status)
    if new_status is not RUNNING:
        node._treestop(node, new_status)
    node.status = new_status
    seen[node] = new_status


def _eternal_guard_tick(node: Any, seen: Seen) -> None:
    result = node.condition()
    if isinstance(result, Status):
        result = False if result == FAILURE else True
    elif not isinstance(result, bool):
        error_message = f"conditional check must return 'bool' or 'common.Status' [{type(result)}]"
        node.logger.error(f"The {error_message}")
        raise RuntimeError(error_message)
    if not result:
        node._treestop(node, FAILURE)
        seen[node] = node.status
    else:
        _decorator_tick(node, seen)


register(Behaviour.tick, _behaviour_tick, Behaviour.stop, _behaviour_stop)
register(Sequence.tick, _sequence_tick, Sequence.stop, composite_stop)
register(Selector.tick, _selector_tick, Selector.stop, composite_stop)
register(Parallel.tick, _parallel_tick, Parallel.stop, _parallel_stop)
register(Decorator.tick, _decorator_tick, Decorator.stop, _decorator_stop)
register(EternalGuard.tick, _eternal_guard_tick)
register(stop_fn=Composite.stop, direct_stop=composite_stop)
