"""`hearth record MISSION --scenario S --out PATH [--format hearth|mcap]`: run a mission on the
simulated robot and record every capture for replay with `hearth run --recording PATH`:
a Hearth recording directory (docs/recording-format.md) or a ROS 2 bag in MCAP storage
(docs/ros2-foxglove.md).

Run a mission on the simulated robot (a scenario, or the world itself as truth) with every
RGB-D capture and robot action written to a recording: a Hearth recording directory, or with
--format mcap a ROS 2 bag (rosbag2 directory, MCAP storage) that also carries the mission's
events. With --scenario and no --world, the scenario's belief.xml is the map. The map is left
as it was (a replay starts from it), unless --map-out names where to keep what the mission
learned. Exit 0 when the mission succeeds, 1 when it fails.
"""
from __future__ import annotations

import sys
from pathlib import Path

from hearth.cli.util import (DEFAULT_WORLD, add_command, add_run_arguments, belief_file,
                               close_map, keep_map, make_clock, output_dir, parse_params,
                               run_to_end, seed)


def register(sub) -> None:
    p = add_command(sub, "record", __doc__,
                    help="run a mission in simulation and record its captures")
    add_run_arguments(p, saves=False)
    p.add_argument("--out", type=output_dir, required=True, metavar="PATH",
                   help="recording directory (or bag directory) to write")
    p.add_argument("--format", choices=("hearth", "mcap"), default="hearth",
                   help="hearth: a Hearth recording (default); mcap: a ROS 2 bag in MCAP "
                        "storage (needs the ros extra: pip install 'hearth[ros]')")
    p.add_argument("--seed", type=seed, default=0, help="sensor noise seed")
    p.add_argument("--quiet", action="store_true", help="print only the outcome")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.executive.executive import Executive
    from hearth.executive.missionfile import load_mission
    from hearth import robot
    from hearth.robot.recording import RecordingRobot
    from hearth.worldmodel.io import load_world

    if args.recording:
        raise robot.RobotError("hearth record simulates; replay a recording with "
                               "hearth run --recording")
    if getattr(args, "topics", None):
        raise robot.RobotError("--topics maps a bag being replayed; hearth record writes the "
                               "default topics (docs/ros2-foxglove.md)")
    if args.format == "mcap":
        from hearth.robot.rosbag import require_ros
        require_ros()
    mission = load_mission(args.mission)
    params = parse_params(mission, args.param)
    clock = make_clock(args)
    world_path = Path(args.world)
    if args.scenario and world_path == Path(str(DEFAULT_WORLD)):
        world_path = Path(args.scenario) / "belief.xml"
    args.world = str(world_path)
    path = belief_file(args)          # world_path itself unless --map-out
    world = load_world(path, clock=clock)
    params = mission.resolve_in_map(params, world)
    keeper = keep_map(args, world, path)
    sim = robot.create_adapter(world=world, scenario=args.scenario, clock=clock, seed=args.seed)
    rec = RecordingRobot(sim, args.out, info=dict(mission=str(args.mission), world=str(world_path),
                                                  scenario=args.scenario, params=params,
                                                  seed=args.seed), format=args.format)
    ex = Executive(world=world, robot=rec, clock=clock, tick_hz=args.tick_hz,
                   runs_dir=args.runs_dir, background=False)
    if hasattr(rec.writer, "event"):
        ex.subscribe(rec.writer.event)            # mission events on their own topic
    try:
        result = run_to_end(ex, mission, params, quiet=args.quiet)
    finally:
        rec.close()
        close_map(keeper, quiet=args.quiet)
    n = len(rec.writer)
    print(f"{mission.name}: {result.outcome} ({result.reason}); recorded {n} capture"
          f"{'' if n == 1 else 's'} to {args.out}", file=sys.stderr if args.quiet else sys.stdout)
    return 0 if result.outcome == "succeeded" else 1
