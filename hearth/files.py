"""Reading a file a user names (a world, a mission): only a regular file, and no more of it
than a limit, with every problem one ``path:line: message`` error of the caller's family.

Importing this module is cheap (no third-party imports).
"""
from __future__ import annotations

import os
import stat

from hearth.errors import HearthError


def read_limited(path, limit: int, error: type[HearthError], too_large: str) -> bytes:
    """The bytes of the regular file ``path``, of at most ``limit`` bytes.

    A device, a directory or a FIFO is refused before anything is read (so ``/dev/zero``
    cannot hang a load). Every problem raises ``error(message, file=str(path), line=0)``; a
    file over the limit says ``too_large``.
    """
    name = str(path)
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer; no effect on regular files.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise error("not a regular file", file=name, line=0)
            if st.st_size > limit:
                raise error(too_large, file=name, line=0)
            data = f.read(limit + 1)
    except FileNotFoundError:
        raise error("no such file", file=name, line=0) from None
    except IsADirectoryError:
        raise error("not a regular file (a directory)", file=name, line=0) from None
    except OSError as err:
        raise error(f"cannot read: {err.strerror or err}", file=name, line=0) from None
    if len(data) > limit:           # it grew between the check and the read
        raise error(too_large, file=name, line=0)
    return data
