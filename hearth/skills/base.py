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
or robot/, write outputs, say what happened with ``self.report(sentence, **values)``.

Feedback is a sentence for a person and the values it speaks of, as data:
``self.report("fix on fridge not trusted: too weak; pose left unchanged", fitness=0.31)``
sets ``feedback_message`` to a :class:`Feedback` (a ``str``: the sentence, readable on its
own) whose ``values`` the executive carries as JSON values into the events, the execution
log, the command API, Foxglove and the monitor page. Never write a value's Python repr into
the sentence; :func:`words` writes a value the way the monitor page does. A plain string in
``feedback_message`` still works (a feedback event without values).
"""
from __future__ import annotations

import importlib
import math
import pkgutil
from collections.abc import Mapping
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


class Feedback(str):
    """A skill's feedback: the string is the sentence for a person, ``values`` the values it
    speaks of (names -> JSON values: numbers, strings, booleans, None, lists, dicts; a Pose
    becomes its dict, numpy values their Python ones, NaN None).

    A ``str``, so everything that reads ``feedback_message`` as text (py_trees' displays, a
    mission's failure reason, third-party code comparing it) sees the sentence alone; equal
    to the plain string of its sentence whatever its values."""

    values: dict[str, Any]

    def __new__(cls, text: str, values: Mapping[str, Any] | None = None, /, **more: Any):
        self = super().__new__(cls, text)
        self.values = {str(k): json_value(v) for k, v in {**(values or {}), **more}.items()}
        return self

    @property
    def text(self) -> str:
        return str.__str__(self)

    def __repr__(self) -> str:
        return f"Feedback({self.text!r}, {self.values!r})"

    def __reduce__(self):
        return (Feedback, (self.text, self.values))


def values_of(message: Any) -> dict[str, Any]:
    """The values a feedback message carries (none for a plain string); for an exception,
    those of the Feedback it was raised with (``raise PerceptionError(Feedback(...))``)."""
    if isinstance(message, BaseException):
        message = message.args[0] if message.args else None
        message = getattr(message, "message", message)      # a HearthError keeps it there
    return dict(getattr(message, "values", None) or {})


def error_text(err: BaseException) -> str:
    """What an error says, for a sentence: ``str(err)``, except that a ``KeyError`` raised
    with a message says the message (its ``str`` is the message's repr, in quotes)."""
    if (isinstance(err, KeyError) and type(err).__str__ is KeyError.__str__
            and len(err.args) == 1 and isinstance(err.args[0], str)):
        return str.__str__(err.args[0])
    return str(err)


def json_value(value: Any) -> Any:
    """``value`` as plain JSON data (see :class:`Feedback`); an object JSON has no word for
    is its ``str``."""
    if value is None or type(value) in (bool, int, str):
        return value
    if isinstance(value, bool):
        return bool(value)
    if isinstance(value, int):                # an IntEnum, say
        return int(value)
    if isinstance(value, str):                # a str enum, a Feedback
        return str.__str__(value)
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): json_value(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [json_value(v) for v in value]
    if hasattr(value, "as_dict"):             # a worldmodel Pose
        return json_value(value.as_dict())
    if hasattr(value, "tolist"):              # numpy arrays and scalars
        return json_value(value.tolist())
    return str(value)


def words(value: Any, depth: int = 0) -> str:
    """A value in a few words for a sentence, the way the monitor page writes values:
    numbers to 3 significant places, ``yes``/``no``, a pose ``(1.2, 3) m, yaw 90°``, a
    search place ``sofa from sofa_front (p 0.6)``, a dict ``key value, ...``,
    a list its first four items and how many there are. Never Python's repr."""
    v = json_value(value)
    if v is None or v == "":
        return "none"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return _num(v)
    if isinstance(v, str):
        return v
    if isinstance(v, list):
        if not v:
            return "none"
        many = any(isinstance(x, (dict, list)) for x in v)
        shown = ("; " if many else ", ").join(words(x, depth + 1) for x in v[:4])
        return f"{shown} … ({len(v)} in all)" if len(v) > 4 else shown
    if isinstance(v.get("place"), str):       # a search place or a surface of one
        text = v["place"]
        if v.get("parking"):
            text += f" from {v['parking']}"
        elif v.get("surface"):
            text = str(v["surface"]).replace("/", " ")
        if isinstance(v.get("probability"), (int, float)):
            text += f" (p {_num(v['probability'])})"
        return text
    if isinstance(v.get("x"), (int, float)) and isinstance(v.get("y"), (int, float)):
        xyz = [v["x"], v["y"]] + ([v["z"]] if v.get("z") else [])
        yaw = v.get("yaw")
        return ("(" + ", ".join(_num(c) for c in xyz) + ") m"
                + (f", yaw {round(math.degrees(yaw))}°" if isinstance(yaw, (int, float)) else ""))
    if depth > 1:
        return "…"
    if not v:
        return "none"
    keys = list(v)
    return ", ".join(f"{k} {words(v[k], depth + 1)}" for k in keys[:6]) + (
        ", …" if len(keys) > 6 else "")


def _num(x: float) -> str:
    if isinstance(x, int):
        return str(x)
    a = abs(x)
    text = f"{x:.{1 if a >= 100 else 2 if a >= 1 else 3}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


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

    # -- feedback -------------------------------------------------------------------------
    def report(self, text: str, /, **values: Any) -> Feedback:
        """Say what happened: ``feedback_message`` becomes ``text`` (a sentence for a person,
        readable on its own) carrying ``values`` as data (see :class:`Feedback`)."""
        self.feedback_message = Feedback(text, values)
        return self.feedback_message

    def report_error(self, err: BaseException) -> Feedback:
        """``report`` of a failure: ``"<NAME>: <err>"`` with the values the error was raised
        with (``raise PerceptionError(Feedback("...", fitness=0.3))``)."""
        return self.report(f"{self.NAME}: {error_text(err)}", **values_of(err))

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
