"""`hearth import TREE.xml [-o MISSION.yaml]`: a BehaviorTree.CPP v4 XML tree as a mission.

Read BehaviorTree.CPP v4 XML (Groot2, Nav2) and write the mission YAML, checked like any
mission. A leaf that is no registered skill, an undeclared port, a node Hearth does not map, an
XML entity or a syntax error is one 'file:line: message' and exit status 2.
"""
from __future__ import annotations

import sys

from hearth.cli.util import add_command

# The module is ``import_`` because ``import`` is a Python keyword; the command is ``import``.


def register(sub) -> None:
    p = add_command(sub, "import", __doc__, help="read a BehaviorTree.CPP v4 XML tree as a mission")
    p.add_argument("tree", metavar="TREE.xml")
    p.add_argument("-o", "--output", metavar="MISSION.yaml", help="write here (default: stdout)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.executive.btcpp import import_tree
    from hearth.worldmodel.io import atomic_write
    text, mission = import_tree(args.tree)
    if args.output:
        atomic_write(args.output, text.encode("utf-8"))
        nodes = sum(1 for _ in mission.nodes())
        print(f"{args.tree}: mission {mission.name} ({nodes} nodes) written to {args.output}",
              file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
