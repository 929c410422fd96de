"""`hearth tour --world W --out REC`: drive the simulated robot through every room of a home and
record the tour for `hearth map build` (docs/mapping.md).

Drive the simulated robot through every room with free floor: stops on a grid of the free
floor (never inside furniture), a full turn of views at each stop at two head tilts, and back
to a room's first stop before leaving it (so the map's pose graph finds loop closures). The
odometry drifts (--drift-distance, --drift-rotation: standard deviations as fractions of the
distance driven and the angle turned); the believed poses are the recording's, the true ones
its ground truth. Writes a Hearth recording (docs/recording-format.md) or, with --format mcap,
a ROS 2 bag (needs the ros extra).
"""
from __future__ import annotations

import sys

from hearth.cli.util import add_command, integer_in, number_in, output_dir, seed


def register(sub) -> None:
    p = add_command(sub, "tour", __doc__, help="drive through a simulated home and record it "
                                               "for hearth map build")
    p.add_argument("--world", required=True, metavar="W", help="the home (world file) to tour")
    p.add_argument("--out", type=output_dir, required=True, metavar="REC",
                   help="recording directory (or bag directory) to write")
    p.add_argument("--format", choices=("hearth", "mcap"), default="hearth",
                   help="hearth: a Hearth recording (default); mcap: a ROS 2 bag")
    p.add_argument("--seed", type=seed, default=0, help="sensor noise and drift seed")
    p.add_argument("--drift-distance", type=number_in(0.0, 0.5, "--drift-distance"),
                   default=0.015, metavar="F",
                   help="odometry translation error per metre driven (default 0.015: 1.5%%)")
    p.add_argument("--drift-rotation", type=number_in(0.0, 0.5, "--drift-rotation"),
                   default=0.015, metavar="F",
                   help="odometry yaw error per radian turned (default 0.015: 1.5%%)")
    p.add_argument("--stops-per-room", type=integer_in(1, 50, "--stops-per-room"), default=4,
                   help="at most this many stops in a room (default 4)")
    p.add_argument("--width", type=integer_in(80, 1280, "--width"), default=640,
                   help="image width in pixels (4:3; default 640, a Kinect)")
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.robot.tour import OdometryDrift, TourOptions, record_tour
    from hearth.perception.camera import Intrinsics
    from hearth.worldmodel.io import load_world

    if args.format == "mcap":
        from hearth.robot.rosbag import require_ros
        require_ros()
    world = load_world(args.world)
    progress = None if args.quiet else (lambda text: print(f"tour: {text}", flush=True))
    summary = record_tour(
        world, args.out, TourOptions(max_stops_per_room=args.stops_per_room),
        OdometryDrift(args.drift_distance, args.drift_rotation), seed=args.seed,
        format=args.format, intrinsics=Intrinsics.kinect(args.width, args.width * 3 // 4),
        info=dict(world=str(args.world)), progress=progress)
    s = summary.as_dict()
    if s["skipped_rooms"]:
        print(f"tour: no free floor for the robot in {', '.join(s['skipped_rooms'])} "
              "(not toured)", file=sys.stderr)
    print(f"toured {len(s['rooms'])} room{'s' if len(s['rooms']) != 1 else ''} "
          f"({s['stops']} stops, {s['path_m']} m, {s['turned_deg']:.0f} deg turned): "
          f"{s['frames']} frames to {args.out}; odometry drifted {s['final_drift_m']} m and "
          f"{s['final_drift_deg']} deg by the end")
    return 0
