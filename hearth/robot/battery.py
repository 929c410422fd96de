"""The robot's battery: what an adapter reports (``BatteryState``) and the simulated robot's
energy model (``BatteryModel``, ``Battery``).

Levels are fractions of the capacity, 0 (flat) to 1 (full). The simulated battery is
integrated lazily from the clock, as ``TimedAction`` is: ``Battery.update(now, driving_s,
arm_s)`` is told how many of the seconds since the last update the base and the arm were
moving, so a simulated clock that jumps an hour ahead drains (or charges) exactly as an hour
of ticks would.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class BatteryState:
    """What the robot reports: ``level`` 0..1, ``charging`` (energy is going in), ``docked``
    (on a charger; ``charger`` its map id when known)."""
    level: float
    charging: bool = False
    docked: bool = False
    charger: Optional[str] = None

    def as_dict(self) -> dict:
        return {"level": round(self.level, 4), "charging": self.charging,
                "docked": self.docked, "charger": self.charger}


@dataclass(frozen=True)
class BatteryModel:
    """Energy use of a HOBBIT-class robot (watts) and its battery (watt-hours).

    Defaults: 200 Wh; 12 W standing (computer, sensors), 40 W more while the base drives,
    25 W more while the arm moves; 100 W charging on the dock (about 2 h from flat to
    full). Standing still a full battery lasts ~17 h, driving all the time ~4 h.
    """
    capacity_wh: float = 200.0
    idle_w: float = 12.0
    drive_w: float = 40.0
    arm_w: float = 25.0
    charge_w: float = 100.0

    def __post_init__(self):
        for name in ("capacity_wh", "charge_w"):
            if not getattr(self, name) > 0:
                raise ValueError(f"battery {name} must be positive")
        for name in ("idle_w", "drive_w", "arm_w"):
            if getattr(self, name) < 0:
                raise ValueError(f"battery {name} must not be negative")

    def seconds_to(self, level_from: float, level_to: float) -> float:
        """Seconds of charging on the dock from one level to a higher one."""
        return max(level_to - level_from, 0.0) * self.capacity_wh * 3600.0 / self.charge_w


class Battery:
    """The simulated battery: a level integrated over the clock."""

    def __init__(self, model: BatteryModel = BatteryModel(), level: float = 1.0,
                 now: float = 0.0):
        if not 0.0 <= level <= 1.0:
            raise ValueError(f"battery level {level!r} is not in 0..1")
        self.model = model
        self.level = float(level)
        self.t = float(now)
        self.docked: Optional[str] = None
        self.lowest = self.level

    def update(self, now: float, driving_s: float = 0.0, arm_s: float = 0.0) -> float:
        """Integrate from the last update to ``now`` (seconds); the new level."""
        dt = now - self.t
        if dt <= 0:
            return self.level
        m = self.model
        if self.docked is not None:
            joules = m.charge_w * dt       # the charger also powers the robot standing
        else:
            joules = -(m.idle_w * dt + m.drive_w * min(driving_s, dt) + m.arm_w * min(arm_s, dt))
        self.level = min(max(self.level + joules / (m.capacity_wh * 3600.0), 0.0), 1.0)
        self.lowest = min(self.lowest, self.level)
        self.t = now
        return self.level

    def state(self) -> BatteryState:
        return BatteryState(self.level, charging=self.docked is not None and self.level < 1.0,
                            docked=self.docked is not None, charger=self.docked)
