"""The `hearth` command line.

Subcommands live in ``hearth/cli/commands/<name>.py`` (each has ``register(subparsers)``;
``cliutil.add_command`` gives it a parser whose ``--help`` description is the module's
docstring past its first paragraph, the synopsis).
Bad input from the user (a world file, a mission file, a recording, a parameter) is turned
into one line on stderr and exit status 2; no traceback.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from hearth.cli import commands as _commands
from hearth.util.errors import HearthError

# Every package's error family (WorldError, MissionError, RobotError, PerceptionError,
# SkillError) subclasses HearthError. Only this light module is imported here, and each
# command module imports its machinery when it runs, so `hearth --help` starts at once.
USER_ERRORS = (HearthError,)


def build_parser() -> argparse.ArgumentParser:
    from hearth import __version__
    parser = argparse.ArgumentParser(
        prog="hearth",
        description="Hearth: YAML missions as behaviour trees for home service robots.",
    )
    parser.add_argument("--version", action="version", version=f"hearth {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(_commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"hearth.cli.commands.{info.name}")
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
    except BrokenPipeError:
        # The reader of stdout has gone (`hearth log show RUN | head`): stop quietly, as a
        # command killed by SIGPIPE would (status 128 + 13).
        from hearth.cli.util import drop_stdout
        drop_stdout()
        return 141
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
