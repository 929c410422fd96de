"""CLI start-up: `hearth --help` and `hearth validate WORLD` timed as whole processes.

Each figure is the median wall time of several runs of a fresh process (interpreter start,
imports, the command itself), after one warm-up run that fills the OS file cache and the
``__pycache__`` folders. The `hearth` console script next to this interpreter is run when
there is one (what a user types), else ``python -m hearth``.

Figures: ``help_s_median`` (target 0.3 s), ``validate_world_s_median`` (target 0.6 s) on
``--world`` (default: the shipped demo home), ``import_modules_help`` (how many modules
`hearth --help` loads). Wall times on a shared 2-core machine are inflated by other load;
the ``*_cpu_s_median`` figures (user + system CPU time of the process) are much less so.
"""
from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from hearth import demo_world_path


def add_arguments(parser) -> None:
    parser.add_argument("--runs", type=int, default=None,
                        help="timed runs per command (default 9; 3 with --quick)")
    parser.add_argument("--world", default=None,
                        help="world file to validate (default: the shipped demo home)")


def hearth_command() -> list[str]:
    script = Path(sys.executable).with_name("hearth")
    if script.is_file() and os.access(script, os.X_OK):
        return [str(script)]
    return [sys.executable, "-m", "hearth"]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _time(cmd: list[str], runs: int) -> tuple[list[float], list[float]]:
    """Wall and CPU seconds of ``runs`` runs of ``cmd``."""
    wall, cpu = [], []
    for i in range(runs + 1):
        c0, t0 = _cpu(), time.perf_counter()
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        dt, dc = time.perf_counter() - t0, _cpu() - c0
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} exited {done.returncode}: {done.stderr.strip()}")
        if i:                                  # the first run only warms caches
            wall.append(dt)
            cpu.append(dc)
    return wall, cpu


def _modules_loaded(argv: list[str]) -> int:
    """How many modules a `hearth ARGV` process has imported when it exits."""
    code = ("import sys, contextlib, io\n"
            "from hearth.cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n"
            f"        main({argv!r})\n"
            "    except SystemExit:\n"
            "        pass\n"
            "print(len(sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(out.stdout.strip().splitlines()[-1])


def run(args) -> dict:
    runs = getattr(args, "runs", None) or (3 if args.quick else 9)
    world = str(getattr(args, "world", None) or demo_world_path())
    cmd = hearth_command()
    help_t, help_cpu = _time(cmd + ["--help"], runs)
    validate_t, validate_cpu = _time(cmd + ["validate", world], runs)
    return {
        "command": " ".join(Path(c).name for c in cmd),
        "runs": runs,
        "help_s_median": round(statistics.median(help_t), 3),
        "help_s_min": round(min(help_t), 3),
        "help_cpu_s_median": round(statistics.median(help_cpu), 3),
        "validate_world_s_median": round(statistics.median(validate_t), 3),
        "validate_world_s_min": round(min(validate_t), 3),
        "validate_world_cpu_s_median": round(statistics.median(validate_cpu), 3),
        "import_modules_help": _modules_loaded(["--help"]),
        "import_modules_validate_world": _modules_loaded(["validate", world]),
        "targets": {"help_s_median": 0.3, "validate_world_s_median": 0.6},
    }
