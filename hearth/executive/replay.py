"""Execution logs: read them, print a timeline, and replay a run offline.

An execution log (``runs/<run id>.jsonl``, written by the Executive) is JSON lines: a
``start`` header (mission file and its source text, parameters, tick rate, clock kind,
start time), then one object per event (see ``hearth.executive.executive.Event``; ``e`` is the
kind, ``tick`` the tick number, ``t`` clock seconds), then an ``end`` line (outcome,
reason, outputs).

:func:`replay` re-runs the mission against the logged skill results: every skill is
replaced by a stand-in that returns, at each tick, the status its original returned and
writes the outputs it wrote; parameter changes, cancels and preempts are applied at the
ticks they happened, and a halted skill reports ``is_halting()`` until the tick its
``stopped`` event was logged (mission-level cancels and watch restarts alike). The replayed
timeline (status changes by tick) must equal the logged one; :class:`ReplayReport` says
whether it does and where it first differs. Time-based nodes (timeout) see the logged
times: simulated-clock runs are reproduced exactly; wall-clock runs log each tick's time.
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from py_trees import common

from hearth.executive.errors import MissionError
from hearth.executive.missionfile import NodeSpec, load_mission
from hearth.skills.base import Bindings, Skill

Status = common.Status


def read_log(path: str | Path) -> tuple[dict, list[dict], dict | None]:
    """(header, events, end) of an execution log; MissionError(file:line) if malformed."""
    path = str(path)
    header, events, end = None, [], None
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise MissionError("no such file", file=path, line=0) from None
    for i, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as err:
            raise MissionError(f"not JSON: {err.msg}", file=path, line=i) from None
        if not isinstance(obj, dict) or "e" not in obj:
            raise MissionError("not an execution log event (no 'e')", file=path, line=i)
        if obj["e"] == "start":
            header = obj
        elif obj["e"] == "end":
            end = obj
        else:
            events.append(obj)
    if header is None:
        raise MissionError("no start line: not an execution log", file=path, line=1)
    return header, events, end


def timeline(events: list[dict]) -> list[tuple]:
    """The comparable part of a run: status changes (tick, path, status, halted)."""
    return [(e["tick"], e["path"], e["status"], bool(e.get("halted")))
            for e in events if e["e"] == "status"]


#: Characters a value takes in a printed event line (the log keeps it whole).
VALUE_CHARS = 160
_LONG_FLOAT = re.compile(r"-?\d+\.\d{4,}(?:e-?\d+)?")


def readable(value: Any, limit: int = VALUE_CHARS) -> str:
    """A value as a person reads it in one line: numbers to 3 decimals, mappings as
    ``{k: v}``, poses as ``(x, y, z, yaw)``, long lists and texts cut with "..." and how much
    was left out. (The execution log keeps every value whole.)"""
    text = _readable(value, limit + 1)
    return text if len(text) <= limit else text[:limit - 3].rstrip(", ") + "..."


def readable_text(text: Any, limit: int = VALUE_CHARS) -> str:
    """A message (a skill's feedback) with its long numbers rounded, cut to ``limit``."""
    text = _LONG_FLOAT.sub(lambda m: _num(float(m.group())), str(text))
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _num(v: float) -> str:
    if v == 0 or 0.001 <= abs(v) < 1e7:
        text = f"{v:.3f}".rstrip("0").rstrip(".")
        return "0" if text in ("-0", "") else text
    return f"{v:.2e}"


def _readable(value: Any, budget: int) -> str:
    if isinstance(value, bool) or value is None:
        return repr(value)
    if isinstance(value, float):
        return _num(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        # Values the log could not keep as JSON are their repr (a Pose and numpy values are
        # logged as their JSON form: hearth.executive.events.json_default; logs written
        # before that hold "Pose(x=2.900486012820682, ...)").
        text = _LONG_FLOAT.sub(lambda m: _num(float(m.group())), value)
        return repr(text if len(text) <= budget else text[:budget] + "...")
    if isinstance(value, (dict, list, tuple)):
        items = list(value.items()) if isinstance(value, dict) else list(enumerate(value))
        parts, used = [], 2
        for i, (k, v) in enumerate(items):
            part = _readable(v, max(budget - used, 8))
            if isinstance(value, dict):
                part = f"{k}: {part}"
            if parts and used + len(part) > budget - 10:     # room to say what is left out
                parts.append(f"+{len(items) - i} more")
                break
            parts.append(part)
            used += len(part) + 2
        inner = ", ".join(parts)
        return "{" + inner + "}" if isinstance(value, dict) else "[" + inner + "]"
    if hasattr(value, "x") and hasattr(value, "y"):      # a Pose
        fields = [f for f in ("x", "y", "z", "yaw") if isinstance(getattr(value, f, None), float)]
        return "(" + ", ".join(f"{f}={_num(getattr(value, f))}" for f in fields) + ")"
    return _readable(repr(value), budget)


def format_event(e: dict, t0: float = 0.0) -> str:
    """One line of ``hearth log show`` (and ``hearth run --verbose``): tick, clock seconds
    since ``t0`` (the run's start), what happened; values as :func:`readable` writes them."""
    head = f"{e.get('tick', 0):>6} {e.get('t', 0.0) - t0:>9.3f}s  "
    kind = e["e"]
    path = e.get("path", "")
    if kind == "start":
        return (head + f"start   {e['mission']} ({e['file']}) params={readable(e.get('params'))} "
                f"at {e.get('tick_hz')} Hz, {e.get('clock')} clock")
    if kind == "end":
        return (head + f"end     {e['outcome']}: {e['reason']}  "
                f"outputs={readable(e.get('outputs'))}")
    if kind == "run":
        return head + f"mission {e['state']}" + (f": {e['reason']}" if e.get("reason") else "")
    if kind == "status":
        extra = " (halted)" if e.get("halted") else ""
        return head + f"status  {path} {e['previous']} -> {e['status']}{extra}"
    if kind == "feedback":
        return head + f"feedbk  {path}: {readable_text(e['message'])}" + (
            f"  values={readable(e['values'])}" if e.get("values") else "")
    if kind == "write":
        return head + f"write   {{{e['key']}}} = {readable(e['value'])}  by {path}"
    if kind == "param":
        return head + f"param   ${e['name']} = {readable(e['value'])}"
    if kind == "restart":
        return head + f"restart {path}: {readable(e.get('changed'))}"
    if kind == "map":
        return head + (f"map     {e.get('node')}.{e.get('field')}: {readable(e.get('old'))} -> "
                       f"{readable(e.get('new'))} ({e.get('source')})")
    if kind == "stopped":
        return head + f"stopped {path} (no longer halting)"
    if kind == "halted":
        return head + f"halted  after {e.get('waited')} s" + (
            f", gave up on {e['timed_out']}" if e.get("timed_out") else "")
    if kind == "tick":
        return head + "tick"
    rest = {k: v for k, v in e.items() if k not in ('e', 'tick', 't', 'run')}
    return head + f"{kind} {readable(rest)}"


def in_tick_order(events: list[dict]) -> list[dict]:
    """Events as they happened within each tick.

    A tick's ``write`` events are reported while the tree ticks, its ``status`` and
    ``feedback`` events after it (the executive diffs the tree once per tick), so a log
    holds a tick's writes first. Leaves finish in the order they were ticked, and a skill
    writes while it ticks: each write belongs just before the status line of the node that
    wrote it, and writes of nodes whose status did not change, before the next status line
    that comes after them."""
    out: list[dict] = []
    writes: list[dict] = []
    tick = None
    for e in events:
        if e.get("tick") != tick:
            out.extend(writes)
            writes = []
            tick = e.get("tick")
        if e["e"] == "write":
            writes.append(e)
            continue
        if e["e"] == "status" and writes:
            mine = [i for i, w in enumerate(writes) if w.get("path") == e.get("path")]
            if mine:
                out.extend(writes[:mine[-1] + 1])
                writes = writes[mine[-1] + 1:]
        out.append(e)
    out.extend(writes)
    return out


class _ReplayClock:
    """A simulated clock that the replayer can also set to a logged tick time."""

    simulated = True

    def __init__(self, start: float, epoch: float):
        self._t = start
        self._epoch = epoch

    def now(self) -> float:
        return self._t

    def wall(self) -> float:
        return self._epoch + self._t

    def advance(self, seconds: float) -> None:
        self._t += seconds

    def sleep(self, seconds: float) -> None:
        self._t += max(0.0, seconds)

    def set(self, t: float) -> None:
        self._t = t


class ReplaySkill(Skill):
    """Plays one skill's logged results back (subclassed per skill for NAME and ports)."""

    record: dict = {}

    def __init__(self, name=None, bindings: Bindings | None = None):
        super().__init__(name=name, bindings=bindings)
        self.statuses: dict[int, str] = {}
        self.writes: dict[int, list[tuple[str, Any]]] = {}
        self.halts: list[list] = []    # [halt tick, tick it stopped (None: never)]
        self.current_tick = lambda: 0

    def setup(self, **kwargs: Any) -> None:
        self.clock = kwargs.get("clock")

    def update(self) -> Status:
        t = self.current_tick()
        for port, value in self.writes.get(t, []):
            self.set_output(port, value)
        return Status(self.statuses.get(t, "RUNNING"))

    def is_halting(self) -> bool:
        """As logged: from a halt until the tick its ``stopped`` event was written."""
        t = self.current_tick()
        for halted, stopped in reversed(self.halts):
            if halted <= t:
                return stopped is None or t < stopped
        return False


@dataclass
class ReplayReport:
    original: list[tuple]
    replayed: list[tuple]
    outcome: str | None
    replayed_outcome: str

    @property
    def same(self) -> bool:
        return self.original == self.replayed and self.outcome == self.replayed_outcome

    def first_difference(self) -> str | None:
        for i, (a, b) in enumerate(zip(self.original, self.replayed)):
            if a != b:
                return f"event {i}: logged {a}, replayed {b}"
        if len(self.original) != len(self.replayed):
            return f"logged {len(self.original)} status changes, replayed {len(self.replayed)}"
        if self.outcome != self.replayed_outcome:
            return f"logged outcome {self.outcome}, replayed {self.replayed_outcome}"
        return None


def replay(path: str | Path, skills: dict[str, type] | None = None) -> ReplayReport:
    """Re-run a logged mission against its logged skill results; compare timelines."""
    from hearth.executive.executive import Executive

    header, events, end = read_log(path)
    if header.get("started") is False:     # cancelled while queued: nothing ran
        outcome = end["outcome"] if end else None
        return ReplayReport(original=[], replayed=[], outcome=outcome, replayed_outcome=outcome)
    file = header["file"]
    source = header.get("sources", {}).get(file)
    if source is not None and Path(file).exists():
        if hashlib.sha256(Path(file).read_bytes()).digest() != \
                hashlib.sha256(source.encode()).digest():
            raise MissionError("the mission file changed since this run; replay needs the "
                               "version that ran", file=str(path), line=1)
    mission = load_mission(file, skills)
    skill_paths = {n.path for n in mission.nodes() if n.kind == "skill"}
    statuses: dict[str, dict[int, str]] = {p: {} for p in skill_paths}
    writes: dict[str, dict[int, list]] = {p: {} for p in skill_paths}
    params_at: dict[int, list[tuple[str, Any]]] = {}
    cancel_at: dict[int, tuple[str, str]] = {}
    tick_times: dict[int, float] = {}
    halts: dict[str, list[list]] = {p: [] for p in skill_paths}   # [halt tick, stopped tick]
    for e in events:
        kind, tick = e["e"], e["tick"]
        if kind == "status" and e["path"] in skill_paths and not e.get("halted"):
            statuses[e["path"]][tick] = e["status"]
        elif kind == "status" and e["path"] in skill_paths and e["status"] == "INVALID":
            halts[e["path"]].append([tick, None])
        elif kind == "stopped" and e.get("path") in skill_paths:
            for interval in reversed(halts[e["path"]]):
                if interval[1] is None:
                    interval[1] = tick
                    break
        elif kind == "write" and e.get("path") in skill_paths:
            writes[e["path"]].setdefault(tick, []).append((e["port"], e["value"]))
        elif kind == "param":
            params_at.setdefault(tick, []).append((e["name"], e["value"]))
        elif kind == "run" and e["state"] == "halting":
            cancel_at[tick] = (e.get("final", "cancelled"), e.get("reason", ""))
        elif kind == "tick":
            tick_times[tick] = e["t"]

    ex_ref: list[Executive] = []

    def current_tick() -> int:
        tick = ex_ref[0].current_tick if ex_ref else None
        return tick if tick is not None else 0

    def make(spec: NodeSpec, bindings: Bindings) -> Skill:
        cls = type(f"Replay{spec.skill.__name__}", (ReplaySkill,),
                   {"NAME": spec.skill.NAME, "INPUTS": spec.skill.INPUTS,
                    "OUTPUTS": spec.skill.OUTPUTS, "HALT_TIMEOUT": spec.skill.HALT_TIMEOUT,
                    "__module__": __name__})
        node = cls(name=spec.name, bindings=bindings)
        node.statuses = statuses[spec.path]
        node.writes = writes[spec.path]
        node.halts = halts[spec.path]
        node.current_tick = current_tick
        return node

    clock = _ReplayClock(start=float(header["t"]), epoch=float(header.get("wall", 0.0))
                         - float(header["t"]))
    ex = Executive(clock=clock, tick_hz=header["tick_hz"], runs_dir=None, skills=skills,
                   make_skill=make, background=False)
    ex_ref.append(ex)
    replayed: list[dict] = []
    handle = ex.submit(mission, priority=header.get("priority", 0), **header.get("params", {}))
    handle.subscribe(lambda ev: replayed.append(ev.to_json()))
    last_tick = end["tick"] if end else max((e["tick"] for e in events), default=0)
    for k in range(last_tick + 10):
        if handle.done:
            break
        if k in tick_times:
            clock.set(tick_times[k])
        for name, value in params_at.get(k, []):
            ex.set_parameter(name, value)
        if k in cancel_at:
            final, reason = cancel_at[k]
            ex.cancel(handle, reason, outcome=final)
        ex.tick()
    if not handle.done:
        handle.cancel("replay ran past the logged end")
        ex.run_until_idle(1000)
    return ReplayReport(original=timeline(events), replayed=timeline(replayed),
                        outcome=end["outcome"] if end else None,
                        replayed_outcome=handle.result.outcome)
