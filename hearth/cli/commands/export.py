"""`hearth export MISSION.yaml --format btcpp [-o FILE] [--nodes-header FILE.hpp]`: a mission
as BehaviorTree.CPP v4 XML.

Check MISSION and write it as BehaviorTree.CPP v4 XML (Groot2, Nav2): one <BehaviorTree> for
the mission and one per included subtree, {key} remapping, and a <TreeNodesModel> with the
skills' ports. See docs/missions.md, 'From and to BehaviorTree.CPP'.
"""
from __future__ import annotations

import sys

from hearth.cli.util import add_command


def register(sub) -> None:
    p = add_command(sub, "export", __doc__, help="write a mission as BehaviorTree.CPP v4 XML")
    p.add_argument("mission", metavar="MISSION.yaml")
    p.add_argument("--format", default="btcpp", choices=["btcpp"],
                   help="output format (btcpp: BehaviorTree.CPP v4 XML)")
    p.add_argument("-o", "--output", metavar="FILE", help="write here (default: stdout)")
    p.add_argument("--nodes-header", metavar="FILE",
                   help="also write the C++ header with Hearth's node types for "
                        "BehaviorTree.CPP (hearth::registerNodes), so the exported mission "
                        "runs there as it is")
    p.add_argument("--palette", action="store_true",
                   help="model every registered skill, not only those the mission uses "
                        "(a full palette for Groot2)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from hearth.executive.btcpp import export_mission
    from hearth.worldmodel.io import atomic_write
    xml = export_mission(args.mission, palette=args.palette)
    if args.output:
        atomic_write(args.output, xml.encode("utf-8"))
        print(f"{args.mission}: written to {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(xml)
    if args.nodes_header:
        from hearth.executive.btcpp import nodes_header
        atomic_write(args.nodes_header, nodes_header().encode("utf-8"))
        print(f"Hearth's node types for BehaviorTree.CPP: written to {args.nodes_header}",
              file=sys.stderr)
    return 0
