"""Helpers shared by the `hearth` subcommands that load and run missions."""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from hearth.executive.errors import MissionError
from hearth import demo_world_path, missions_dir

if TYPE_CHECKING:   # the mission loader (py_trees, jsonschema) is imported when a command runs
    from hearth.executive.missionfile import Mission

DEFAULT_WORLD = demo_world_path()


def parse_params(mission: Mission, pairs: list[str] | None) -> dict[str, Any]:
    """``["presence=away", ...]`` -> typed values for ``mission``'s parameters."""
    from hearth.executive.missionfile_types import parse_param_text

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
        if name in out:     # the last would silently win: say which one was meant
            raise MissionError(f"given twice (--param {name}=...); give it once", param=name)
        out[name] = parse_param_text(name, spec.type, text)
    mission.resolve_parameters(out)   # enum, required and item checks before anything starts
    return out


def mission_file(text: str) -> str:
    """A mission argument as given, or, when no such file is here, the shipped mission it
    names (``missions/go_to_rest.yaml``, ``go_to_rest.yaml`` or ``go_to_rest``): an installed
    Hearth runs its own missions from any directory."""
    path = Path(text)
    if path.exists() or path.is_absolute():
        return text
    shipped = missions_dir()
    named = [shipped / f"{text}.yaml"] if text and not path.suffix and "/" not in text else []
    for candidate in (shipped.parent / path, shipped / path, *named):
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


def suite_missions(text: str) -> tuple[str, ...]:
    """An argparse type: comma-separated missions the scenario suite can make cases for."""
    from hearth.executive.scenarios import SUITE_MISSIONS
    names = tuple(m.strip() for m in text.split(",") if m.strip())
    bad = [m for m in names if m not in SUITE_MISSIONS]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"no scenarios for {', '.join(map(repr, bad)) or 'no mission'}; the suite has "
            f"scenarios for {', '.join(SUITE_MISSIONS)}")
    return names


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


def add_command(sub, name: str, doc: str | None, help: str) -> argparse.ArgumentParser:
    """The parser of the command ``name``: ``help`` is its line in ``hearth --help``; its own
    ``--help`` describes it with ``doc``, the docstring of its module, past the first
    paragraph (that one is the synopsis, for the reader of the code)."""
    return sub.add_parser(name, help=help, description=(doc or "").partition("\n\n")[2] or None)


def output_dir(text: str) -> str:
    """An argparse type: a directory to write into (it may exist, or be made), not a file."""
    if not text:
        raise argparse.ArgumentTypeError("an output directory must be named")
    if os.path.lexists(text) and not os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a directory")
    return text


def add_run_arguments(p: argparse.ArgumentParser, saves: bool = True) -> None:
    """The options of a command that runs a mission (run, step, record); ``saves``: whether
    it keeps the belief map on disk by default (add_map_arguments)."""
    p.set_defaults(saves_map=saves)
    p.add_argument("mission", type=mission_file,
                   help="mission file (YAML); one not found here is looked up among the shipped "
                        "missions (missions/NAME.yaml)")
    p.add_argument("--param", action="append", metavar="NAME=VALUE", default=[],
                   help="mission parameter (repeatable)")
    p.add_argument("--world", default=str(DEFAULT_WORLD),
                   help="world file: the belief map (default: the shipped demo home, "
                        "data/demo_home/world.xml)")
    p.add_argument("--scenario", default=None, metavar="DIR", help="simulation scenario")
    p.add_argument("--recording", default=None, metavar="PATH",
                   help="recording to replay instead of simulating: a Hearth recording "
                        "directory, or a ROS 2 bag (.mcap file or rosbag2 directory)")
    p.add_argument("--tick-hz", type=tick_rate, default=10.0,
                   help=f"tick rate (Hz, {MIN_TICK_HZ:g} to {MAX_TICK_HZ:g}; default 10)")
    p.add_argument("--runs-dir", default="runs", help="where execution logs go")
    p.add_argument("--wall-clock", action="store_true",
                   help="run in real time (default: simulated time, as fast as possible)")
    add_map_arguments(p, saves=saves)


