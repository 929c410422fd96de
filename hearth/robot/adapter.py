"""The robot adapter protocol: what skills may ask of a robot (docs/robot-adapter.md).

Every long-running request returns an ``Action`` at once (never blocks): skills start it in
``initialise()``, poll ``status()`` in ``update()`` and ``cancel()`` it in ``terminate()``.
Poses are world-frame ``hearth.worldmodel.pose.Pose`` values; a base pose uses x, y and yaw only.
The adapter reports what the robot *believes* (its localisation); simulators keep the truth
apart and expose it only as ground truth (``Frame.T_world_camera_true``).
"""
from __future__ import annotations

import threading
from typing import Any, Callable, Optional, Protocol, runtime_checkable


from hearth.robot.errors import RobotError
from hearth.worldmodel import frames
from hearth.worldmodel.pose import Pose

STATUSES = ("running", "succeeded", "failed", "cancelled")


#: How a grasp that came back empty starts its reason (RobotAdapter.grasp).
EMPTY_GRASP = "the gripper closed on nothing"


class Action:
    """A request in progress. ``status()`` is one of running, succeeded, failed, cancelled;
    ``progress`` 0..1; ``reason`` says why it failed or was cancelled; ``result`` what it
    produced (for example the reached pose). ``cancel()`` stops it (no effect once ended)."""

    def __init__(self, name: str = "action"):
        self.name = name
        self._status = "running"
        self.progress = 0.0
        self.reason = ""
        self.result: Any = None
        self._lock = threading.RLock()

    def status(self) -> str:
        return self._status

    def done(self) -> bool:
        return self.status() != "running"

    def cancel(self) -> None:
        with self._lock:
            if self._status == "running":
                self._status = "cancelled"
                self.reason = self.reason or "cancelled"

    def _finish(self, status: str, reason: str = "", result: Any = None) -> None:
        with self._lock:
            if self._status != "running":
                return
            self._status = status
            self.reason = reason
            if result is not None:
                self.result = result
            if status == "succeeded":
                self.progress = 1.0

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} {self._status} {self.progress:.0%}>"


class DoneAction(Action):
    """An action that has already succeeded (instant requests: speech, head moves)."""

    def __init__(self, name: str = "action", result: Any = None):
        super().__init__(name)
        self._finish("succeeded", result=result)


class FailedAction(Action):
    """An action refused at once, with the reason."""

    def __init__(self, name: str, reason: str):
        super().__init__(name)
        self._finish("failed", reason)


class TimedAction(Action):
    """An action that takes ``duration`` seconds on ``clock`` (simulated or real).

    Its state is computed from the clock whenever it is asked (no threads): at the end
    ``on_done()`` applies its effect (a RobotError raised there fails it with that reason;
    ``fail`` fails it at the end without applying anything); ``on_progress(fraction)`` is
    called on every poll and ``on_cancel(fraction)`` when it is cancelled, so a cancelled
    door stays part-open and a cancelled drive stops where it was.
    """

    def __init__(self, name: str, clock, duration: float,
                 on_done: Optional[Callable[[], Any]] = None,
                 on_progress: Optional[Callable[[float], None]] = None,
                 on_cancel: Optional[Callable[[float], None]] = None,
                 fail: Optional[str] = None, fail_at: float = 1.0):
        super().__init__(name)
        self.clock = clock
        self.start = clock.now()
        self.stopped_at: Optional[float] = None
        self.duration = max(float(duration), 0.0)
        self._on_done, self._on_progress, self._on_cancel = on_done, on_progress, on_cancel
        self._fail, self._fail_at = fail, fail_at

    def _fraction(self) -> float:
        if self.duration <= 0:
            return 1.0
        return min(max((self.clock.now() - self.start) / self.duration, 0.0), 1.0)

    def status(self) -> str:
        with self._lock:
            if self._status != "running":
                return self._status
            f = self._fraction()
            if self._fail is not None and f >= self._fail_at:
                self.progress = self._fail_at
                if self._on_progress:
                    self._on_progress(self._fail_at)
                self._finish("failed", self._fail)
                return self._status
            self.progress = f
            if self._on_progress:
                self._on_progress(f)
            if f >= 1.0:
                try:
                    result = self._on_done() if self._on_done else None
                except RobotError as err:
                    self._finish("failed", str(err))
                else:
                    self._finish("succeeded", result=result)
            return self._status

    def cancel(self) -> None:
        with self._lock:
            if self.status() != "running":
                return
            self.stopped_at = self.clock.now()
            f = self._fraction()
            self.progress = f
            if self._on_cancel:
                self._on_cancel(f)
            super().cancel()


