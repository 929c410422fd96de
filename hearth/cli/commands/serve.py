"""`hearth serve`: the command API and the live monitor page (docs/command-layer.md).

Binds to 127.0.0.1 by default. Listening on any other address needs a token
(``--token`` or the HEARTH_TOKEN environment variable); clients send it as
``Authorization: Bearer TOKEN``. Requests whose Host is not the address they came in on (or
localhost, or an ``--allowed-host``) are refused; ``--tls-cert``/``--tls-key`` serve HTTPS.
"""
from __future__ import annotations

import argparse
import os
import sys

from hearth.cli.util import (DEFAULT_WORLD, MAX_TICK_HZ, MIN_TICK_HZ, add_map_arguments,
                               add_topics_argument,
                               belief_file, close_map, close_robot, integer_in, keep_map,
                               make_world_and_robot, number_in, tick_rate)
from hearth.cli.commands.run import add_groot2_arguments, start_groot2
from hearth import missions_dir

DEFAULT_MISSIONS = missions_dir()


def register(sub) -> None:
    p = sub.add_parser("serve", help="serve the command API and the monitor page",
                       description="Start the executive on a simulated, replayed or live "
                                   "(--ros2) robot and "
                                   "serve the command API (OpenAPI at /docs) and the live "
                                   "monitor page at /. Localhost only unless a token is given.")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1; others need --token)")
    p.add_argument("--port", type=integer_in(0, 65535, "the port"), default=8080,
                   help="port (default 8080; 0: any free)")
    p.add_argument("--token", default=os.environ.get("HEARTH_TOKEN"),
                   help="require this bearer token (default: $HEARTH_TOKEN)")
    p.add_argument("--allowed-host", action="append", default=[], metavar="NAME",
                   help="also serve requests whose Host header is NAME, e.g. robot.local "
                        "(repeatable; '*': any, behind a proxy that checks Host). By default "
                        "only the address a request came in on, and localhost on loopback")
    p.add_argument("--tls-cert", default=None, metavar="PEM",
                   help="serve HTTPS with this certificate (chain) file; needs --tls-key")
    p.add_argument("--tls-key", default=None, metavar="PEM",
                   help="the certificate's private key file")
    p.add_argument("--missions", action="append", default=None, metavar="PATH",
                   help="mission file or directory that can be asked for (repeatable; "
                        "default: missions/)")
    p.add_argument("--world", default=str(DEFAULT_WORLD),
                   help="world file: the belief map (default: the shipped demo home); what "
                        "missions learn is saved into it after every change (the demo home: "
                        "into a copy in $HEARTH_STATE_DIR), see --map-out and --no-save")
    p.add_argument("--scenario", default=None, metavar="DIR", help="simulation scenario")
    p.add_argument("--recording", default=None, metavar="PATH",
                   help="recording to replay (a Hearth recording or a ROS 2 bag)")
    add_topics_argument(p)
    p.add_argument("--tick-hz", type=tick_rate, default=10.0,
                   help=f"tick rate (Hz, {MIN_TICK_HZ:g} to {MAX_TICK_HZ:g}; default 10)")
    p.add_argument("--runs-dir", default="runs", help="where execution logs go")
    add_map_arguments(p)
    p.add_argument("--autonomy", type=int, default=3, choices=range(4),
                   help="granted autonomy level: skills above it wait for an operator's "
                        "approval (0 observe, 1 move, 2 act on the home, 3 handle objects; "
                        "default 3: never ask)")
    p.add_argument("--approval-timeout", default=120.0,
                   type=number_in(0, 86_400, "the approval timeout", lo_open=True),
                   help="seconds to wait for an approval before the skill fails")
    p.add_argument("--schedule", default=None, metavar="DAY.yaml",
                   help="run a day: this schedule's missions at their times, the battery "
                        "watch, emergencies first, interrupted missions resumed "
                        "(docs/day.md; /api/day)")
    add_groot2_arguments(p)
    from hearth.cli.util import add_foxglove_arguments
    add_foxglove_arguments(p, wait=False)
    p.set_defaults(func=_serve)


def check_bind(host: str, token: str | None) -> str | None:
    """Why ``host`` may not be used without a token (None: fine)."""
    from hearth.executive.command.server import is_loopback
    if not is_loopback(host) and not token:
        return (f"hearth serve: listening on {host} needs a token (--token or HEARTH_TOKEN); "
                f"without one only loopback addresses (127.0.0.1, ::1, localhost) are allowed")
    return None


