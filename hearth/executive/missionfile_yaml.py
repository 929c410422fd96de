"""YAML with line numbers for mission files: ``load_yaml`` returns plain data whose mappings
and lists (``LineDict``, ``LineList``) know the line each key and item came from
(``line_of``). The loader is a ``SafeLoader`` subclass: no Python objects, no tags beyond plain
data, finite numbers only, and aliases, nesting and size bounded (missionfile_format.py)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml
import yaml.composer
import yaml.constructor
import yaml.resolver

from hearth.executive.errors import MissionError
from hearth.executive.missionfile_format import (
    MAX_FILE_CHARS, MAX_INT, MAX_YAML_DEPTH, MAX_YAML_VALUES,
)
from hearth.util.files import read_limited


# ---------------------------------------------------------------------------------------
# YAML with line numbers
# ---------------------------------------------------------------------------------------
class LineDict(dict):
    """A YAML mapping that remembers its line and each key's line (1-based)."""
    line = 0

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.key_lines: dict[Any, int] = {}


class LineList(list):
    """A YAML sequence that remembers its line and each item's line (1-based)."""
    line = 0

    def __init__(self, *args):
        super().__init__(*args)
        self.item_lines: list[int] = []


if yaml.__with_libyaml__:
    # libyaml scans and parses (ten times faster than PyYAML's Python parser on a 10,000-node
    # mission); composing stays in Python, where nesting can be bounded (the C composer
    # recurses without a limit).
    _BASES: tuple = (yaml.cyaml.CParser, yaml.composer.Composer, yaml.constructor.SafeConstructor,
                     yaml.resolver.Resolver)
else:  # pragma: no cover - PyYAML built without libyaml
    _BASES = (yaml.SafeLoader,)


class _Loader(*_BASES):
    """A safe loader (PyYAML's SafeConstructor: plain data only) that records lines, refuses
    duplicate keys and non-finite numbers, and bounds nesting and what aliases expand to
    (``MAX_YAML_DEPTH``, ``MAX_YAML_VALUES``)."""

    _depth = 0

    def __init__(self, stream):
        if _BASES[0] is yaml.SafeLoader:  # pragma: no cover
            yaml.SafeLoader.__init__(self, stream)
            return
        yaml.cyaml.CParser.__init__(self, stream)
        yaml.composer.Composer.__init__(self)
        yaml.constructor.SafeConstructor.__init__(self)
        yaml.resolver.Resolver.__init__(self)

    check_node = yaml.composer.Composer.check_node
    get_node = yaml.composer.Composer.get_node
    get_single_node = yaml.composer.Composer.get_single_node

    _aliases = 0
    _values = 0

    def compose_node(self, parent, index):
        # PyYAML composes recursively: refuse deep nesting before Python's stack runs out.
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                mark = self.peek_event().start_mark
                raise MissionError(f"YAML nests more than {MAX_YAML_DEPTH} levels deep",
                                   line=mark.line + 1)
            if self.check_event(yaml.AliasEvent):
                self._aliases += 1
            else:
                self._values += 1
                if self._values > MAX_YAML_VALUES:
                    raise MissionError(f"more than {MAX_YAML_VALUES} YAML values",
                                       line=self.peek_event().start_mark.line + 1)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_document(self, node):
        # Without aliases a document holds what composing counted and is as deep as composing
        # allowed; with them, count what they expand to.
        if self._aliases:
            _check_expansion(node)
        return super().construct_document(node)


