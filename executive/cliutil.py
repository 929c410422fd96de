"""Helpers shared by the `hearth` subcommands that load and run missions."""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from executive.errors import MissionError
from hearth import demo_world_path, missions_dir

if TYPE_CHECKING:   # the mission loader (py_trees, jsonschema) is imported when a command runs
    from executive.missionfile import Mission

DEFAULT_WORLD = demo_world_path()


def parse_params(mission: Mission, pairs: list[str] | None) -> dict[str, Any]:
    """``["presence=away", ...]`` -> typed values for ``mission``'s parameters."""
    from executive.missionfile import parse_param_text

    out: dict[str, Any] = {}
    for pair in pairs or []:
        name, sep, text = pair.partition("=")
        name = name.strip()
        if not sep or not name:
            raise MissionError(f"expected NAME=VALUE, got {pair!r}", param=name or pair)
        spec = mission.parameters.get(name)
        if spec is None:
            known = ", ".join(sorted(mission.parameters)) or "none"
            raise MissionError(f"unknown parameter of mission {mission.name} (known: {known})",
                               param=name)
        out[name] = parse_param_text(name, spec.type, text)
    mission.resolve_parameters(out)   # enum, required and item checks before anything starts
    return out


def mission_file(text: str) -> str:
    """A mission argument as given, or, when no such file is here, the shipped mission it
    names (``missions/go_to_rest.yaml`` or ``go_to_rest.yaml``): an installed Hearth runs its
    own missions from any directory."""
    path = Path(text)
    if path.exists() or path.is_absolute():
        return text
    shipped = missions_dir()
    for candidate in (shipped.parent / path, shipped / path):
        if candidate.is_file():
            return str(candidate)
    return text


# -- argument types: a bad value is argparse's one error line and exit 2, never a traceback --

#: Tick rates `hearth run/step/record/serve` accept (Hz).
MIN_TICK_HZ, MAX_TICK_HZ = 0.1, 1000.0
#: Seeds: what numpy's and Python's generators all take.
MAX_SEED = 2**32 - 1


def number_in(lo: float, hi: float, what: str = "a number", lo_open: bool = False
              ) -> Callable[[str], float]:
    """An argparse type: a finite float in [lo, hi] (or (lo, hi] with ``lo_open``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        low_ok = value > lo if lo_open else value >= lo
        if not (math.isfinite(value) and low_ok and value <= hi):
            raise argparse.ArgumentTypeError(
                f"{what} must be a number {'>' if lo_open else '>='} {lo:g} and <= {hi:g}, "
                f"got {text!r}")
        return value
    parse.__name__ = what
    return parse


def integer_in(lo: int, hi: int, what: str = "an integer") -> Callable[[str], int]:
    """An argparse type: an integer in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{what} must be an integer from {lo} to {hi}, "
                                             f"got {text!r}")
        return value
    parse.__name__ = what
    return parse


tick_rate = number_in(MIN_TICK_HZ, MAX_TICK_HZ, "the tick rate")
seed = integer_in(0, MAX_SEED, "a seed")


def output_dir(text: str) -> str:
    """An argparse type: a directory to write into (it may exist, or be made), not a file."""
    if not text:
        raise argparse.ArgumentTypeError("an output directory must be named")
    if os.path.lexists(text) and not os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a directory")
    return text


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("mission", type=mission_file,
                   help="mission file (YAML); one not found here is looked up among the shipped "
                        "missions (missions/NAME.yaml)")
    p.add_argument("--param", action="append", metavar="NAME=VALUE", default=[],
                   help="mission parameter (repeatable)")
    p.add_argument("--world", default=str(DEFAULT_WORLD),
                   help="world file (default: data/demo_home/world.xml)")
    p.add_argument("--scenario", default=None, metavar="DIR", help="simulation scenario")
    p.add_argument("--recording", default=None, metavar="PATH",
                   help="recording to replay instead of simulating: a Hearth recording "
                        "directory, or a ROS 2 bag (.mcap file or rosbag2 directory)")
    p.add_argument("--tick-hz", type=tick_rate, default=10.0,
                   help=f"tick rate (Hz, {MIN_TICK_HZ:g} to {MAX_TICK_HZ:g}; default 10)")
    p.add_argument("--runs-dir", default="runs", help="where execution logs go")
    p.add_argument("--wall-clock", action="store_true",
                   help="run in real time (default: simulated time, as fast as possible)")


