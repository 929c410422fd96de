"""The day's part of the command API (``hearth serve --schedule``, docs/day.md): the battery
and its watch's levels, emergencies, away, the schedule's slots run and missed.

    GET  /api/day              battery, levels, away, figures so far, missed slots
    PUT  /api/day/battery      {"low": 0.3, "critical": 0.15, "charge_to": 0.95} (any of them)
    POST /api/day/emergency    {"user_room": "bathroom"} ("" or absent: unknown)
    PUT  /api/day/away         {"away": true}

Day events reach the event stream (``/api/events``) as kind ``day`` and the monitor's log.
A :class:`DayRunner` calls ``Day.step()`` once a second on its own thread.
"""
from __future__ import annotations

import threading
from typing import Any

from fastapi import APIRouter, Depends
from pydantic import BaseModel, Field


class BatteryLevels(BaseModel):
    low: float | None = Field(default=None, gt=0, le=1)
    critical: float | None = Field(default=None, gt=0, le=1)
    charge_to: float | None = Field(default=None, gt=0, le=1)


class EmergencyCall(BaseModel):
    user_room: str = Field(default="", max_length=200)
    source: str = Field(default="api", max_length=200)


class Away(BaseModel):
    away: bool


class DayRunner:
    """Steps a Day every ``period`` seconds of real time until ``close()``."""

    def __init__(self, day: Any, period: float = 1.0):
        self.day = day
        self.period = period
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hearth-day", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        import logging
        while not self._stop.wait(self.period):
            try:
                self.day.step()
            except Exception:  # noqa: BLE001 - the watch must go on
                logging.getLogger("hearth.day").exception("day step failed")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)


def day_router(day: Any, check_token: Any) -> APIRouter:
    """The routes above over ``day``; ``check_token``: the app's token dependency."""
    r = APIRouter(prefix="/api/day", dependencies=[Depends(check_token)], tags=["day"])

    @r.get("", summary="the day: battery, watch levels, away, figures, missed slots")
    def state() -> dict[str, Any]:
        b = day.battery
        return {"battery": day.robot.battery_state().as_dict(),
                "levels": {"low": b.low, "critical": b.critical, "charge_to": b.charge_to},
                "away": day.away, "time": day.now_text(), "report": day.report(),
                "missed": day.missed[-50:]}

    @r.put("/battery", summary="set the battery watch's levels (a runtime parameter)")
    def battery(body: BatteryLevels) -> dict[str, Any]:
        new = day.set_battery(body.low, body.critical, body.charge_to)
        return {"low": new.low, "critical": new.critical, "charge_to": new.charge_to}

    @r.post("/emergency", summary="the user calls for help: go_to_user above everything")
    def emergency(body: EmergencyCall) -> dict[str, Any]:
        h = day.emergency(body.user_room, source=body.source)
        return {"run": h.id if h is not None else None, "waits_for_charge": h is None}

    @r.put("/away", summary="the user is out (the schedule pauses) or back")
    def away(body: Away) -> dict[str, Any]:
        day.set_away(body.away)
        return {"away": day.away}

    return r


__all__ = ["DayRunner", "day_router"]
