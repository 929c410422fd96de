"""What a skill input, a condition operand or a for-each source refers to: a literal (``Lit``),
a blackboard key (``BBKey``), a mission parameter (``Param``), and conditions
(``parse_expression`` -> ``Expr``)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from hearth.executive.errors import MissionError
from hearth.executive.missionfile_format import _KEY_RE, _PARAM_RE
from hearth.executive.missionfile_types import plain
from hearth.executive.missionfile_yaml import load_yaml_text


# ---------------------------------------------------------------------------------------
# References: what an input, a condition operand or a for-each source points at
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Lit:
    """A constant from the mission file."""
    value: Any


@dataclass(frozen=True)
class BBKey:
    """A mission blackboard key, scoped: ``pose``, or ``search_at_1/pose`` inside an include."""
    key: str


@dataclass(frozen=True)
class Param:
    """A mission parameter (lives on the blackboard, so runtime parameters change live)."""
    name: str


Ref = Lit | BBKey | Param


@dataclass(frozen=True)
class Expr:
    """A condition: ``left`` alone (truthiness), or ``left op right``; ``negate`` for ``not``.

    A compound condition (``a && b || c``) has ``either``: groups of simple conditions, the
    whole true when every condition of some group holds (``&&`` binds tighter than ``||``,
    as in C and BehaviorTree.CPP's scripts); its ``left`` is None."""
    text: str
    left: Ref | None
    op: str | None = None
    right: Ref | None = None
    negate: bool = False
    either: tuple[tuple["Expr", ...], ...] = ()

    def refs(self) -> list[Ref]:
        if self.either:
            return [r for group in self.either for e in group for r in e.refs()]
        return [r for r in (self.left, self.right) if r is not None]


_OPERAND = r"""\{[A-Za-z_]\w*\}|\$[A-Za-z_]\w*|'[^']*'|"[^"]*"|\[[^\]]*\]|[^\s=!<>'"]+"""
_EXPR_RE = re.compile(r"^\s*(not\s+)?(" + _OPERAND + r")\s*(?:(==|!=|<=|>=|<|>|not\s+in|in)\s*("
                      + _OPERAND + r"))?\s*$")
OPERATORS = ("==", "!=", "<", "<=", ">", ">=", "in", "not in")


def parse_operand(token: str) -> Ref:
    m = _KEY_RE.match(token)
    if m:
        return BBKey(m.group(1))
    m = _PARAM_RE.match(token)
    if m:
        return Param(m.group(1))
    return Lit(plain(load_yaml_text(token, "<condition>")))


# ``&&`` and ``||`` outside quoted literals (they never occur inside a simple condition).
_JOIN_RE = re.compile(r"""'[^']*'|"[^"]*"|(&&|\|\|)""")


def _split_joins(text: str) -> list[str]:
    """``text`` cut at every ``&&`` / ``||`` outside quotes: [part, op, part, op, part...]."""
    out, start = [], 0
    for m in _JOIN_RE.finditer(text):
        if m.group(1):
            out += [text[start:m.start()], m.group(1)]
            start = m.end()
    return out + [text[start:]]


def parse_expression(text: str) -> Expr:
    """Parse ``{key} OP value`` / ``$param OP value`` / ``[not] {key}``, joined by ``&&``
    and ``||``; ValueError if not."""
    pieces = _split_joins(text)
    if len(pieces) == 1:
        return _parse_simple(text)
    groups: list[list[Expr]] = [[]]
    for i, piece in enumerate(pieces):
        if i % 2:
            if piece == "||":
                groups.append([])
            continue
        if not piece.strip():
            raise ValueError(f"condition {text!r}: && and || join two conditions")
        groups[-1].append(_parse_simple(piece.strip(), whole=text))
    return Expr(text=text, left=None, either=tuple(tuple(g) for g in groups))


def _parse_simple(text: str, whole: str | None = None) -> Expr:
    m = _EXPR_RE.match(text)
    if not m:
        raise ValueError(f"cannot read condition {text!r}: use '{{key}} OP value' with OP one of "
                         f"{', '.join(OPERATORS)}, or '[not] {{key}}', joined by && and ||")
    negate, left, op, right = m.groups()
    if op is not None and negate:
        raise ValueError(f"condition {text!r}: 'not' only applies to a single operand")
    try:
        lref = parse_operand(left)
        rref = parse_operand(right) if right is not None else None
    except MissionError as err:
        raise ValueError(f"cannot read a value in condition {text!r}: {err.message}") from None
    if isinstance(lref, Lit) and (rref is None or isinstance(rref, Lit)):
        raise ValueError(f"condition {(whole or text)!r} compares constants only; name a "
                         "{key} or $param")
    op = " ".join(op.split()) if op else None
    return Expr(text=text, left=lref, op=op, right=rref, negate=bool(negate))
