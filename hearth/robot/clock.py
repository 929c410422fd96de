"""Clocks: the wall clock on a robot, a simulated clock in simulation and tests.

Everything that measures time in Hearth (tick rates, timeouts, navigation and action
durations, history timestamps) takes a clock, so runs are deterministic in simulation.
Times are seconds (float).
"""
from __future__ import annotations

import threading
import time


class WallClock:
    """Real time. ``now()`` is monotonic seconds; ``sleep`` really sleeps."""

    simulated = False

    def now(self) -> float:
        return time.monotonic()

    def wall(self) -> float:
        """Seconds since the epoch, for timestamps people read."""
        return time.time()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

    def advance(self, seconds: float) -> None:
        """Real time cannot be advanced: it passes by itself. Sleep instead."""
        self.sleep(seconds)


class SimClock:
    """Simulated time that moves only when advanced, as fast as the computer allows.

    ``sleep(dt)`` advances the clock by ``dt`` at once. Thread-safe.
    """

    simulated = True

    def __init__(self, start: float = 0.0, epoch: float = 1_700_000_000.0):
        self._t = float(start)
        self._epoch = float(epoch)
        self._lock = threading.Lock()

    def now(self) -> float:
        with self._lock:
            return self._t

    def wall(self) -> float:
        with self._lock:
            return self._epoch + self._t

    def advance(self, seconds: float) -> None:
        if seconds < 0:
            raise ValueError("a clock cannot go backwards")
        with self._lock:
            self._t += seconds

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            self.advance(seconds)
