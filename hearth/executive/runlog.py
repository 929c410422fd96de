"""Execution logs: one writer for a run's JSON-lines log (``runs/<run id>.jsonl``).

A log is a ``start`` header, one line per :class:`~hearth.executive.events.Event` and an ``end``
line (docs/missions.md, "Events and execution logs"; read back by hearth/executive/replay.py).
Every line is ``json.dumps(obj, default=json_default)`` (a Pose as its dict, numpy values as
numbers, anything else JSON has no word for as its repr); status lines, most of a log, are formatted
by hand on the hot path (a tick of a 200-node tree writes about 30 of them) and must be the
same bytes as the generic path, ``json.dumps(Event(...).to_json())``:
tests/executive/test_runlog.py writes both through this class and compares the files.

A run that never started (cancelled while queued) gets a log too: its header says
``"started": false`` and the end line says how it ended, so every submitted run can be
accounted for.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import IO, Any

from py_trees import common

from hearth.executive.events import Event, EventKind, json_default
from hearth.executive.missionfile import Mission, plain

log = logging.getLogger("hearth.executive")

#: Version of the log format (the header's ``format``).
LOG_FORMAT = 1
START, END = "start", "end"

Status = common.Status
# (status, previous) values -> the end of a status line; keyed by the enums' string values
# (hashing py_trees' Status members goes through Python-level Enum.__hash__).
_TAILS = {(a.value, b.value, halted): f', "status": "{a.value}", "previous": "{b.value}"'
          + (', "halted": true}\n' if halted else "}\n")
          for a in Status for b in Status for halted in (False, True)}


def dumps(obj: Any) -> str:
    return json.dumps(obj, default=json_default)


def header_fields(run_id: str, mission: Mission, params: dict[str, Any], priority: int,
                  t0: float, wall: float, tick_hz: float, simulated: bool,
                  ns: str | None) -> dict[str, Any]:
    """What a ``start`` line says, in its order: the mission and the source text of every
    file it was loaded from, parameters, priority, tick rate, clock kind, start time."""
    sources = {}
    for f in mission.files:
        try:
            sources[f] = Path(f).read_text(encoding="utf-8")
        except OSError:
            pass
    return {"format": LOG_FORMAT, "run": run_id, "tick": 0, "t": t0, "wall": wall,
            "mission": mission.name, "file": mission.file, "sources": sources,
            "params": plain(params), "priority": priority, "tick_hz": tick_hz,
            "clock": "sim" if simulated else "wall", "ns": ns}


class RunLog:
    """The log file of one run. Not thread-safe: the executive writes it under its lock.

    ``event(ev)`` writes any event; ``begin_tick``/``status``/``flush`` are the hot path for
    status changes (buffered within a tick, written before the next other event, so lines
    keep their order)."""

    def __init__(self, path: str | Path, run_id: str):
        self.path = Path(path)
        self._file: IO[str] | None = open(self.path, "w", encoding="utf-8")  # noqa: SIM115
        self._run_json = json.dumps(run_id)
        self._head = ""
        self._pending: list[str] = []

    @classmethod
    def create(cls, runs_dir: Path, run_id: str, header: dict[str, Any]) -> "RunLog":
        """``runs_dir/<run id>.jsonl`` with its ``start`` line written."""
        runs_dir.mkdir(parents=True, exist_ok=True)
        runlog = cls(runs_dir / f"{run_id}.jsonl", run_id)
        runlog.header(header)
        return runlog

    @classmethod
    def write_unstarted(cls, runs_dir: Path, run_id: str, header: dict[str, Any], ev: Event,
                        outcome: str, reason: str) -> Path | None:
        """The whole log of a run that ended before it started (``"started": false``);
        its path, or None if it could not be written."""
        try:
            runlog = cls.create(runs_dir, run_id, {**header, "started": False})
            runlog.event(ev)
            runlog.finish(run_id, 0, ev.time, outcome, reason, {})
            return runlog.path
        except OSError:
            log.exception("writing the log of %s failed", run_id)
            return None

    @property
    def closed(self) -> bool:
        return self._file is None

    def header(self, fields: dict[str, Any]) -> None:
        """The ``start`` line (``fields`` in the order they are written, after ``e``)."""
        self._write(dumps({"e": START, **fields}) + "\n")

    def event(self, ev: Event) -> None:
        self.flush()
        self._write(dumps(ev.to_json()) + "\n")

    def end(self, run_id: str, tick: int, time: float, outcome: str, reason: str,
            outputs: Any, extra: dict[str, Any] | None = None) -> None:
        self.flush()
        self._write(dumps({"e": END, "run": run_id, "tick": tick, "t": time, "outcome": outcome,
                           "reason": reason, "outputs": outputs, **(extra or {})}) + "\n")

    def finish(self, run_id: str, tick: int, time: float, outcome: str, reason: str,
               outputs: Any, extra: dict[str, Any] | None = None) -> None:
        """The ``end`` line, then close; never raises (a full disk must not keep a run
        from ending: the error is logged)."""
        try:
            self.end(run_id, tick, time, outcome, reason, outputs, extra)
        except Exception:  # noqa: BLE001
            log.exception("writing the end of %s failed", self.path)
        try:
            self.close()
        except Exception:  # noqa: BLE001
            log.exception("closing %s failed", self.path)

    # -- the hot path ------------------------------------------------------------------------
    def begin_tick(self, tick: int, now: float) -> None:
        """Status lines from here on are of tick ``tick`` at clock time ``now``."""
        self.flush()
        self._head = (f'{{"e": "status", "run": {self._run_json}, "tick": {tick}, '
                      f'"t": {_time_json(now)}, "path": ')

    def status(self, path_json: str, status: Status, previous: Status,
               halted: bool = False) -> None:
        """A status line of this tick (``path_json``: the node path, JSON-encoded)."""
        self._pending.append(self._head + path_json
                             + _TAILS[status._value_, previous._value_, halted])

    def flush(self) -> None:
        if self._pending:
            self._write("".join(self._pending))
            self._pending.clear()

    def close(self) -> None:
        if self._file is not None:
            try:
                self.flush()
            finally:
                self._file.close()
                self._file = None

    def _write(self, text: str) -> None:
        if self._file is not None:
            self._file.write(text)


def _time_json(t: float) -> str:
    # json.dumps(float) is float.__repr__ (clock times are finite).
    return repr(round(t, 9))


def status_event(run_id: str, tick: int, now: float, path: str, status: Status,
                 previous: Status, halted: bool = False) -> Event:
    """The Event a status line stands for."""
    data: dict[str, Any] = {"status": status.value, "previous": previous.value}
    if halted:
        data["halted"] = True
    return Event(EventKind.STATUS, run_id, tick, now, path, data)
