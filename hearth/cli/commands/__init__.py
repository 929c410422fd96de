"""`hearth` subcommands, one module each.

Every module here defines ``register(subparsers)``, which adds its parser(s) and sets
``func`` (called with the parsed ``args``; returns the exit status). The CLI discovers the
modules, so adding a subcommand never touches ``hearth/cli/main.py``.
"""
