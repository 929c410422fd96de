"""`hearth bench NAME --json`: run a benchmark from ``benchmarks/NAME.py``.

A benchmark module defines ``run(args) -> dict`` and optionally ``add_arguments(parser)``
and a module docstring (shown in the help). It prints one JSON object.
"""
from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
import sys

import benchmarks


def available() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(benchmarks.__path__)
                  if not m.name.startswith("_"))


def register(sub) -> None:
    p = sub.add_parser("bench", help="run a speed/accuracy benchmark and print JSON",
                       description="Run a benchmark; prints one JSON object. "
                                   f"Benchmarks: {', '.join(available())}, all.")
    p.add_argument("name", help="benchmark name, or 'all'")
    p.add_argument("--json", action="store_true", help="print JSON only (the default output)")
    p.add_argument("--seed", type=int, default=0, help="base random seed")
    p.add_argument("--quick", action="store_true", help="fewer repetitions (smoke run)")
    p.add_argument("--scenarios", type=int, default=None, help="scenarios per figure, where used")
    p.add_argument("--jobs", type=int, default=1, help="parallel worker processes, where used")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    names = available() if args.name == "all" else [args.name]
    out = {}
    for name in names:
        if name not in available():
            print(f"hearth bench: unknown benchmark {name!r}; known: {', '.join(available())}",
                  file=sys.stderr)
            return 2
        module = importlib.import_module(f"benchmarks.{name}")
        out[name] = module.run(args)
    result = out[names[0]] if len(names) == 1 else out
    print(json.dumps(result, indent=None if args.json else 2, sort_keys=True))
    return 0
