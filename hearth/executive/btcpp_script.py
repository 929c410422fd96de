"""The subset of BT.CPP's scripting language Hearth reads (Script, ScriptCondition, the pre and
post-condition attributes): assignments (``script_assignments``) and conditions
(``script_condition``, into a Hearth condition)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any


# ---------------------------------------------------------------------------------------
# BT.CPP scripts (Script, ScriptCondition, pre/post conditions): the subset Hearth reads
# ---------------------------------------------------------------------------------------
# BT.CPP's scripting language (docs "Introduction to Scripting") is read as far as Hearth's
# own nodes can carry it: assignments of a literal or of another entry (SetValue), and
# conditions made of comparisons, ! and the && / || joins (Check). Arithmetic, parentheses,
# the ternary operator, enums and root-blackboard entries (@key) are refused with the line.
_SCRIPT_TOKEN = re.compile(r"""\s*(?:(?P<str>'[^']*'|"[^"]*")"""
                           r"""|(?P<num>-?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+))"""
                           r"""|(?P<id>@?[A-Za-z_][A-Za-z0-9_]*)"""
                           r"""|(?P<op>:=|==|!=|<=|>=|&&|\|\||[-+*/]=|[=<>!;()+\-*/?:~^&|]))""")
_COMPARE = ("==", "!=", "<", "<=", ">", ">=")


@dataclass(frozen=True)
class _Tok:
    kind: str       # str, num, id, op
    text: str


def _script_tokens(code: str) -> list[_Tok]:
    out, pos = [], 0
    code = code.rstrip()
    while pos < len(code):
        m = _SCRIPT_TOKEN.match(code, pos)
        if not m or m.end() == pos:
            raise ValueError(f"cannot read {code[pos:].strip()[:20]!r}")
        kind = m.lastgroup
        out.append(_Tok(kind, m.group(kind)))
        pos = m.end()
    return out


def _script_literal(tok: _Tok) -> Any:
    if tok.kind == "str":
        return tok.text[1:-1]
    if tok.kind == "num":
        value = float(tok.text)
        return int(value) if value.is_integer() and not any(c in tok.text for c in ".eE") \
            else value
    return tok.text == "true"


def _is_literal(tok: _Tok) -> bool:
    return tok.kind in ("str", "num") or (tok.kind == "id" and tok.text in ("true", "false"))


def _no_root(tok: _Tok) -> None:
    if tok.kind == "id" and tok.text.startswith("@"):
        raise ValueError(f"{tok.text}: root-blackboard entries have no Hearth equivalent; "
                         "pass the value through the subtree's ports")


def script_assignments(code: str) -> list[tuple[str, Any]]:
    """``a := 1; b = 'x'; c := d`` -> [(key, value)], a value being a Python literal or
    ``{key}`` for another entry. ValueError (what cannot be read) otherwise."""
    out = []
    for stmt in _statements(_script_tokens(code)):
        if len(stmt) == 3 and stmt[0].kind == "id" and stmt[1].text in (":=", "="):
            target, value = stmt[0], stmt[2]
            _no_root(target)
            _no_root(value)
            if _is_literal(value):
                out.append((target.text, _script_literal(value)))
                continue
            if value.kind == "id":
                out.append((target.text, "{" + value.text + "}"))
                continue
        text = " ".join(t.text for t in stmt)
        raise ValueError(f"cannot read {text!r}: Hearth reads assignments of a literal or of "
                         "another entry (key := 1; key := 'text'; key := other)")
    if not out:
        raise ValueError("an empty script")
    return out


def _statements(tokens: list[_Tok]) -> list[list[_Tok]]:
    out: list[list[_Tok]] = [[]]
    for t in tokens:
        if t.text == ";" and t.kind == "op":
            out.append([])
        else:
            out[-1].append(t)
    return [s for s in out if s]


def script_condition(code: str) -> str:
    """A BT.CPP boolean script (``A == 1 && name != 'john' || !done``) as a Hearth condition
    (``{A} == 1 && {name} != 'john' || not {done}``). ValueError beyond that subset."""
    stmts = _statements(_script_tokens(code))
    if len(stmts) != 1:
        raise ValueError("a condition is one expression (no ';')")
    parts: list[list[_Tok]] = [[]]
    joins: list[str] = []
    for t in stmts[0]:
        if t.kind == "op" and t.text in ("&&", "||"):
            parts.append([])
            joins.append(t.text)
        else:
            parts[-1].append(t)

    def operand(tok: _Tok) -> str:
        _no_root(tok)
        if tok.kind == "id" and tok.text not in ("true", "false"):
            return "{" + tok.text + "}"
        if tok.kind == "str":
            return "'" + tok.text[1:-1] + "'" if "'" not in tok.text[1:-1] else tok.text
        return tok.text

    out = []
    for part in parts:
        text = " ".join(t.text for t in part)
        if len(part) == 1 and part[0].kind in ("id", "str", "num"):
            out.append(operand(part[0]))
        elif len(part) == 2 and part[0].text == "!" and part[1].kind == "id":
            out.append("not " + operand(part[1]))
        elif len(part) == 3 and part[1].kind == "op" and part[1].text in _COMPARE \
                and part[0].kind != "op" and part[2].kind != "op":
            out.append(f"{operand(part[0])} {part[1].text} {operand(part[2])}")
        else:
            raise ValueError(f"cannot read {text or code!r}: Hearth reads comparisons "
                             "(== != < <= > >=), ! and && / || (no arithmetic, no parentheses)")
    text = out[0]
    for j, o in zip(joins, out[1:]):
        text += f" {j} {o}"
    return text