def _yaml_children(node: yaml.Node) -> list:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def _check_expansion(root: yaml.Node) -> None:
    """Refuse a document whose aliases make it stand for more than MAX_YAML_VALUES values or
    nest deeper than MAX_YAML_DEPTH, or refer to themselves.

    Aliases make the composed graph a DAG whose expansion can be exponential in its size;
    this counts the expansion in one pass over the distinct nodes (iterative, so a long chain
    of aliases cannot exhaust the stack), never building it.
    """
    info: dict[int, tuple[int, int]] = {}       # id(node) -> (expanded size, depth)
    open_: set[int] = set()                     # nodes on the current path (cycle check)
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            kids = [info[id(c)] for c in _yaml_children(node)]
            size = 1 + sum(k[0] for k in kids)
            depth = 1 + max((k[1] for k in kids), default=0)
            open_.discard(key)
            line = node.start_mark.line + 1
            if size > MAX_YAML_VALUES:
                raise MissionError(f"YAML aliases expand this to more than {MAX_YAML_VALUES} "
                                   "values", line=line)
            if depth > MAX_YAML_DEPTH:
                raise MissionError(f"YAML aliases nest this more than {MAX_YAML_DEPTH} levels "
                                   "deep", line=line)
            info[key] = (size, depth)
            continue
        if key in info:
            continue
        if key in open_:
            raise MissionError("a YAML alias refers to the value it is in",
                               line=node.start_mark.line + 1)
        open_.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in _yaml_children(node) if id(c) not in info)


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    out = LineDict()
    out.line = node.start_mark.line + 1
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        line = key_node.start_mark.line + 1
        if not isinstance(key, (str, int, float, bool)) or key is None:
            raise MissionError(f"mapping keys must be plain scalars, not {key!r}", line=line)
        if key in out:
            raise MissionError(f"duplicate key {key!r}", line=line)
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_lines[key] = line
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LineList:
    out = LineList(loader.construct_object(child, deep=True) for child in node.value)
    out.line = node.start_mark.line + 1
    out.item_lines = [child.start_mark.line + 1 for child in node.value]
    return out


def _construct_float(loader: _Loader, node: yaml.ScalarNode) -> float:
    value = loader.construct_yaml_float(node)
    if not math.isfinite(value):
        raise MissionError(f"{node.value!r} is not a finite number", line=node.start_mark.line + 1)
    return value


def _construct_int(loader: _Loader, node: yaml.ScalarNode) -> int:
    try:
        value = loader.construct_yaml_int(node)
    except ValueError:     # more digits than Python converts
        value = None
    if value is None or abs(value) > MAX_INT:
        shown = repr(node.value) if len(node.value) <= 30 else f"of {len(node.value)} digits"
        raise MissionError(f"integer {shown} is too large (at most 2^63 - 1)",
                           line=node.start_mark.line + 1)
    return value


def _refuse(what: str):
    def construct(loader: _Loader, node: yaml.Node):
        raise MissionError(f"{what} values are not allowed in a mission file (quote it to make "
                           "it a string)", line=node.start_mark.line + 1)
    return construct


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)
_Loader.add_constructor("tag:yaml.org,2002:float", _construct_float)
_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)
for _tag, _what in (("timestamp", "date and time"), ("binary", "binary"), ("set", "set"),
                    ("omap", "ordered map"), ("pairs", "pairs")):
    _Loader.add_constructor(f"tag:yaml.org,2002:{_tag}", _refuse(_what))


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML file into LineDict/LineList/scalars; errors carry file and line.

    Only a regular file is read (a device, FIFO or directory is refused before reading), and
    no more of it than MAX_FILE_CHARS allows."""
    path = str(path)
    data = read_limited(path, 4 * MAX_FILE_CHARS + 4, MissionError,   # UTF-8: <= 4 bytes a char
                        f"file is larger than {MAX_FILE_CHARS} characters")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise MissionError("not a UTF-8 text file", file=path, line=0) from None
    return load_yaml_text(text, path)


def load_yaml_text(text: str, path: str = "<string>", loader: Any = None) -> Any:
    if len(text) > MAX_FILE_CHARS:
        raise MissionError(f"file is larger than {MAX_FILE_CHARS} characters", file=path, line=0)
    try:
        return yaml.load(text, Loader=loader or _Loader)  # noqa: S506 - a SafeLoader
    except MissionError as err:
        raise MissionError(err.message, file=path, line=err.line) from None
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        line = mark.line + 1 if mark is not None else 0
        what = err.problem or err.context or "syntax error"
        raise MissionError(f"YAML syntax error: {what}", file=path, line=line) from None
    except yaml.YAMLError as err:
        raise MissionError(f"YAML error: {err}", file=path, line=0) from None
    except RecursionError:  # pragma: no cover - MAX_YAML_DEPTH keeps well below the limit
        raise MissionError("YAML nests too deeply", file=path, line=0) from None


def line_of(data: Any, path: list | tuple) -> int:
    """The line of the value at ``path`` (keys/indices) in loaded YAML, or the nearest parent's."""
    line = getattr(data, "line", 0)
    cur = data
    for step in path:
        if isinstance(cur, LineDict) and step in cur:
            line = cur.key_lines.get(step, line)
            cur = cur[step]
        elif isinstance(cur, LineList) and isinstance(step, int) and step < len(cur):
            line = cur.item_lines[step]
            cur = cur[step]
        else:
            break
    return line
