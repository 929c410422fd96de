"""Row bands of an image processed on a small thread pool (numpy releases the GIL).

Shared by the renderer and the simulated sensor noise. The pool is made again in a forked
child, because threads do not survive a fork.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

BANDS = 2
_POOL: ThreadPoolExecutor | None = None
_POOL_PID: int | None = None


def pool() -> ThreadPoolExecutor:
    global _POOL, _POOL_PID
    if _POOL is None or _POOL_PID != os.getpid():
        _POOL = ThreadPoolExecutor(max_workers=BANDS, thread_name_prefix="bands")
        _POOL_PID = os.getpid()
    return _POOL


def row_bands(height: int) -> list[slice]:
    """``BANDS`` slices covering rows 0..height."""
    return [slice(i * height // BANDS, (i + 1) * height // BANDS) for i in range(BANDS)]
