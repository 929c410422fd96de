"""Row bands of an image processed on a small thread pool (numpy releases the GIL).

Shared by the renderer and the simulated sensor noise. The pool is made again in a forked
child, because threads do not survive a fork.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence

def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))     # the cores this process may run on
    except AttributeError:                      # not on every platform
        return os.cpu_count() or 2


#: Bands an image is cut into: one per core, at least 2 and at most 8 (beyond that the
#: bands are too thin for the thread hand-offs to pay).
BANDS = max(2, min(8, _cores()))
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


def in_bands(parts: Sequence, fn: Callable) -> None:
    """``fn(part)`` for every part: all but the last on the pool, the last on the calling
    thread (which would otherwise only wait; and so that one band still runs while another
    task, such as the sensor noise's random draws, holds a pool thread)."""
    futures = [pool().submit(fn, p) for p in parts[:-1]]
    try:
        if parts:
            fn(parts[-1])
    finally:
        for f in futures:
            f.result()
