"""`hearth log show RUN.jsonl`: print a run's timeline; `hearth log replay RUN.jsonl`.

Execution logs: show a run's timeline, or replay it offline against the logged skill results.
"""
from __future__ import annotations

from hearth.cli.util import add_command


def register(sub) -> None:
    p = add_command(sub, "log", __doc__, help="read execution logs (runs/*.jsonl)")
    lsub = p.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    s = lsub.add_parser("show", help="print a run's timeline",
                        description="Print a run's events, in the order they happened within "
                                    "each tick, with clock seconds since the run started and "
                                    "values cut to a readable length (the log keeps them whole).")
    s.add_argument("log")
    s.add_argument("--kinds", default=None,
                   help="comma-separated event kinds to show (e.g. status,run)")
    s.set_defaults(func=_show)
    r = lsub.add_parser("replay", help="re-run the mission against the logged results and "
                                       "check the timeline is the same")
    r.add_argument("log")
    r.set_defaults(func=_replay)


def _show(args) -> int:
    from hearth.executive.replay import format_event, in_tick_order, read_log

    header, events, end = read_log(args.log)
    kinds = set(args.kinds.split(",")) if args.kinds else None
    t0 = float(header.get("t", 0.0))       # times since the run started (a wall clock's too)
    print(format_event(header, t0))
    for e in in_tick_order(events):
        if kinds is None or e["e"] in kinds:
            print(format_event(e, t0))
    if end is not None:
        print(format_event(end, t0))
    else:
        print("(no end line: the run was interrupted)")
    return 0


def _replay(args) -> int:
    from hearth.executive.replay import replay

    report = replay(args.log)
    if report.same:
        print(f"replay matches: {len(report.original)} status changes, outcome "
              f"{report.replayed_outcome}")
        return 0
    print(f"replay differs: {report.first_difference()}")
    return 1
