"""`hearth test-mission MISSION --substitute FILE`: run a scripted case, report coverage."""
from __future__ import annotations


def register(sub) -> None:
    from hearth.cli.util import mission_file

    p = sub.add_parser("test-mission", help="run a mission with scripted skills; report "
                                            "outcome and never-ticked nodes",
                       description="Run MISSION on a simulated clock with skills replaced by "
                                   "the scripted stand-ins of FILE (see docs/missions.md). "
                                   "Exit 0 when the outcome is the expected one (or none is "
                                   "expected), 1 otherwise.")
    p.add_argument("mission", type=mission_file,
                   help="mission file, or the name of a shipped mission (go_to_rest)")
    p.add_argument("--substitute", required=True, metavar="FILE", help="substitution file")
    p.add_argument("--runs-dir", default=None, help="write the execution log here")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.executive.testing import load_mission_case, run_mission_case

    case = load_mission_case(args.substitute)
    report = run_mission_case(args.mission, case, runs_dir=args.runs_dir)
    print(f"outcome: {report.outcome} ({report.reason}) after {report.ticks} ticks, "
          f"{report.duration:.2f} s simulated")
    covered = len(report.nodes) - len(report.never_ticked)
    print(f"coverage: {covered}/{len(report.nodes)} nodes ticked")
    for path in report.never_ticked:
        print(f"  never ticked: {path}")
    if report.unscripted:
        print(f"not scripted (default {'real skill' if case.default is None else case.default.outcomes[0]}): "
              + ", ".join(report.unscripted))
    if report.log_path:
        print(f"log: {report.log_path}")
    if not report.passed:
        print(f"FAILED: expected {report.expected}, got {report.outcome}")
        return 1
    return 0
