"""The `hearth` command line.

Subcommands live in ``executive/commands/<name>.py`` (each has ``register(subparsers)``).
Bad input from the user (a world file, a mission file, a recording, a parameter) is turned
into one line on stderr and exit status 2; no traceback.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from executive import commands as _commands
from executive.errors import MissionError
from perception.errors import PerceptionError
from hearth.robot.errors import RobotError
from skills.errors import SkillError
from worldmodel.errors import WorldError

USER_ERRORS = (WorldError, MissionError, RobotError, PerceptionError, SkillError)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hearth",
        description="Hearth: YAML missions as behaviour trees for home service robots.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(_commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"executive.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        status = args.func(args)
    except USER_ERRORS as err:
        print(str(err), file=sys.stderr)
        return 2
    except FileNotFoundError as err:
        print(f"{err.filename}: no such file", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
