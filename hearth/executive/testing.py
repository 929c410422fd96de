"""Testing missions without perception or a robot: scripted stand-ins for skills.

A :class:`Script` says what a stand-in does: the outcome of each activation (the last one
repeats), how many clock seconds it runs first, what outputs it writes, how long it keeps
reporting ``is_halting()`` after being halted. :func:`substitution_factory` turns scripts
into a ``make_skill`` for the Executive: a script matches a skill **name** (``NavigateTo``,
wildcards allowed) or a **tree path** (a pattern starting with ``/``, e.g. ``/main/*/say``).
The stand-in has the real skill's NAME and ports, so the mission is checked exactly as
with the real skill.

A substitution file (``hearth test-mission MISSION --substitute FILE``) is YAML::

    params: {presence: away}            # mission parameters
    default: success                    # unmatched skills: success | failure | real
    substitute:
      - match: NavigateTo
        duration: 2.0                   # clock seconds
        outcome: success                # or outcomes: [failure, success]
        outputs: {reached: kitchen}
        halt_duration: 0.5
    set_parameters:                     # runtime parameter changes, clock seconds from start
      - {at: 1.0, presence: home}
    cancel_at: 30.0                     # optional
    expect: succeeded                   # optional: succeeded, failed, cancelled
    tick_hz: 10
    max_seconds: 600

:func:`run_case` runs it on a simulated clock and reports the result and the nodes that were
never ticked. This module also holds the test-only skills used by tests/executive.
"""
from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from py_trees import common

from hearth.executive.errors import MissionError
from hearth.executive.missionfile import NodeSpec
from hearth.executive.missionfile_types import plain
from hearth.executive.missionfile_yaml import LineDict, LineList, load_yaml
from hearth.executive.tree import SkillFactory, default_factory
from hearth.skills.base import Bindings, Port, Skill

Status = common.Status
_OUTCOMES = {"success": Status.SUCCESS, "failure": Status.FAILURE}


@dataclass
class Script:
    """What a stand-in does. Times are clock seconds."""
    match: str = "*"
    outcomes: list[str] = field(default_factory=lambda: ["success"])
    duration: float = 0.0
    outputs: dict[str, Any] = field(default_factory=dict)
    halt_duration: float = 0.0
    feedback: str = ""

    def __post_init__(self):
        for o in self.outcomes:
            if o not in _OUTCOMES:
                raise MissionError(f"script {self.match}: outcome {o!r} is not success or failure")
        if not self.outcomes:
            raise MissionError(f"script {self.match}: needs at least one outcome")

    def matches(self, spec: NodeSpec) -> bool:
        if "/" in self.match:
            return fnmatch.fnmatchcase(spec.path, self.match)
        return fnmatch.fnmatchcase(spec.skill_name, self.match)


class ScriptedSkill(Skill):
    """A skill that plays a Script. Subclassed per real skill to borrow its NAME and ports.

    Records ``activations`` (starts), ``halts`` (stopped while running) and ``seen_inputs``
    (input values at each start) for assertions.
    """

    script: ClassVar[Script] = Script()
    #: every stand-in's start and terminate, in order: (event, path) - for halting-order tests
    journal: ClassVar[list | None] = None

    def __init__(self, name: str | None = None, bindings: Bindings | None = None):
        super().__init__(name=name, bindings=bindings)
        self.activations = 0
        self.halts = 0
        self.seen_inputs: list[dict[str, Any]] = []
        self._started = 0.0
        self._halted_at: float | None = None

    def _now(self) -> float:
        return self.clock.now() if self.clock is not None else 0.0

    def initialise(self) -> None:
        self.activations += 1
        self._started = self._now()
        self._halted_at = None
        self.seen_inputs.append({p.name: self.input(p.name) for p in self.INPUTS})
        if self.journal is not None:
            self.journal.append(("start", getattr(self, "hearth_path", self.name)))

    def update(self) -> Status:
        s = self.script
        if self._now() - self._started < s.duration - 1e-9:
            self.feedback_message = s.feedback or f"{self.NAME} working"
            return Status.RUNNING
        for port, value in s.outputs.items():
            if self.port(port, outputs=True) is not None:
                self.set_output(port, value)
        outcome = s.outcomes[min(self.activations, len(s.outcomes)) - 1]
        self.feedback_message = s.feedback or f"{self.NAME} scripted {outcome}"
        return _OUTCOMES[outcome]

    def terminate(self, new_status: Status) -> None:
        if self.journal is not None and self.status != Status.INVALID:
            self.journal.append(("terminate", getattr(self, "hearth_path", self.name)))
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.halts += 1
            self._halted_at = self._now()

    def is_halting(self) -> bool:
        return (self._halted_at is not None
                and self._now() - self._halted_at < self.script.halt_duration - 1e-9)