def wait(action: Action, clock, timeout: float = 600.0, step: float = 0.1) -> str:
    """Advance ``clock`` (sleep) until ``action`` ends or ``timeout`` seconds pass; the final
    status. For scripts and tests; skills poll instead."""
    t_end = clock.now() + timeout
    while action.status() == "running" and clock.now() < t_end:
        clock.sleep(step)
    return action.status()


def as_base_pose(pose) -> Pose:
    """A planar base Pose from a Pose, a 4x4 ``T_world_base``, (x, y, yaw) or a mapping with
    x, y, yaw."""
    try:
        return frames.as_base_pose(pose)
    except ValueError:
        raise RobotError(f"not a base pose: {pose!r}") from None


@runtime_checkable
class RobotAdapter(Protocol):
    """What every robot adapter offers (simulated, replayed, recorded, real)."""

    # -- localisation -------------------------------------------------------------------
    def base_pose(self) -> Pose:
        """The believed base pose in the world (x, y, yaw)."""

    def apply_correction(self, pose) -> None:
        """Set the believed base pose to ``pose`` (a Pose, (x, y, yaw) or 4x4 T_world_base),
        e.g. after a localisation fix on landmarks."""

    # -- base and head -------------------------------------------------------------------
    def navigate_to(self, pose) -> Action:
        """Drive so that the believed base pose becomes ``pose``; result: the reached
        believed Pose."""

    def head(self) -> tuple[float, float]:
        """Head (pan, tilt) in radians; (0, 0) for a fixed camera."""

    def set_head(self, pan: float, tilt: float) -> Action:
        """Turn the head (radians, clipped to its limits)."""

    def look_at(self, point_world) -> Action:
        """Turn the head so the camera's optical axis goes through a world point (metres),
        as far as the believed base pose allows."""

    # -- sensing -------------------------------------------------------------------------
    def capture(self):
        """A fresh RGB-D ``robot.sim.Frame``: color uint8 RGB (H, W, 3), depth float32 metres
        (0 = none), ``intrinsics``, believed ``T_world_camera``, ``timestamp``, pan/tilt."""

    # -- arm -----------------------------------------------------------------------------
    def open_articulated(self, part_id: str, handle_id: Optional[str],
                         target_state: float) -> Action:
        """Open a door or drawer by its handle to a joint state (rad or m)."""

    def close_articulated(self, part_id: str, handle_id: Optional[str],
                          target_state: float = 0.0) -> Action:
        """Close a door or drawer by its handle (to ``target_state``, normally its lower limit)."""

    def turn_knob(self, knob_id: str, angle: float) -> Action:
        """Turn a knob to an angle (rad, the knob's frame)."""

    def grasp(self, object_id: str, pose: Pose) -> Action:
        """Grasp a small object seen at ``pose`` (world). A grasp that reached the pose and
        came back with nothing in the gripper fails with a reason starting with
        ``EMPTY_GRASP``: the object was not where it was seen (a false detection), which a
        mission may answer by searching on."""

    def place(self, parent_id: str, pose: Pose) -> Action:
        """Put the held object down on/in large object ``parent_id`` at world ``pose``."""

    def hand_over(self) -> Action:
        """Hand the held object to the person."""

    # -- battery and charger (docs/day.md) --------------------------------------------------
    def battery_state(self):
        """The battery now: a ``robot.battery.BatteryState`` (level 0..1, charging, docked)."""

    def dock(self) -> Action:
        """Dock on the charger the robot stands in front of (at its dock pose); charging
        starts once docked. Result: the charger's id."""

    def undock(self) -> Action:
        """Leave the charger (done at once when not docked)."""

    # -- speech and safety -----------------------------------------------------------------
    def say(self, text: str) -> Action:
        """Say a text (returns at once; the action ends when the speech has been said)."""

    def stop(self) -> None:
        """Stop everything now: every running action is cancelled."""
