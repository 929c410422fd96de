"""Robot adapters: the protocol (robot/adapter.py), the simulated robot over a truth world
(robot/simulated.py), recordings and the replay robot (robot/recording.py), scenarios
(robot/scenario.py), the Kinect-class noise model (robot/noise.py) and simulated views
(robot/sim.py). See docs/robot-adapter.md and docs/recording-format.md.
"""
from __future__ import annotations

from typing import Any, Optional

from hearth.robot.errors import RobotError

__all__ = ["Action", "DoneAction", "FailedAction", "RobotAdapter", "RobotError", "TimedAction",
           "create_adapter", "wait"]

# The adapter protocol (numpy, the world model) is re-exported lazily (PEP 562), so importing
# hearth.robot.errors or hearth.robot.clock stays cheap.
_ADAPTER_NAMES = ("Action", "DoneAction", "FailedAction", "RobotAdapter", "TimedAction", "wait")


def __getattr__(name: str):
    if name in _ADAPTER_NAMES:
        from hearth.robot import adapter
        value = getattr(adapter, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'hearth.robot' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


def create_adapter(world=None, scenario: Optional[str] = None, recording: Optional[str] = None,
                   clock: Any = None, topics: Any = None, ros2: Optional[str] = None, **kw):
    """The robot adapter for a run.

    - ``recording`` (a Hearth recording directory, or a ROS 2 bag: an ``.mcap`` file or a
      rosbag2 directory, with ``topics`` its topic and frame mapping, see
      ``hearth.robot.rosbag.TopicMap``): a ``ReplayRobot`` serving its frames, checked whole
      before it starts (keywords go to it, e.g. ``position_tolerance``, ``yaw_tolerance``).
    - ``scenario`` (a directory from ``hearth scenario make`` / ``robot.scenario``): a
      ``SimulatedRobot`` on the scenario's truth, start pose, localisation error, stuck knobs
      and locked doors.
    - neither: a ``SimulatedRobot`` whose truth is a copy of ``world`` (the belief map).

    - ``ros2`` (a Zenoh endpoint, rmw_zenoh's router): a live ROS 2 robot,
      ``hearth.robot.ros2_live.Ros2Robot``, with ``topics`` its names (the same mapping).

    Other keywords go to ``SimulatedRobot`` (``seed``, ``noise``, ``intrinsics``, ...).
    Raises RobotError (one line, with the file) for a bad recording or scenario.
    """
    if ros2 is not None:
        if recording is not None or scenario is not None:
            raise RobotError("a live ROS 2 robot (--ros2) takes no scenario or recording")
        from hearth.robot.ros2_live import Ros2Robot
        return Ros2Robot(world=world, endpoint=ros2, topics=topics, clock=clock, **kw)
    if recording is not None and scenario is not None:
        raise RobotError("give a scenario or a recording, not both")
    if recording is not None:
        from hearth.robot.recording import ReplayRobot, open_recording
        return ReplayRobot(open_recording(recording, topics=topics), clock=clock, **kw)
    if topics is not None:
        raise RobotError("--topics maps the topics of a ROS 2 bag given with --recording "
                         "or of a live robot given with --ros2")
    from hearth.robot.simulated import SimulatedRobot
    if scenario is not None:
        from hearth.robot.scenario import load_scenario
        sc = load_scenario(scenario, clock=clock)
        kw.setdefault("seed", sc.seed)
        return SimulatedRobot(sc.truth, clock=clock, start_pose=sc.start_pose,
                              localisation_error=sc.localisation_error,
                              stuck_knobs=sc.stuck_knobs, locked=sc.locked, **kw)
    if world is None:
        raise RobotError("a simulated robot needs a world (or a scenario, or a recording)")
    return SimulatedRobot(world.copy(), clock=clock, **kw)