def check_tls(cert: str | None, key: str | None) -> str | None:
    """Why the TLS files cannot be used (None: fine, or no TLS asked for)."""
    if cert is None and key is None:
        return None
    if cert is None or key is None:
        return "hearth serve: --tls-cert and --tls-key go together (a certificate and its key)"
    import ssl
    try:
        ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(cert, key)
    except OSError as err:      # ssl.SSLError is an OSError
        what = err.strerror or getattr(err, "reason", None) or str(err)
        where = f" ({err.filename})" if getattr(err, "filename", None) else ""
        return f"hearth serve: cannot use --tls-cert {cert} / --tls-key {key}{where}: {what}"
    return None


def _serve(args: argparse.Namespace) -> int:
    problem = check_bind(args.host, args.token) or check_tls(args.tls_cert, args.tls_key)
    if problem:
        print(problem, file=sys.stderr)
        return 2
    from hearth.executive.command.api import create_app
    from hearth.executive.command.server import bind_socket, make_server, make_service
    from hearth.robot.clock import WallClock

    schedule = None
    if args.schedule:
        from hearth.executive.day import load_schedule
        schedule = load_schedule(args.schedule)      # a bad file: one line, before anything
    clock = WallClock()
    path = belief_file(args)
    world, robot = make_world_and_robot(args, clock, path)
    keeper = keep_map(args, world, path)
    service = make_service(world, robot, args.missions or [str(DEFAULT_MISSIONS)], clock=clock,
                           tick_hz=args.tick_hz, runs_dir=args.runs_dir, granted=args.autonomy,
                           approval_timeout=args.approval_timeout)
    from hearth.executive.foxglove import sink_from_args
    sink = sink_from_args(args, world=world, clock=clock)
    if sink is not None:
        sink.attach(service.executive)     # live while hearth serve runs
    for line in service.catalogue_problems:
        print(f"hearth serve: skipped {line}", file=sys.stderr)
    names = ", ".join(sorted(service.vocabulary.catalogue)) or "none"
    pub = day = runner = None
    try:
        if schedule is not None:
            day, runner = _start_day(args, service, robot, schedule)
        pub = start_groot2(args, service.executive)
        try:
            sock = bind_socket(args.host, args.port)
        except OSError as err:
            print(f"hearth serve: cannot listen on {args.host}:{args.port}: {err.strerror}",
                  file=sys.stderr)
            return 2
        host, port = sock.getsockname()[:2]
        scheme = "https" if args.tls_cert else "http"
        shown = f"[{host}]" if ":" in host else host

        def started() -> None:
            # once uvicorn serves (and its Ctrl-C handler is in place), not before
            print(f"hearth serve: missions {names}; {scheme}://{shown}:{port}/ (API docs at /docs)",
                  file=sys.stderr, flush=True)
            if keeper is not None:
                print(f"hearth serve: the map is kept in {keeper.path}", file=sys.stderr, flush=True)
        app = create_app(service, token=args.token, allowed_hosts=args.allowed_host)
        if day is not None:
            from hearth.executive.command.api import _check_token
            from hearth.executive.command.day_api import day_router
            app.include_router(day_router(day, _check_token(args.token)))
        make_server(app, tls_cert=args.tls_cert, tls_key=args.tls_key,
                    on_started=started).run(sockets=[sock])
    finally:
        if runner is not None:
            runner.close()
        if day is not None:
            day.close()
        if pub is not None:
            pub.close()
        service.executive.shutdown()
        service.close()
        if sink is not None:
            sink.close()
        close_robot(robot)
        close_map(keeper, quiet=True)
    return 0


def _start_day(args: argparse.Namespace, service, robot, schedule):
    """The Day over the service's executive (the catalogue's missions), stepped once a
    second; its events go to the event stream (kind ``day``) and ``RUNS_DIR/day.jsonl``."""
    from pathlib import Path

    from hearth.executive.command.day_api import DayRunner
    from hearth.executive.day import Day
    missions = {n: e.mission for n, e in service.vocabulary.catalogue.items()}
    log = None
    if args.runs_dir:
        Path(args.runs_dir).mkdir(parents=True, exist_ok=True)
        log = Path(args.runs_dir) / "day.jsonl"
    def submit(name, params, priority, source):
        return service.submit(name, params, priority, source=f"day: {source}")[0].handle
    day = Day(service.executive, robot, missions, schedule,
              on_event=lambda e: service.hub.publish("day", e), log_path=log, submit=submit)
    return day, DayRunner(day)