def make_world_and_robot(args: argparse.Namespace, clock: Any) -> tuple[Any, Any]:
    """Load the world (worldmodel.io.load_world) and make the robot adapter
    (robot.create_adapter); one clear MissionError line if either is not available."""
    try:
        from worldmodel.io import load_world
    except ImportError as err:
        raise MissionError(f"cannot load worlds: worldmodel.io is not available ({err})") from None
    world = load_world(args.world, clock=clock)
    try:
        from hearth import robot
        create_adapter = robot.create_adapter
    except (ImportError, AttributeError):
        raise MissionError("no robot adapter: robot.create_adapter() does not exist yet") from None
    extra = {"topics": args.topics} if getattr(args, "topics", None) else {}   # a bag's mapping
    adapter = create_adapter(world=world, scenario=args.scenario, recording=args.recording,
                             clock=clock, **extra)
    return world, adapter


def make_clock(args: argparse.Namespace) -> Any:
    from hearth.robot.clock import SimClock, WallClock
    return WallClock() if getattr(args, "wall_clock", False) else SimClock()


def run_to_end(ex: Any, mission: Mission, params: dict[str, Any], quiet: bool = False) -> Any:
    """Submit ``mission`` to a non-background Executive, print its progress unless ``quiet``,
    tick it to the end (Ctrl-C cancels it and lets the robot stop) and return its result."""
    from executive.replay import format_event

    if not quiet:
        ex.subscribe(lambda e: print(format_event(e.to_json()))
                     if e.kind in ("run", "feedback", "write", "param", "restart") else None)
    handle = ex.submit(mission, **params)
    try:
        ex.run_until_idle()
    except KeyboardInterrupt:
        handle.cancel("interrupted")
        ex.run_until_idle(100_000)
    return handle.result


def make_executive(args: argparse.Namespace) -> tuple[Mission, dict[str, Any], Any]:
    """The mission, its typed parameters and a non-background Executive on the world and
    robot named by ``add_run_arguments`` options (what `hearth run` and `hearth step` share)."""
    from executive.executive import Executive
    from executive.missionfile import load_mission

    mission = load_mission(args.mission)
    params = parse_params(mission, args.param)
    clock = make_clock(args)
    world, robot = make_world_and_robot(args, clock)
    ex = Executive(world=world, robot=robot, clock=clock, tick_hz=args.tick_hz,
                   runs_dir=args.runs_dir, background=False)
    return mission, params, ex


def add_foxglove_arguments(p, live: bool = True, file: bool = True, wait: bool = True) -> None:
    """The ``--foxglove [PORT]`` (and ``--foxglove-mcap FILE``) options of run/serve."""
    if live:
        p.add_argument("--foxglove", nargs="?", type=int, const=8765, default=None,
                       metavar="PORT",
                       help="stream the run live to Foxglove on ws://127.0.0.1:PORT (default "
                            "8765; 0: any free port); needs the ros extra")
    if file:
        p.add_argument("--foxglove-mcap", default=None, metavar="FILE",
                       help="write the run's log, tree, poses, images and map as MCAP with "
                            "Foxglove schemas (a new file); needs the ros extra")
    if live and wait:
        p.add_argument("--foxglove-wait", type=float, default=10.0, metavar="SECONDS",
                       help="with --foxglove on a simulated clock: wait up to this long for a "
                            "viewer before starting, and after the end for viewers to leave "
                            "(default 10; 0: do not wait)")
