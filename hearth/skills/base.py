"""The skill contract: a py_trees behaviour that declares its ports.

A skill class declares ``NAME`` (the name mission files use), ``INPUTS`` and ``OUTPUTS``
(typed ports) and optionally ``AUTONOMY`` (how much it acts on the home; see
docs/missions.md). The executive checks a mission against these declarations before anything
runs, binds each input either to a literal from the mission file or to a blackboard key, and
calls ``setup(world=..., robot=..., clock=..., ...)`` once, the py_trees way.

Inside a skill: ``self.input("object")`` reads an input (literal, or the bound blackboard
key), ``self.set_output("pose", value)`` writes an output to its bound key. ``self.world``,
``self.robot`` and ``self.clock`` are the belief map, the robot adapter and the clock given
to ``setup``. Keep skills short: read inputs, call one function of hearth/perception/, hearth/worldmodel/
or robot/, write outputs, set ``feedback_message``.
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field
from typing import Any, ClassVar

import py_trees

#: Port types a mission file can name. ``node_id`` is a map node id (a string),
#: ``pose`` a dict/sequence x, y, z, roll, pitch, yaw (or a worldmodel Pose), ``any`` anything.
PORT_TYPES = ("string", "number", "integer", "boolean", "node_id", "pose", "list", "dict", "any")


@dataclass(frozen=True)
class Port:
    name: str
    type: str = "any"
    required: bool = True
    default: Any = None
    description: str = ""

    def __post_init__(self):
        # A union such as "node_id|pose" accepts any of its alternatives.
        if any(t.strip() not in PORT_TYPES for t in self.type.split("|")):
            raise ValueError(f"port {self.name}: unknown type {self.type!r}")


@dataclass(frozen=True)
class Literal:
    """An input bound to a constant from the mission file."""
    value: Any


@dataclass(frozen=True)
class Key:
    """An input or output bound to a blackboard key (absolute, e.g. ``/object_id``)."""
    key: str


@dataclass
class Bindings:
    inputs: dict[str, Literal | Key] = field(default_factory=dict)
    outputs: dict[str, Key] = field(default_factory=dict)


class Skill(py_trees.behaviour.Behaviour):
    """Base class of every skill. Subclasses set NAME, INPUTS, OUTPUTS and implement update()."""

    NAME: ClassVar[str] = ""
    INPUTS: ClassVar[tuple[Port, ...]] = ()
    OUTPUTS: ClassVar[tuple[Port, ...]] = ()
    #: 0: observes only; 1: moves the base; 2: acts on the home (doors, knobs); 3: handles
    #: objects near the user. The executive asks an operator when above the granted level.
    AUTONOMY: ClassVar[int] = 0
    DESCRIPTION: ClassVar[str] = ""
    #: Seconds (clock time) the executive waits for ``is_halting()`` to turn False after
    #: halting this skill, before it gives up on it and reports the cancel anyway.
    HALT_TIMEOUT: ClassVar[float] = 5.0
    #: Set by the executive: called as ``output_hook(skill, port, key, value)`` after each
    #: ``set_output``, so outputs reach the event stream and the execution log.
    output_hook = None

    def __init__(self, name: str | None = None, bindings: Bindings | None = None):
        super().__init__(name=name or self.NAME)
        self.bindings = bindings or Bindings()
        self.world = None
        self.robot = None
        self.clock = None
        self.context: dict[str, Any] = {}
        self._bb = self.attach_blackboard_client(name=f"{self.name}")
        for port in self.INPUTS:
            b = self.bindings.inputs.get(port.name)
            if isinstance(b, Key):
                self._bb.register_key(key=b.key, access=py_trees.common.Access.READ)
        for port in self.OUTPUTS:
            b = self.bindings.outputs.get(port.name)
            if isinstance(b, Key):
                self._bb.register_key(key=b.key, access=py_trees.common.Access.WRITE)

    # -- py_trees lifecycle -------------------------------------------------------------
    def setup(self, **kwargs: Any) -> None:
        self.world = kwargs.get("world")
        self.robot = kwargs.get("robot")
        self.clock = kwargs.get("clock")
        self.context = kwargs

    # -- ports --------------------------------------------------------------------------
    @classmethod
    def port(cls, name: str, outputs: bool = False) -> Port | None:
        for p in cls.OUTPUTS if outputs else cls.INPUTS:
            if p.name == name:
                return p
        return None

    def input(self, name: str) -> Any:
        """The value of input ``name``: its literal, its blackboard key's value, or its default."""
        port = self.port(name)
        if port is None:
            raise KeyError(f"{self.NAME} has no input {name!r}")
        b = self.bindings.inputs.get(name)
        if b is None:
            return port.default
        if isinstance(b, Literal):
            return b.value
        try:
            return self._bb.get(b.key)
        except KeyError:
            return port.default

    def has_input(self, name: str) -> bool:
        return name in self.bindings.inputs

    def set_output(self, name: str, value: Any) -> None:
        if self.port(name, outputs=True) is None:
            raise KeyError(f"{self.NAME} has no output {name!r}")
        b = self.bindings.outputs.get(name)
        if b is not None:
            self._bb.set(b.key, value)
            if self.output_hook is not None:
                self.output_hook(self, name, b.key, value)

    def is_halting(self) -> bool:
        """After ``terminate(INVALID)``: True while a robot action this skill started is still
        stopping (e.g. the base is braking). The executive keeps polling, once per tick, and
        reports a cancel only when every halted skill says False or ``HALT_TIMEOUT`` passes.
        The default: stopping is immediate."""
        return False


def registry() -> dict[str, type[Skill]]:
    """Every skill class in the ``skills`` package, by NAME (imports its modules)."""
    import hearth.skills as pkg

    for info in pkgutil.iter_modules(pkg.__path__):
        if info.name not in ("base", "errors"):
            importlib.import_module(f"hearth.skills.{info.name}")
    found: dict[str, type[Skill]] = {}
    stack = list(Skill.__subclasses__())
    while stack:
        cls = stack.pop()
        stack.extend(cls.__subclasses__())
        if cls.NAME and cls.__module__.startswith("hearth.skills."):
            found[cls.NAME] = cls
    return found
