"""A thread-safe list of callbacks, for the objects that tell others of their changes (the
world model's map changes, the autonomy approvals).

Importing this module is cheap (no third-party imports).
"""
from __future__ import annotations

import threading
from typing import Callable, Generic, Iterator, TypeVar

F = TypeVar("F", bound=Callable)


class Subscribers(Generic[F]):
    """``add(callback)`` returns the function that removes it again; iterating gives the
    callbacks subscribed at that moment, so a callback may unsubscribe while it is called."""

    def __init__(self):
        self._lock = threading.Lock()
        self._callbacks: list[F] = []

    def add(self, callback: F) -> Callable[[], None]:
        with self._lock:
            self._callbacks.append(callback)

        def unsubscribe() -> None:
            with self._lock:
                if callback in self._callbacks:
                    self._callbacks.remove(callback)
        return unsubscribe

    def __iter__(self) -> Iterator[F]:
        with self._lock:
            return iter(list(self._callbacks))