def add_topics_argument(p: argparse.ArgumentParser) -> None:
    """``--topics``: how a replayed ROS 2 bag names its topics and frames (run, step)."""
    p.add_argument("--topics", default=None, metavar="FILE|KEY=VALUE,...",
                   help="with a ROS 2 bag: its topics and tf frames (a YAML file, or e.g. "
                        "depth=/cam/depth,base_frame=base_footprint; docs/ros2-foxglove.md)")


def add_map_arguments(p: argparse.ArgumentParser, saves: bool = True) -> None:
    """``--map-out PATH`` and ``--no-save``: where the belief map is kept (hearth/executive/mapstore.py).
    ``saves=False`` (hearth record): the map is kept only where --map-out says."""
    if not saves:
        p.add_argument("--map-out", default=None, metavar="PATH",
                       help="keep the belief map in PATH, saved after every change (read "
                            "from PATH when it exists); by default a recording's map is left "
                            "as it was, so that replaying it starts from the same map")
        return
    g = p.add_mutually_exclusive_group()
    g.add_argument("--map-out", default=None, metavar="PATH",
                   help="keep the belief map in PATH instead of the world file: read from PATH "
                        "when it exists (else from --world), saved after every change")
    g.add_argument("--no-save", action="store_true",
                   help="leave the map on disk as it is (by default what the mission learns is "
                        "saved: into the world file, or for the shipped demo home into a copy "
                        "in $HEARTH_STATE_DIR, default ~/.local/share/hearth)")


def keeps_map(args: argparse.Namespace) -> bool:
    """Whether this command keeps the belief map on disk. A replay (``--recording``) and
    ``hearth record`` do only with --map-out: a recording is replayed from the map it was
    made on, so writing what it learned into that map would make the next replay differ."""
    if getattr(args, "no_save", False):
        return False
    if getattr(args, "map_out", None):
        return True
    return getattr(args, "saves_map", True) and not getattr(args, "recording", None)


def belief_file(args: argparse.Namespace) -> Any:
    """The file the belief map is read from (and kept in, see :func:`keeps_map`)."""
    if not keeps_map(args):
        return args.world
    from hearth.executive.mapstore import map_path
    try:
        return map_path(args.world, getattr(args, "map_out", None))
    except FileNotFoundError:
        raise
    except OSError as err:
        where = err.filename or getattr(args, "map_out", None) or args.world
        raise MissionError(f"{where}: cannot keep the map there: {err.strerror or err}") from None


def keep_map(args: argparse.Namespace, world: Any, path: Any) -> Any:
    """A MapKeeper saving ``world`` to ``path`` after every change, or None (not kept)."""
    if not keeps_map(args):
        return None
    from hearth.executive.mapstore import MapKeeper
    return MapKeeper(world, path)


def close_map(keeper: Any, quiet: bool = False) -> None:
    """Write what is pending and say where the map is (a failed save: always, on stderr)."""
    if keeper is None:
        return
    keeper.close()
    if keeper.error:
        print(f"hearth: {keeper.error}", file=sys.stderr)
    elif not quiet and keeper.saves:
        print(f"map saved to {keeper.path}")


def make_world_and_robot(args: argparse.Namespace, clock: Any, path: Any = None,
                         check: Callable[[Any], None] | None = None) -> tuple[Any, Any]:
    """Load the belief map from ``path`` (default: ``args.world``), call ``check(world)``
    (before the robot adapter exists: parameters refuted by the map fail fast), and make the
    robot adapter (robot.create_adapter); one clear MissionError line if either is not
    available."""
    try:
        from hearth.worldmodel.io import load_world
    except ImportError as err:
        raise MissionError(f"cannot load worlds: hearth.worldmodel.io is not available ({err})") from None
    world = load_world(path if path is not None else args.world, clock=clock)
    if check is not None:
        check(world)
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


