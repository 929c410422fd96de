"""The command service: the executive, the vocabulary, the approvals and the event hub
behind one thread-safe object. The HTTP API (api.py) is a thin layer over it; a dialogue
system in the same process may use it directly.

No command lost or run twice: every accepted submission gets a run id at once (the
executive queues or preempts by priority); a client that retries with the same
idempotency key gets the same run back (and 409 if the key is reused for something else).
"""
from __future__ import annotations

import asyncio
import hashlib
import json
import threading
import time
from collections import OrderedDict, deque
from itertools import repeat
from dataclasses import dataclass
from typing import Any

from hearth.executive.autonomy import Approvals
from hearth.executive.command.commands import Interpretation, interpret
from hearth.executive.command.vocabulary import Vocabulary, load_catalogue
from hearth.executive.events import TERMINAL, EventKind, json_default
from hearth.executive.missionfile import plain
from hearth.skills.base import json_value

#: executive event kinds not forwarded (``tick``: one per tick on a wall clock; ``map``: the
#: hub hears the map directly, also while no mission runs)
_DROPPED = {EventKind.TICK, EventKind.MAP}


class NotFound(LookupError):
    """An unknown mission, run, parameter or approval request (HTTP 404)."""


class Conflict(RuntimeError):
    """The request clashes with the state (HTTP 409): an idempotency key reused for another
    request, a run that has already ended, an approval already decided."""


