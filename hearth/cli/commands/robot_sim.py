"""`hearth robot-sim [--world W] [--listen ENDPOINT]`: serve Hearth's simulated robot as a live
ROS 2 robot over Zenoh, for `hearth run MISSION --ros2 ENDPOINT` (docs/ros2-foxglove.md).

Serve Hearth's simulated robot as a ROS 2 robot on rmw_zenoh's wire conventions (key
expressions, attachments, liveliness tokens, CDR), so that `hearth run MISSION --ros2
ENDPOINT` (or any ROS 2 node on rmw_zenoh_cpp) drives it: /tf and /tf_static (map -> odom ->
base_link -> camera), colour, depth and camera_info, joint_states, battery_state, Nav2's
NavigateToPose and Hearth's RobotTask actions. By default it is its own Zenoh router on
ENDPOINT (as rmw_zenoh's rmw_zenohd is); --connect joins an existing router instead. It runs
in real time (--rate scales it) with stamps from a fixed epoch (1700000000 s, 2023-11-14) until
Ctrl-C or --duration. Needs the ros extra.
"""
from __future__ import annotations

import sys
import time

from hearth.cli.util import add_command, number_in, seed

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"


def register(sub) -> None:
    p = add_command(sub, "robot-sim", __doc__,
                    help="serve the simulated robot as a live ROS 2 robot over Zenoh")
    home = p.add_mutually_exclusive_group()
    home.add_argument("--world", default=None, metavar="W",
                      help="the home (world file; default: the shipped demo home)")
    home.add_argument("--scenario", default=None, metavar="DIR",
                      help="a simulation scenario (its truth, start pose, localisation error, "
                           "stuck knobs) instead of --world")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--listen", default=None, metavar="ENDPOINT",
                       help=f"be the Zenoh router on ENDPOINT (default {DEFAULT_LISTEN})")
    where.add_argument("--connect", default=None, metavar="ENDPOINT",
                       help="join the Zenoh router at ENDPOINT as a peer (e.g. a running "
                            "rmw_zenohd)")
    p.add_argument("--topics", default=None, metavar="FILE|KEY=VALUE,...",
                   help="the robot's topic and frame names (the mapping of --ros2 and bag "
                        "replay; docs/ros2-foxglove.md)")
    p.add_argument("--domain", type=int, default=None, metavar="N",
                   help="ROS_DOMAIN_ID (default: the environment's, else 0)")
    p.add_argument("--rate", type=number_in(0.1, 50.0, "--rate"), default=1.0,
                   help="simulated seconds per real second (default 1: real time)")
    p.add_argument("--camera-hz", type=number_in(0.2, 30.0, "--camera-hz"), default=5.0,
                   help="RGB-D frames per real second (default 5)")
    p.add_argument("--tf-hz", type=number_in(10.0, 200.0, "--tf-hz"), default=20.0,
                   help="/tf and joint_states messages per simulated second (default 20)")
    p.add_argument("--seed", type=seed, default=0, help="sensor noise seed")
    p.add_argument("--duration", type=number_in(0.0, 1e7, "--duration"), default=0.0,
                   metavar="SECONDS", help="stop after this many seconds (default 0: on Ctrl-C)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.cli.util import DEFAULT_WORLD
    from hearth.robot.zenoh_ros import open_session
    from hearth.robot.zenoh_sim import serve_simulated
    from hearth.worldmodel.io import load_world

    world = None if args.scenario else load_world(args.world or str(DEFAULT_WORLD))
    if args.connect:
        endpoint, mode = args.connect, "peer"
    else:
        endpoint, mode = args.listen or DEFAULT_LISTEN, "router"
    session = open_session(endpoint, mode=mode)
    server = None
    try:
        server = serve_simulated(session, world=world, scenario=args.scenario,
                                 topics=args.topics, rate=args.rate,
                                 camera_rate=args.camera_hz, tf_rate=args.tf_hz,
                                 seed=args.seed, domain=args.domain,
                                 log=lambda text: print(f"robot-sim: {text}", flush=True))
        role = "router on" if mode == "router" else "peer of the router at"
        print(f"robot-sim: a ROS 2 robot on Zenoh ({role} {endpoint}, domain "
              f"{server.node.domain}); run a mission with: hearth run MISSION --ros2 "
              f"{endpoint}" + ("" if args.duration else "; Ctrl-C stops"), flush=True)
        t_end = time.monotonic() + args.duration if args.duration else None
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.2 if t_end is None else max(min(0.2, t_end - time.monotonic()), 0))
    except KeyboardInterrupt:
        pass
    finally:
        if server is not None:
            server.close()
            print(f"robot-sim: stopped after {server.frames_published} frames", file=sys.stderr,
                  flush=True)
        session.close()
    return 0