def scripted_class(real: type[Skill], script: Script) -> type[ScriptedSkill]:
    """A ScriptedSkill with ``real``'s NAME, INPUTS and OUTPUTS playing ``script``."""
    return type(f"Scripted{real.__name__}", (ScriptedSkill,),
                {"NAME": real.NAME, "INPUTS": real.INPUTS, "OUTPUTS": real.OUTPUTS,
                 "HALT_TIMEOUT": max(real.HALT_TIMEOUT, script.halt_duration + 1.0),
                 "script": script, "__module__": __name__})


class Substitution:
    """A ``make_skill`` for the Executive: the first matching script wins; unmatched skills
    get ``default`` (a Script) or, when it is None, the real skill. ``made`` maps each tree
    path to the behaviour built for it (the last run's), ``matched`` the paths scripted."""

    def __init__(self, scripts: list[Script], default: Script | None = None,
                 fallback: SkillFactory = default_factory):
        self.scripts = list(scripts)
        self.default = default
        self.fallback = fallback
        self.made: dict[str, Skill] = {}
        self.matched: set[str] = set()

    def __call__(self, spec: NodeSpec, bindings: Bindings) -> Skill:
        script = next((s for s in self.scripts if s.matches(spec)), None)
        if script is not None:
            self.matched.add(spec.path)
        elif not issubclass(spec.skill, ScriptedSkill):
            script = self.default
        if script is None:
            node = self.fallback(spec, bindings)
        else:
            node = scripted_class(spec.skill, script)(name=spec.name, bindings=bindings)
        self.made[spec.path] = node
        return node


def substitution_factory(scripts: list[Script], default: Script | None = None) -> Substitution:
    return Substitution(scripts, default)


# ---------------------------------------------------------------------------------------
# Substitution files and test-mission
# ---------------------------------------------------------------------------------------
@dataclass
class Case:
    """A scripted test case for one mission (see the module docstring)."""
    scripts: list[Script]
    default: Script | None = field(default_factory=Script)
    params: dict[str, Any] = field(default_factory=dict)
    set_parameters: list[tuple[float, dict[str, Any]]] = field(default_factory=list)
    cancel_at: float | None = None
    expect: str | None = None
    tick_hz: float = 10.0
    max_seconds: float = 600.0


_CASE_KEYS = {"params", "default", "substitute", "set_parameters", "cancel_at", "expect",
              "tick_hz", "max_seconds"}
_SCRIPT_KEYS = {"match", "outcome", "outcomes", "duration", "outputs", "halt_duration",
                "feedback"}


def load_case(path: str | Path) -> Case:
    """Read a substitution file; MissionError with file:line for anything wrong."""
    path = str(path)
    data = load_yaml(path)
    if not isinstance(data, LineDict):
        raise MissionError("a substitution file is a YAML mapping", file=path, line=1)

    def bad(msg: str, line: int) -> MissionError:
        return MissionError(msg, file=path, line=line)

    for k in data:
        if k not in _CASE_KEYS:
            raise bad(f"unknown key {k!r} (known: {', '.join(sorted(_CASE_KEYS))})",
                      data.key_lines[k])
    scripts = []
    items = data.get("substitute") or LineList()
    if not isinstance(items, list):
        raise bad("substitute: expected a list", data.key_lines.get("substitute", 1))
    for i, item in enumerate(items):
        line = items.item_lines[i] if isinstance(items, LineList) else 1
        if not isinstance(item, dict) or "match" not in item:
            raise bad("each substitute entry is a mapping with match:", line)
        for k in item:
            if k not in _SCRIPT_KEYS:
                raise bad(f"unknown key {k!r} (known: {', '.join(sorted(_SCRIPT_KEYS))})", line)
        outcomes = item.get("outcomes") or [item.get("outcome", "success")]
        try:
            scripts.append(Script(match=str(item["match"]), outcomes=list(outcomes),
                                  duration=float(item.get("duration", 0.0)),
                                  outputs=plain(item.get("outputs") or {}),
                                  halt_duration=float(item.get("halt_duration", 0.0)),
                                  feedback=str(item.get("feedback", ""))))
        except (MissionError, TypeError, ValueError) as err:
            raise bad(getattr(err, "message", str(err)), line) from None
    default = data.get("default", "success")
    if default not in ("success", "failure", "real"):
        raise bad("default: expected success, failure or real", data.key_lines.get("default", 1))
    changes = []
    for i, item in enumerate(data.get("set_parameters") or []):
        if not isinstance(item, dict) or "at" not in item:
            raise bad("set_parameters entries look like {at: SECONDS, name: value}",
                      data.key_lines.get("set_parameters", 1))
        changes.append((float(item["at"]), {k: plain(v) for k, v in item.items() if k != "at"}))
    expect = data.get("expect")
    if expect is not None and expect not in ("succeeded", "failed", "cancelled"):
        raise bad("expect: succeeded, failed or cancelled", data.key_lines.get("expect", 1))
    return Case(scripts=scripts,
                default=None if default == "real" else Script(outcomes=[default]),
                params=plain(data.get("params") or {}), set_parameters=sorted(changes, key=lambda c: c[0]),
                cancel_at=data.get("cancel_at"), expect=expect,
                tick_hz=float(data.get("tick_hz", 10.0)),
                max_seconds=float(data.get("max_seconds", 600.0)))


