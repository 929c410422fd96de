"""`hearth export MISSION.yaml --format btcpp [-o FILE]`: a mission as BehaviorTree.CPP v4 XML."""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("export", help="write a mission as BehaviorTree.CPP v4 XML",
                       description="Check MISSION and write it as BehaviorTree.CPP v4 XML "
                                   "(Groot2, Nav2): one <BehaviorTree> for the mission and one "
                                   "per included subtree, {key} remapping, and a "
                                   "<TreeNodesModel> with the skills' ports. See "
                                   "docs/missions.md, 'From and to BehaviorTree.CPP'.")
    p.add_argument("mission", metavar="MISSION.yaml")
    p.add_argument("--format", default="btcpp", choices=["btcpp"],
                   help="output format (btcpp: BehaviorTree.CPP v4 XML)")
    p.add_argument("-o", "--output", metavar="FILE", help="write here (default: stdout)")
    p.add_argument("--palette", action="store_true",
                   help="model every registered skill, not only those the mission uses "
                        "(a full palette for Groot2)")
    p.set_defaults(func=_run)


def write_atomically(path: str, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder, so a failed
    write never leaves half a file."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent or ".", prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _run(args) -> int:
    from executive.btcpp import export_mission
    xml = export_mission(args.mission, palette=args.palette)
    if args.output:
        write_atomically(args.output, xml)
        print(f"{args.mission}: written to {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(xml)
    return 0
