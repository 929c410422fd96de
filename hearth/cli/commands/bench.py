"""`hearth bench NAME --json`: run a benchmark from ``benchmarks/NAME.py``.

A benchmark module defines ``run(args) -> dict`` and optionally ``add_arguments(parser)``
(its own options, given after the name: ``hearth bench api --clients 10``) and a module
docstring. It prints one JSON object on stdout; progress goes to stderr: a line as each
benchmark starts and ends, and one per case where a benchmark reports cases (its own
``--verbose``, turned on here unless ``--no-progress``). A module may define
``incomplete(result) -> str | None``: a sentence when its figures leave cases out (an engine
that could not deliver them); the command then says so on stderr and exits 1.
"""
from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
import sys
import time

from hearth.cli.util import integer_in, seed
from hearth import benchmarks


def available() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(benchmarks.__path__)
                  if not m.name.startswith("_"))


def _common(p: argparse.ArgumentParser, default=None) -> None:
    def d(value):
        return argparse.SUPPRESS if default is argparse.SUPPRESS else value
    p.add_argument("--json", action="store_true", default=d(False),
                   help="print compact JSON on one line (default: indented)")
    p.add_argument("--seed", type=seed, default=d(0), help="base random seed")
    p.add_argument("--quick", action="store_true", default=d(False),
                   help="fewer repetitions (smoke run)")
    p.add_argument("--scenarios", type=integer_in(1, 100_000, "--scenarios"), default=d(None),
                   help="scenarios per figure, where used")
    p.add_argument("--jobs", type=integer_in(1, 256, "--jobs"), default=d(1),
                   help="parallel worker processes, where used")
    p.add_argument("--no-progress", action="store_true", default=d(False),
                   help="no progress lines on stderr (by default: one as each benchmark starts "
                        "and ends, and one per case where a benchmark reports cases)")


def register(sub) -> None:
    p = sub.add_parser("bench", help="run a speed/accuracy benchmark and print JSON",
                       description="Run a benchmark; prints one JSON object. "
                                   f"Benchmarks: {', '.join(available())}, all. "
                                   "A benchmark's own options follow its name "
                                   "(`hearth bench NAME --help-bench` lists them).")
    p.add_argument("name", help="benchmark name, or 'all'")
    _common(p)
    p.add_argument("extra", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    p.set_defaults(func=_run)


def _own_options(name: str, module, extra: list[str], args: argparse.Namespace) -> None:
    """Parse what follows the name: the common options again, and the benchmark's own."""
    own = argparse.ArgumentParser(prog=f"hearth bench {name}", add_help=False)
    own.add_argument("--help-bench", action="help", help="show this benchmark's options")
    _common(own, default=argparse.SUPPRESS)
    if hasattr(module, "add_arguments"):
        module.add_arguments(own)
    given = {a.split("=")[0] for a in extra if a.startswith("--")}
    for key, value in vars(own.parse_args(extra)).items():
        flag = f"--{key.replace('_', '-')}"
        if flag in given or getattr(args, key, None) is None:
            setattr(args, key, value)


def _progress(args: argparse.Namespace, text: str) -> None:
    if not args.no_progress:
        print(f"hearth bench: {text}", file=sys.stderr, flush=True)


def _run(args: argparse.Namespace) -> int:
    names = available() if args.name == "all" else [args.name]
    out = {}
    failed: list[str] = []    # benchmarks whose figures do not cover every case: exit 1
    for i, name in enumerate(names, 1):
        if name not in available():
            print(f"hearth bench: unknown benchmark {name!r}; known: {', '.join(available())}",
                  file=sys.stderr)
            return 2
        module = importlib.import_module(f"hearth.benchmarks.{name}")
        given_verbose = any(a == "--verbose" for a in args.extra or [])
        _own_options(name, module, list(args.extra or []), args)
        if hasattr(args, "verbose") and not given_verbose:
            # A benchmark with cases reports each on stderr with its own --verbose.
            args.verbose = not args.no_progress
        of = f" ({i}/{len(names)})" if len(names) > 1 else ""
        _progress(args, f"{name}{of} running...")
        t0 = time.perf_counter()
        out[name] = module.run(args)
        _progress(args, f"{name}{of} done in {time.perf_counter() - t0:.1f} s")
        why = module.incomplete(out[name]) if hasattr(module, "incomplete") else None
        if why:
            failed.append(f"{name}: {why}")
    result = out[names[0]] if len(names) == 1 else out
    print(json.dumps(result, indent=None if args.json else 2, sort_keys=True))
    for line in failed:
        print(f"hearth bench: {line}", file=sys.stderr)
    return 1 if failed else 0