@dataclass
class CaseReport:
    outcome: str
    reason: str
    ticks: int
    duration: float
    never_ticked: list[str]
    nodes: list[str]
    unscripted: list[str]
    expected: str | None
    log_path: str | None = None

    @property
    def passed(self) -> bool:
        return self.expected is None or self.expected == self.outcome


def run_case(mission_path: str | Path, case: Case, skills: dict[str, type] | None = None,
             world: Any = None, robot: Any = None, runs_dir: str | None = None) -> CaseReport:
    """Run ``case`` on a simulated clock and report outcome and coverage."""
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock

    clock = SimClock()
    sub = Substitution(case.scripts, case.default)
    ex = Executive(world=world, robot=robot, clock=clock, tick_hz=case.tick_hz,
                   runs_dir=runs_dir, skills=skills, make_skill=sub, background=False)
    ticked: set[str] = set()
    ex.subscribe(lambda ev: ticked.add(ev.path) if ev.kind == "status" and ev.path
                 and ev.data.get("status") != "INVALID" else None)
    handle = ex.submit(mission_path, **case.params)
    start = clock.now()
    changes = list(case.set_parameters)
    max_ticks = int(case.max_seconds * case.tick_hz) + 10
    for _ in range(max_ticks):
        elapsed = clock.now() - start
        while changes and changes[0][0] <= elapsed + 1e-9:
            for name, value in changes.pop(0)[1].items():
                ex.set_parameter(name, value)
        if case.cancel_at is not None and elapsed >= case.cancel_at - 1e-9:
            handle.cancel("cancel_at in the test case")
        if not ex.tick():
            break
    if not handle.done:
        handle.cancel("max_seconds reached")
        ex.run_until_idle(10_000)
    all_paths = [n.path for n in handle.mission.nodes()]
    result = handle.result
    return CaseReport(outcome=result.outcome, reason=result.reason, ticks=result.ticks,
                      duration=result.duration,
                      never_ticked=[p for p in all_paths if p not in ticked], nodes=all_paths,
                      unscripted=sorted(n.path for n in handle.mission.nodes()
                                        if n.kind == "skill" and n.path not in sub.matched),
                      expected=case.expect, log_path=result.log_path)


# ---------------------------------------------------------------------------------------
# Test-only skills (never in the hearth/skills/ package, so never in the real registry)
# ---------------------------------------------------------------------------------------
class Act(ScriptedSkill):
    """Does nothing for real; succeeds at once unless substituted."""
    NAME = "Act"
    INPUTS = (Port("label", "string", required=False, default=""),)
    OUTPUTS = (Port("result", "any"),)


class Navigate(ScriptedSkill):
    NAME = "Navigate"
    INPUTS = (Port("target", "node_id|pose"),)
    OUTPUTS = (Port("reached", "node_id|pose"),)

    def update(self) -> Status:
        status = super().update()
        if status == Status.SUCCESS:
            self.set_output("reached", self.input("target"))
        return status


class Detect(ScriptedSkill):
    NAME = "Detect"
    INPUTS = (Port("object", "node_id"),)
    OUTPUTS = (Port("pose", "pose"), Port("found", "boolean"), Port("count", "integer"))


class Speak(ScriptedSkill):
    NAME = "Speak"
    INPUTS = (Port("text", "string"),)
    OUTPUTS = ()


class Measure(ScriptedSkill):
    NAME = "Measure"
    INPUTS = ()
    OUTPUTS = (Port("value", "number"),)


def test_skills() -> dict[str, type[Skill]]:
    """The test-only registry: Act, Navigate, Detect, Speak, Measure."""
    return {c.NAME: c for c in (Act, Navigate, Detect, Speak, Measure)}


test_skills.__test__ = False  # not a pytest test
