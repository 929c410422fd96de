"""The types of mission parameters, skill inputs and outputs (``TYPES``): checking a value
against a type, which types flow into which, a value's type, and a parameter given as text on
the command line (``parse_param_text``)."""
from __future__ import annotations

import math
import re
import reprlib
import unicodedata
from typing import Any

from hearth.executive.errors import MissionError
from hearth.executive.missionfile_format import MAX_INT, MAX_YAML_DEPTH
from hearth.executive.missionfile_yaml import load_yaml_text, _Loader


# ---------------------------------------------------------------------------------------
# Types
# ---------------------------------------------------------------------------------------
TYPES = ("string", "number", "integer", "boolean", "node_id", "pose", "list", "dict", "any")
_POSE_KEYS = {"x", "y", "z", "roll", "pitch", "yaw"}
_COMPATIBLE = {("integer", "number"), ("node_id", "string"), ("string", "node_id")}


def _alternatives(type_name: str) -> list[str]:
    return [t.strip() for t in type_name.split("|")]


def _is_number(v: Any) -> bool:
    """A finite float, or an int that fits in 64 bits (NaN and infinities are not numbers
    here: a ``timeout`` of NaN never fires, a pose of NaN breaks every solver)."""
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return -MAX_INT - 1 <= v <= MAX_INT
    return isinstance(v, float) and math.isfinite(v)


def check_value(type_name: str, value: Any) -> bool:
    """Whether ``value`` is of mission type ``type_name`` (unions like ``node_id|pose`` allowed).

    A pose is a mapping with numeric x, y (and optional z, roll, pitch, yaw; metres and
    radians), a list of 3 (x, y, yaw) or 6 numbers, or an object with x and y attributes.
    """
    for t in _alternatives(type_name):
        if t == "any":
            return True
        if t in ("string", "node_id") and isinstance(value, str):
            return True
        if t == "number" and _is_number(value):
            return True
        if t == "integer" and isinstance(value, int) and _is_number(value):
            return True
        if t == "boolean" and isinstance(value, bool):
            return True
        if t == "list" and isinstance(value, (list, tuple)):
            return True
        if t == "dict" and isinstance(value, dict):
            return True
        if t == "pose" and _is_pose(value):
            return True
    return False


def _is_pose(value: Any) -> bool:
    if isinstance(value, dict):
        return ({"x", "y"} <= set(value) and set(value) <= _POSE_KEYS
                and all(_is_number(v) for v in value.values()))
    if isinstance(value, (list, tuple)):
        return len(value) in (3, 6) and all(_is_number(v) for v in value)
    return hasattr(value, "x") and hasattr(value, "y") and not isinstance(value, (str, bytes))


def compatible(source: str, target: str) -> bool:
    """Whether a value declared ``source`` may flow into a port declared ``target``."""
    for s in _alternatives(source):
        for t in _alternatives(target):
            if s == t or "any" in (s, t) or (s, t) in _COMPATIBLE:
                return True
    return False


def infer_type(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        return "list"
    if isinstance(value, dict):
        return "dict"
    return "any"


def _control_character(value: Any, depth: int = 0) -> str | None:
    """The first control character (or lone surrogate) in a string of ``value``, if any: a
    value with one is never what a person meant ("kitchen\x01" would resolve to kitchen)."""
    if isinstance(value, str):
        for ch in value:
            if unicodedata.category(ch) in ("Cc", "Cs"):
                return ch
        return None
    if depth < MAX_YAML_DEPTH and isinstance(value, dict):
        value = [*value.keys(), *value.values()]
    if depth < MAX_YAML_DEPTH and isinstance(value, (list, tuple)):
        for v in value:
            bad = _control_character(v, depth + 1)
            if bad is not None:
                return bad
    return None


#: Numbers in a parameter's text are decimal: YAML 1.1 also reads 0x10 as 16, 010 as 8,
#: 1_000 as 1000 and 1:30 as 90, which no one typing max_places=0x10 means.
_DECIMAL_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)")
_DECIMAL_FLOAT = re.compile(r"[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+|[0-9]+)(?:[eE][-+]?[0-9]+)?"
                            r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)")


class _ParamLoader(_Loader):
    """The mission loader, with numbers read in decimal only (``_DECIMAL_INT``)."""

    yaml_implicit_resolvers = {
        first: [(tag, rx) for tag, rx in resolvers
                if tag not in ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")]
        for first, resolvers in _Loader.yaml_implicit_resolvers.items()}


for _tag, _rx in (("tag:yaml.org,2002:int", _DECIMAL_INT), ("tag:yaml.org,2002:float", _DECIMAL_FLOAT)):
    _ParamLoader.add_implicit_resolver(_tag, re.compile(f"^(?:{_rx.pattern})$"),
                                       list("-+0123456789."))


def parse_param_text(name: str, type_name: str, text: str) -> Any:
    """Turn a command-line ``--param name=text`` into a value of ``type_name``.

    Strings and node ids are taken verbatim; other types are read as YAML scalars/flow
    collections (``[1, 2, 0.5]``, ``{x: 1, y: 2}``, ``true``), numbers in decimal only. A
    control character anywhere is refused. Raises MissionError(param=).
    """
    bad = _control_character(text)
    if bad is not None:
        raise MissionError(f"{_short(text)} holds the control character U+{ord(bad):04X}",
                           param=name)
    if any(t in ("string", "node_id") for t in _alternatives(type_name)):
        return text
    try:
        value = plain(load_yaml_text(text, "<parameter>", loader=_ParamLoader))
    except MissionError as err:
        raise MissionError(f"cannot read {text[:80]!r} as {type_name}: {err.message}",
                           param=name) from None
    if _alternatives(type_name) == ["number"] and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not check_value(type_name, value):
        raise MissionError(f"expected {type_name}, got {_short(text)}", param=name)
    return value


def plain(value: Any) -> Any:
    """LineDict/LineList -> dict/list, recursively (for values handed to skills and logs)."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)) and not isinstance(value, str):
        return [plain(v) for v in value]
    return value


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60
_REPR.maxlist = _REPR.maxdict = 4
_REPR.maxlevel = 2


def _short(value: Any) -> str:
    """``repr`` cut to a readable length (a node pasted 2,500 times is one line, not 300 kB)."""
    return _REPR.repr(value)
