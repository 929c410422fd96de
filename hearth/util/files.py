"""Reading a file a user names (a world, a mission): only a regular file, and no more of it
than a limit, with every problem one ``path:line: message`` error of the caller's family.

Importing this module is cheap (no third-party imports).
"""
from __future__ import annotations

import os
import stat

from hearth.util.errors import HearthError


def read_limited(path, limit: int, error: type[HearthError], too_large: str) -> bytes:
    """The bytes of the regular file ``path``, of at most ``limit`` bytes.

    A device, a directory or a FIFO is refused before anything is read (so ``/dev/zero``
    cannot hang a load). Every problem raises ``error(message, file=str(path), line=None)``
    (printed ``path:0: message`` by a family whose file problems carry a line, ``path:
    message`` by one whose do not); a file over the limit says ``too_large``.
    """
    name = str(path)
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer; no effect on regular files.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise error("not a regular file", file=name, line=None)
            if st.st_size > limit:
                raise error(too_large, file=name, line=None)
            data = f.read(limit + 1)
    except FileNotFoundError:
        raise error("no such file", file=name, line=None) from None
    except IsADirectoryError:
        raise error("not a regular file (a directory)", file=name, line=None) from None
    except OSError as err:
        raise error(f"cannot read: {err.strerror or err}", file=name, line=None) from None
    if len(data) > limit:           # it grew between the check and the read
        raise error(too_large, file=name, line=None)
    return data


def file_inside(base, rel, start=None) -> tuple[str, str | None]:
    """Where ``rel``, a path relative to the folder ``start`` (default ``base``), leads
    (symbolic links followed), and why a file named by a file from elsewhere may not be read
    there (None: it may): it must lie inside ``base``.

    The one rule for every path a world, a mesh, a material library or a recording names:
    relative, inside the folder once links are followed, a regular file (not a directory, a
    FIFO that would block, a device that never ends). The reasons are codes the callers turn
    into their own sentences: ``"not relative"`` (empty, absolute, ``~``, a NUL byte),
    ``"leaves"`` (``..`` out of the folder), ``"leaves through a link"``, ``"missing"``,
    ``"not regular"``, ``"unreadable: STRERROR"``.
    """
    if not isinstance(rel, str) or not rel or "\x00" in rel or os.path.isabs(rel) \
            or rel.startswith("~"):
        return "", "not relative"
    norm = os.path.normpath(rel)
    if start is None and (norm == ".." or norm.startswith(".." + os.sep)):
        return "", "leaves"
    real_base = os.path.realpath(base)
    full = os.path.realpath(os.path.join(start or real_base, rel))
    if os.path.commonpath([real_base, full]) != real_base:
        return full, "leaves through a link"
    try:
        st = os.stat(full)
    except FileNotFoundError:
        return full, "missing"
    except OSError as err:
        return full, f"unreadable: {err.strerror}"
    if not stat.S_ISREG(st.st_mode):
        return full, "not regular"
    return full, None


#: The longest integer a JSON file Hearth reads may hold, in digits (a 64-bit integer has at
#: most 20). Python's own limit (4300 digits) is a ValueError far from the file's line, and
#: a number that long is never data.
MAX_INT_DIGITS = 40


class BadJSON(ValueError):
    """Why a JSON text was refused: ``message`` and, where known, ``line`` (1-based)."""

    def __init__(self, message: str, line: int = 0, syntax=None):
        super().__init__(message)
        self.message, self.line = message, line
        self.syntax = syntax    # the json.JSONDecodeError, when the text is not JSON at all


def _bounded_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise BadJSON(f"an integer of {digits} digits (at most {MAX_INT_DIGITS})")
    return int(text)


def _no_constant(name: str):
    raise BadJSON(f"{name} is not a JSON number")


def _finite_float(text: str) -> float:
    value = float(text)
    if value in (float("inf"), float("-inf")):
        raise BadJSON(f"the number {text[:40]} is beyond a float's range")
    return value


def _unique_keys(pairs):
    out = {}
    for k, v in pairs:
        if k in out:
            raise BadJSON(f"the key {k[:40]!r} is given twice")
        out[k] = v
    return out


def load_json(text: str | bytes, *, finite: bool = False, unique_keys: bool = False):
    """``json.loads`` for text from a file or a request, with every problem one ``BadJSON``:
    integers bounded (``MAX_INT_DIGITS``), nesting bounded (Python's recursion limit, said in
    words), and with ``finite`` NaN and Infinity refused, with ``unique_keys`` a key given
    twice in one object refused (plain ``json`` keeps the last silently). Strings are checked
    to be encodable UTF-8 (``"\\ud800"`` decodes to a lone surrogate that no file, log or
    answer can hold)."""
    import json
    try:
        value = json.loads(text, parse_int=_bounded_int,
                           parse_float=_finite_float if finite else None,
                           parse_constant=_no_constant if finite else None,
                           object_pairs_hook=_unique_keys if unique_keys else None)
    except BadJSON as err:
        if err.message.startswith("an integer"):     # say where: the first such run of digits
            import re
            raw = text.decode("utf-8", "replace") if isinstance(text, bytes) else text
            m = re.search(r"[0-9]{%d,}" % (MAX_INT_DIGITS + 1), raw)
            if m is not None:
                err.line = raw.count("\n", 0, m.start()) + 1
        raise
    except json.JSONDecodeError as err:
        raise BadJSON(f"{err.msg} (column {err.colno})", err.lineno, syntax=err) from None
    except RecursionError:
        raise BadJSON("nested too deeply") from None
    except UnicodeDecodeError:
        raise BadJSON("not UTF-8 text") from None
    except ValueError as err:           # e.g. a float literal too long for the parser
        raise BadJSON(str(err)[:120]) from None
    if _may_hold_surrogates(text):
        _check_strings(value)
    return value


def _may_hold_surrogates(text: str | bytes) -> bool:
    """Whether a JSON text can decode to a lone surrogate: only through a \\uD800-\\uDFFF
    escape (or, in a ``str``, the character itself)."""
    import re
    if isinstance(text, bytes):
        return re.search(rb"\\u[dD][89abcdefABCDEF]", text) is not None
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return True
    return re.search(r"\\u[dD][89abcdefABCDEF]", text) is not None


def _check_strings(value) -> None:
    stack = [value]
    while stack:
        cur = stack.pop()
        if isinstance(cur, str):
            try:
                cur.encode("utf-8")
            except UnicodeEncodeError:
                raise BadJSON("a string holds a lone surrogate (\\ud800-\\udfff), which is "
                              "not text") from None
        elif isinstance(cur, dict):
            stack.extend(cur.keys())
            stack.extend(cur.values())
        elif isinstance(cur, list):
            stack.extend(cur)