class EventHub:
    """Numbered events (``seq`` from 1) in a ring buffer. ``publish`` from any thread is
    O(1) (the executive's event delivery calls it for every event); asyncio readers wake on
    new events. Each item is ``(seq, kind, run, text, ends_run)``: ``ends_run`` marks the
    event that reports a run's end (its ``run`` event in a terminal state)."""

    def __init__(self, keep: int = 50_000):
        self._lock = threading.Lock()
        self._buf: deque[tuple[int, str, str | None, str, bool]] = deque(maxlen=keep)
        # A stream that follows one run reads that run's events and the run-less ones (map,
        # vocabulary, autonomy) without scanning everybody else's (50 clients each
        # following their own run would otherwise rescan every event).
        self._by_run: OrderedDict[str, deque] = OrderedDict()
        self._global: deque = deque(maxlen=2000)
        self._keep_runs = 5000
        self.last_seq = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._event: asyncio.Event | None = None
        # Streams following one run wait on that run's event, set only when the run (or
        # nobody: a run-less event) has news: 50 clients each following their own run are
        # not all woken by every event (event loop only; an event here is never set).
        self._run_events: dict[str, asyncio.Event] = {}
        self._news: set[str | None] = set()     # runs with events since the last wake
        self._wake_pending = False

    def attach_loop(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        self._event = asyncio.Event()
        self._run_events = {}

    def publish(self, kind: str, data: dict[str, Any], run: str | None = None,
                ends_run: bool = False) -> int:
        text = json.dumps(data, default=json_default)
        with self._lock:
            self.last_seq += 1
            seq = self.last_seq
            item = (seq, kind, run, text, ends_run)
            self._buf.append(item)
            self._news.add(run)
            if run is None:
                self._global.append(item)
            else:
                per = self._by_run.get(run)
                if per is None:
                    per = self._by_run[run] = deque(maxlen=10_000)
                    if len(self._by_run) > self._keep_runs:
                        self._by_run.popitem(last=False)
                per.append(item)
            wake = self._loop is not None and not self._wake_pending
            if wake:
                self._wake_pending = True
        if wake:
            try:
                self._loop.call_soon_threadsafe(self._wake)
            except RuntimeError:   # the loop has closed (server shutting down)
                pass
        return seq

    def _wake(self) -> None:
        with self._lock:
            self._wake_pending = False
            news, self._news = self._news, set()
        old, self._event = self._event, asyncio.Event()
        old.set()
        if None in news or len(self._run_events) > 1000:
            # Run-less news concerns every stream (and the bound drops the events of runs
            # whose streams left before any news: a spurious wake is harmless).
            woken, self._run_events = list(self._run_events.values()), {}
        else:
            woken = [e for e in map(self._run_events.pop, news, repeat(None)) if e is not None]
        for event in woken:
            event.set()

    def waiter(self, run: str | None = None) -> asyncio.Event:
        """The event to await for news (take it before reading with ``since``): any news,
        or with ``run`` news of that run or of no run; call from the event loop (attaches it
        if the app's lifespan did not)."""
        if self._event is None:
            self.attach_loop(asyncio.get_running_loop())
        if run is None:
            return self._event
        event = self._run_events.get(run)
        if event is None:
            event = self._run_events[run] = asyncio.Event()
        return event

    def since(self, seq: int, limit: int = 1000, run: str | None = None
              ) -> tuple[list[tuple[int, str, str | None, str, bool]], bool]:
        """Events after ``seq`` (at most ``limit``) and whether some were already dropped.
        With ``run``: only that run's events and the run-less ones."""
        with self._lock:
            if not self._buf or seq >= self.last_seq:
                return [], False
            if run is not None:
                per = self._by_run.get(run, ())
                mine = _after(per, seq)
                other = _after(self._global, seq)
                items = sorted(mine + other)[:limit] if other else mine[:limit]
                gap = bool(per) and per[0][0] > seq + 1 and len(per) == per.maxlen
                return items, gap
            first = self._buf[0][0]
            start = max(seq + 1 - first, 0)
            gap = seq + 1 < first
            n = len(self._buf)
            items = [self._buf[i] for i in range(start, min(n, start + limit))]
        return items, gap


def _after(items: deque, seq: int) -> list:
    """The items of ``items`` (in ``seq`` order) numbered after ``seq``, read from the newest
    back: a stream woken for one new event reads that one, not the whole buffer (a run's
    holds up to 10,000, the run-less one 2,000)."""
    out = []
    for item in reversed(items):
        if item[0] <= seq:
            break
        out.append(item)
    out.reverse()
    return out


@dataclass
class RunRecord:
    """A submitted mission as the API shows it."""
    handle: Any
    mission: str
    priority: int
    params: dict[str, Any]
    submitted: float
    source: str
    idempotency_key: str | None = None

    @property
    def id(self) -> str:
        return self.handle.id

    def to_json(self) -> dict[str, Any]:
        h = self.handle
        r = h.result
        return {"id": h.id, "mission": self.mission, "status": h.status,
                "priority": self.priority, "params": plain(self.params),
                "submitted": self.submitted, "source": self.source,
                "result": None if r is None else {"outcome": r.outcome, "reason": r.reason,
                                                  "outputs": json_value(plain(r.outputs)),
                                                  "ticks": r.ticks,
                                                  "duration": r.duration,
                                                  "robot_stopped": r.robot_stopped}}


class CommandService:
    """See the module docstring. ``mission_paths``: mission files or directories (only these
    missions can be asked for, by name: the network never names files)."""

    def __init__(self, executive: Any, world: Any, mission_paths: list[str],
                 approvals: Approvals | None = None, keep_runs: int = 2000):
        self.executive = executive
        self.world = world
        self.approvals = approvals or Approvals()
        self.hub = EventHub()
        self._map_changes: deque[dict[str, Any]] = deque(maxlen=100)
        self._unsubs = []
        if world is not None and callable(getattr(world, "subscribe", None)):
            # Before the vocabulary's subscription: a change is streamed before the new
            # vocabulary revision it causes.
            self._unsubs.append(world.subscribe(self._on_map))
        catalogue, self.catalogue_problems = load_catalogue(mission_paths, executive.load)
        self.vocabulary = Vocabulary(world, catalogue, on_change=self._vocabulary_changed)
        self._lock = threading.RLock()
        self._runs: OrderedDict[str, RunRecord] = OrderedDict()
        self._keep_runs = keep_runs
        self._idem: OrderedDict[str, tuple[str, str]] = OrderedDict()   # key -> (fingerprint, run)
        self._live: dict[str, tuple[dict[str, str], dict[str, dict]]] = {}
        self._unsubs += [executive.subscribe(self._on_event),
                         self.approvals.subscribe(self._on_approval)]
        self.started = time.time()

    def close(self) -> None:
        for u in self._unsubs:
            u()
        self._unsubs = []
        self.vocabulary.close()

    # -- events ------------------------------------------------------------------------
    def _on_event(self, ev: Any) -> None:
        # The executive's event delivery (one thread, in order, outside the executive's
        # lock): keep it short, every event of every run passes here.
        kind = ev.kind
        if kind in _DROPPED:
            return
        if ev.path is not None and kind in (EventKind.STATUS, EventKind.FEEDBACK):
            # A run may report before submit() has filed its record, so its nodes live apart.
            live = self._live.get(ev.run)
            if live is None:
                live = self._live.setdefault(ev.run, ({}, {}))
            if kind is EventKind.STATUS:
                live[0][ev.path] = ev.data.get("status", "")
            else:
                live[1][ev.path] = ev.data
        ends = kind is EventKind.RUN and ev.data.get("state") in TERMINAL
        self.hub.publish(kind, ev.to_json(), run=ev.run, ends_run=ends)

    def _on_approval(self, kind: str, data: dict) -> None:
        self.hub.publish(kind, {"e": kind, **data}, run=data.get("run"))

    def _on_map(self, change: Any) -> None:
        data = {"e": "map", "node": change.node, "field": change.field,
                "old": plain(change.old), "new": plain(change.new), "source": change.source,
                "time": change.time}
        self._map_changes.append(data)
        self.hub.publish("map", data)

    def _vocabulary_changed(self, revision: int) -> None:
        self.hub.publish("vocabulary", {"e": "vocabulary", "revision": revision})

    # -- missions ------------------------------------------------------------------------
    def missions(self) -> list[dict[str, Any]]:
        return [e.to_json() for e in self.vocabulary.catalogue.values()]

    def _entry(self, name: str):
        entry = self.vocabulary.catalogue.get(name)
        if entry is None:
            known = ", ".join(sorted(self.vocabulary.catalogue)) or "none"
            raise NotFound(f"no mission named {name!r} (known: {known})")
        return entry

    def _claim(self, key: str | None, fingerprint: str) -> RunRecord | None:
        """The run already made for this idempotency key, or None (lock held)."""
        if key is None:
            return None
        seen = self._idem.get(key)
        if seen is None:
            return None
        if seen[0] != fingerprint:
            raise Conflict(f"idempotency key {key!r} was used for a different request")
        return self._runs.get(seen[1])

    def submit(self, mission: str, params: dict[str, Any] | None = None, priority: int = 0,
               idempotency_key: str | None = None, source: str = "api"
               ) -> tuple[RunRecord, bool]:
        """Queue ``mission`` (a catalogue name). Returns (record, created); created is False
        when the idempotency key had already made this run. MissionError: bad parameters."""
        got = self._submit(mission, params, priority, idempotency_key, source, blocking=True)
        assert got is not None
        return got

    def try_submit(self, mission: str, params: dict[str, Any] | None = None, priority: int = 0,
                   idempotency_key: str | None = None, source: str = "api"
                   ) -> tuple[RunRecord, bool] | None:
        """:meth:`submit`, or None without having done anything when a lock it needs (this
        service's, the executive's, the map's) is held by another thread: the HTTP API
        submits on its event loop when nothing is in the way, and from a worker thread
        otherwise, so the loop never waits on a tick."""
        return self._submit(mission, params, priority, idempotency_key, source,
                            blocking=False)

    def _submit(self, mission: str, params: dict[str, Any] | None, priority: int,
                idempotency_key: str | None, source: str, blocking: bool
                ) -> tuple[RunRecord, bool] | None:
        params = dict(params or {})
        entry = self._entry(mission)
        fp = hashlib.sha256(json.dumps([mission, params, priority], sort_keys=True,
                                       default=repr).encode()).hexdigest()
        if not self._lock.acquire(blocking=blocking):
            return None
        try:
            old = self._claim(idempotency_key, fp)
            if old is not None:
                return old, False
            if blocking:
                handle = self.executive.submit(entry.mission, priority=priority, **params)
            else:
                handle = self.executive.try_submit(entry.mission, priority, params)
                if handle is None:
                    return None
            rec = RunRecord(handle=handle, mission=mission, priority=priority,
                            params=dict(handle.params), submitted=time.time(), source=source,
                            idempotency_key=idempotency_key)
            self._runs[handle.id] = rec
            while len(self._runs) > self._keep_runs:
                oldest_id, oldest = next(iter(self._runs.items()))
                if not oldest.handle.done:
                    break
                self._runs.pop(oldest_id)
                self._live.pop(oldest_id, None)
            if idempotency_key is not None:
                self._idem[idempotency_key] = (fp, handle.id)
                while len(self._idem) > 10 * self._keep_runs:
                    self._idem.popitem(last=False)
        finally:
            self._lock.release()
        self.hub.publish("submitted", {"e": "submitted", "run": handle.id, "mission": mission,
                                       "priority": priority, "params": plain(rec.params),
                                       "source": source}, run=handle.id)
        return rec, True

    def command(self, text: str, priority: int = 0, idempotency_key: str | None = None
                ) -> tuple[Interpretation, RunRecord | None, bool]:
        """Interpret an utterance; start its mission when it is understood."""
        entries = self.vocabulary.catalogue
        it = interpret(text, self.vocabulary.templates, self.world,
                       {n: e.mission for n, e in entries.items()})
        if it.outcome != "run":
            return it, None, False
        rec, created = self.submit(it.mission, it.params, priority, idempotency_key,
                                   source=f"command: {text}")
        return it, rec, created

    # -- runs ------------------------------------------------------------------------------
    def run(self, run_id: str) -> RunRecord:
        with self._lock:
            rec = self._runs.get(run_id)
        if rec is None:
            raise NotFound(f"no run {run_id!r}")
        return rec

    def runs(self, limit: int = 50) -> list[RunRecord]:
        with self._lock:
            recs = list(self._runs.values())
        return recs[-limit:][::-1]

    def cancel(self, run_id: str, reason: str = "cancelled by a client") -> RunRecord:
        rec = self.run(run_id)
        if not rec.handle.cancel(reason):
            raise Conflict(f"run {run_id} has already ended ({rec.handle.status})")
        return rec

    def tree(self, run_id: str) -> dict[str, Any]:
        """The run's tree: nodes with their last reported status and feedback (the sentence,
        and the values it carried: ``{}`` when none)."""
        rec = self.run(run_id)
        live = self._live.get(run_id, ({}, {}))
        statuses, feedback = dict(live[0]), dict(live[1])

        def node(spec: Any) -> dict[str, Any]:
            return {"path": spec.path, "name": spec.name, "kind": spec.kind,
                    "label": spec.label, "status": statuses.get(spec.path, "INVALID"),
                    "feedback": feedback.get(spec.path, {}).get("message", ""),
                    "values": feedback.get(spec.path, {}).get("values", {}),
                    "children": [node(c) for c in spec.children]}
        return {"run": rec.id, "mission": rec.mission, "status": rec.handle.status,
                "root": node(rec.handle.mission.root)}

    def current(self) -> RunRecord | None:
        h = self.executive.current
        if h is None:
            return None
        with self._lock:
            return self._runs.get(h.id)

    # -- parameters ------------------------------------------------------------------------
    def runtime_parameters(self) -> dict[str, list]:
        """name -> the missions declaring it as a runtime parameter."""
        out: dict[str, list] = {}
        for e in self.vocabulary.catalogue.values():
            for p in e.mission.parameters.values():
                if p.runtime:
                    out.setdefault(p.name, []).append(p)
        return out

    def parameters(self) -> dict[str, Any]:
        current = self.executive.parameters
        out = {}
        for name, specs in self.runtime_parameters().items():
            spec = specs[0]
            out[name] = {"value": plain(current.get(name, spec.default)), "type": spec.type,
                         "enum": plain(spec.enum), "description": spec.description}
        return out

    def set_parameter(self, name: str, value: Any) -> Any:
        specs = self.runtime_parameters().get(name)
        if specs is None:
            known = ", ".join(sorted(self.runtime_parameters())) or "none"
            raise NotFound(f"no mission declares a runtime parameter {name!r} (known: {known})")
        for spec in specs:
            spec.check(value)          # MissionError(param=name)
        self.executive.set_parameter(name, value)
        self.hub.publish("param", {"e": "param", "name": name, "value": plain(value)})
        return value

    # -- approvals ---------------------------------------------------------------------------
    def decide(self, request_id: str, approve: bool, by: str = "operator", reason: str = ""):
        try:
            return self.approvals.decide(request_id, approve, by=by, reason=reason)
        except KeyError:
            raise NotFound(f"no approval request {request_id!r}") from None
        except ValueError as err:
            raise Conflict(str(err)) from None

    # -- map ---------------------------------------------------------------------------------
    def map_view(self) -> dict[str, Any]:
        w = self.world
        if w is None:
            return {"rooms": [], "recent_changes": list(self._map_changes)}
        rooms = []
        with w.lock:
            for r in w.rooms:
                objs = []
                for o in r.objects:
                    p = w.world_pose(o.id)
                    entry = {"id": o.id, "label": w.label(o.id), "type": o.type,
                             "x": round(p.x, 3), "y": round(p.y, 3), "yaw": round(p.yaw, 4),
                             "parts": [], "knobs": [], "contents": []}
                    for node in w.descendants(o.id):
                        if node.kind == "Part":
                            entry["parts"].append({"id": node.id, "label": w.label(node.id),
                                                   "state": node.joint.state})
                        elif node.kind == "Knob":
                            entry["knobs"].append({"id": node.id, "state": node.state})
                        elif node.kind == "SmallObject":
                            entry["contents"].append({"id": node.id, "label": w.label(node.id),
                                                      "where": w.describe_location(node.id)})
                    objs.append(entry)
                rooms.append({"id": r.id, "name": r.name or r.id,
                              "bounds": list(r.bounds) if r.bounds else None, "objects": objs})
        return {"rooms": rooms, "recent_changes": list(self._map_changes)[::-1]}

