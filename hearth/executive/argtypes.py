"""Command-line argument types that know the executive's vocabulary, shared by ``hearth
suite`` (hearth/cli/commands/suite.py) and ``hearth bench missions``
(hearth/benchmarks/missions.py), which sit on floors above it."""
from __future__ import annotations

import argparse


def suite_missions(text: str) -> tuple[str, ...]:
    """An argparse type: comma-separated missions the scenario suite can make cases for."""
    from hearth.executive.scenarios import SUITE_MISSIONS
    names = tuple(m.strip() for m in text.split(",") if m.strip())
    bad = [m for m in names if m not in SUITE_MISSIONS]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"no scenarios for {', '.join(map(repr, bad)) or 'no mission'}; the suite has "
            f"scenarios for {', '.join(SUITE_MISSIONS)}")
    return names
