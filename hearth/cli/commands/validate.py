"""`hearth validate FILE...`: check world files (.xml) and mission files (.yaml/.yml).

Check world files (XML, schema and semantics), mission files (YAML, with their utterance
templates as `hearth serve` compiles them) and day schedules (YAML with a top-level 'day:').
Prints nothing and
exits 0 when all are valid; otherwise one 'path:line: message' line per problem (the first 50
of a file, then a line counting the rest) and exit status 2.
"""
from __future__ import annotations

import sys
from pathlib import Path

from hearth.cli.util import add_command


def register(sub) -> None:
    p = add_command(sub, "validate", __doc__, help="check world (.xml) and mission (.yaml) files")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.set_defaults(func=_run)


def problems_in(path: str) -> list[str]:
    suffix = Path(path).suffix.lower()
    if not Path(path).exists():
        return [f"{path}:0: no such file"]
    if suffix in (".yaml", ".yml"):
        from hearth.executive.day import is_schedule_file, schedule_problems
        if is_schedule_file(path):          # a day's schedule (docs/day.md)
            return schedule_problems(path)
        from hearth.executive.missionfile import validate_file as validate_mission
        problems = [str(e) for e in validate_mission(path)]
        if problems:
            return problems
        # The utterance templates too, as `hearth serve` compiles them (bounded, slots that
        # are parameters): a file that validates is one the server takes.
        from hearth.executive.command.vocabulary import read_templates
        from hearth.executive.errors import MissionError
        from hearth.executive.missionfile import LineDict, load_mission, load_yaml
        if not isinstance(load_yaml(path), LineDict) or "tree" not in load_yaml(path):
            return []       # a library of subtrees: no utterances of its own
        try:
            read_templates(load_mission(path), path)
        except MissionError as err:
            return [str(err)]
        return []
    from hearth.worldmodel.io import validate_file as validate_world
    return [str(e) for e in validate_world(path)]


def _run(args) -> int:
    from hearth.util.errors import problem_lines

    bad = False
    for path in args.files:
        problems = problems_in(path)
        if problems:
            print(problem_lines(problems), file=sys.stderr)
            bad = True
    return 2 if bad else 0