def drop_stdout() -> None:
    """Whoever read stdout has gone (``hearth log show ... | head``): what is still to be
    printed goes to /dev/null, so neither a later print nor Python's final flush raises."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):   # not a real file (a test's capture)
        pass


class RunPrinter:
    """What `hearth run` prints while a mission runs (an Executive subscriber).

    Concise (the default): the mission's own events (started, halting, how it ended,
    parameter changes, restarts) and each skill's outcome once, with what it said, one line
    each; on a terminal, one progress line (the running skill's latest feedback) rewrites
    itself in place. ``verbose``: every event, in the order it happened within its tick
    (hearth.executive.replay.in_tick_order). Times are clock seconds since the run started; values
    are cut to a readable length (the execution log keeps everything)."""

    def __init__(self, mission: Mission, verbose: bool = False, out: Any = None):
        import shutil
        self.out = out if out is not None else sys.stdout
        self.verbose = verbose
        isatty = getattr(self.out, "isatty", None)
        self.tty = bool(isatty and isatty())
        self.width = max(40, shutil.get_terminal_size((100, 24)).columns - 1)
        self.nodes = {n.path: n for n in mission.nodes()}
        self.t0: float | None = None
        self.tick: int | None = None
        self.pending: list[dict] = []
        self.feedback: dict[str, str] = {}     # path -> the last feedback it reported
        self.progress = ""

    def __call__(self, event: Any) -> None:
        e = event.to_json()
        if e["e"] == "tick":
            return
        if self.t0 is None:
            self.t0 = e.get("t", 0.0)
        if e.get("tick") != self.tick:
            self.flush()
            self.tick = e.get("tick")
        self.pending.append(e)
        if e["e"] == "run" and e.get("state") not in ("running", "halting"):
            self.flush()

    def flush(self) -> None:
        """Print the events of the tick seen so far."""
        events, self.pending = self.pending, []
        if not events:
            return
        if self.verbose:
            from hearth.executive.replay import format_event, in_tick_order
            for e in in_tick_order(events):
                self._line(format_event(e, self.t0 or 0.0))
            return
        progress = None
        for i, e in enumerate(events):
            kind, path = e["e"], e.get("path")
            node = self.nodes.get(path) if path else None
            if kind == "feedback":
                self.feedback[path] = e["message"]
            if kind == "run":
                self._line(self._at(e) + f"mission {e['state']}"
                           + (f": {e['reason']}" if e.get("reason") else ""))
                progress = None
            elif kind == "param":
                from hearth.executive.replay import readable
                self._line(self._at(e) + f"parameter {e['name']} = {readable(e['value'])}")
            elif kind == "restart":
                changed = ", ".join(f"{k} {o} -> {n}" for k, (o, n) in (e.get("changed") or {}).items())
                self._line(self._at(e) + f"restarting {self._label(path)} ({changed})")
            elif kind == "status" and node is not None and node.kind == "skill":
                if e["status"] in ("SUCCESS", "FAILURE") and not e.get("halted"):
                    said = self._said(events, i, path)
                    skill = getattr(node, "skill_name", "") or ""
                    if skill and said.startswith(skill + ": "):
                        said = said[len(skill) + 2:]      # the line names the skill already
                    mark = "ok  " if e["status"] == "SUCCESS" else "FAIL"
                    self._line(self._at(e) + f"{mark} {self._label(path)}"
                               + (f": {said}" if said else ""))
                    if progress is not None and progress.get("path") == path:
                        progress = None
                elif e.get("halted") and e.get("previous") == "RUNNING":
                    self._line(self._at(e) + f"halt {self._label(path)}")
            elif kind == "status" and e.get("status") == "RUNNING":
                pass
            elif kind == "feedback" and node is not None and node.kind == "skill":
                progress = e
        if progress is not None and self.tty:
            self._show_progress(self._at(progress) + f"...  {self._label(progress['path'])}: "
                                + self._text(progress["message"]))

    def close(self) -> None:
        self.flush()
        self._clear_progress()

    # -- helpers --------------------------------------------------------------------------
    def _said(self, events: list[dict], i: int, path: str) -> str:
        """The feedback a skill reported with its outcome (the diff reports a node's status,
        then its feedback), else the last it reported (a feedback is reported when it
        changes)."""
        for e in events[i + 1:]:
            if e.get("path") == path:
                if e["e"] == "feedback":
                    return self._text(e["message"])
                if e["e"] == "status":
                    break
        return self._text(self.feedback.get(path, ""))

    def _label(self, path: str | None) -> str:
        node = self.nodes.get(path or "")
        return node.label if node is not None else (path or "").rsplit("/", 1)[-1]

    def _at(self, e: dict) -> str:
        return f"{e.get('t', 0.0) - (self.t0 or 0.0):8.1f}s  "

    @staticmethod
    def _text(message: Any) -> str:
        from hearth.executive.replay import readable_text
        return readable_text(message)

    def _line(self, text: str) -> None:
        self._clear_progress()
        self._write(text + "\n")

    def _show_progress(self, text: str) -> None:
        self._write("\r\x1b[K" + text[:self.width])
        self.progress = text

    def _clear_progress(self) -> None:
        if self.progress:
            self._write("\r\x1b[K")
            self.progress = ""

    def _write(self, text: str) -> None:
        if self.out is None:
            return
        try:
            self.out.write(text)
            if self.tty:
                self.out.flush()
        except BrokenPipeError:     # `hearth run ... | head`: the mission goes on, unprinted
            self.out = None
            drop_stdout()


def outcome_line(mission: Mission, result: Any) -> str:
    """The last line of `hearth run`: how the mission ended, in how long, and its log."""
    line = (f"{mission.name}: {result.outcome} ({result.reason}) in {result.ticks} ticks, "
            f"{result.duration:.2f} s")
    return line + (f"; log {result.log_path}" if result.log_path else "")


def run_to_end(ex: Any, mission: Mission, params: dict[str, Any], quiet: bool = False,
               verbose: bool = False) -> Any:
    """Submit ``mission`` to a non-background Executive, print its progress unless ``quiet``
    (:class:`RunPrinter`), tick it to the end (Ctrl-C cancels it and lets the robot stop) and
    return its result."""
    printer = None if quiet else RunPrinter(mission, verbose=verbose)
    unsubscribe = ex.subscribe(printer) if printer is not None else None
    try:
        handle = ex.submit(mission, **params)
        try:
            ex.run_until_idle()
        except KeyboardInterrupt:
            handle.cancel("interrupted")
            ex.run_until_idle(100_000)
    finally:
        if printer is not None:
            unsubscribe()
            printer.close()
    return handle.result


def make_executive(args: argparse.Namespace) -> tuple[Mission, dict[str, Any], Any, Any]:
    """The mission, its typed parameters (checked against the map), a non-background
    Executive on the world and robot named by ``add_run_arguments`` options, and the
    MapKeeper that keeps the map on disk (None with --no-save): what `hearth run` and
    `hearth step` share. Close the keeper with :func:`close_map`."""
    from hearth.executive.executive import Executive
    from hearth.executive.missionfile import load_mission

    mission = load_mission(args.mission)
    params = parse_params(mission, args.param)
    clock = make_clock(args)
    path = belief_file(args)
    checked: dict[str, Any] = {}

    def check(world: Any) -> None:        # before the robot adapter is made
        checked.update(mission.resolve_in_map(params, world))

    world, robot = make_world_and_robot(args, clock, path, check=check)
    ex = Executive(world=world, robot=robot, clock=clock, tick_hz=args.tick_hz,
                   runs_dir=args.runs_dir, background=False)
    return mission, checked, ex, keep_map(args, world, path)


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
