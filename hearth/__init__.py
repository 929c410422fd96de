"""Hearth's one import name: the layers (``hearth.executive``, ``hearth.skills``,
``hearth.perception``, ``hearth.worldmodel``), the robot adapters, mapping, benchmarks and the
command line live beneath it (docs/packaging.md, docs/architecture.md). This module holds the
version and where the shipped data lives. Importing it is cheap: nothing heavy is imported here.
"""
from __future__ import annotations

from pathlib import Path

__version__ = "0.2.0"

_HERE = Path(__file__).resolve().parent


def resource_dir(name: str) -> Path:
    """The shipped folder ``name`` ("missions" or "data").

    ``hearth/missions`` and ``hearth/data`` are symbolic links to the repository's top-level
    folders in a checkout, and real folders inside an installed wheel; the top-level folder
    is the fallback when the link is missing (a copy that dropped links).
    """
    inside = _HERE / name
    if inside.is_dir():
        return inside
    return _HERE.parent / name


def missions_dir() -> Path:
    """The folder of the shipped missions (``missions/`` in a checkout)."""
    return resource_dir("missions")


def demo_world_path() -> Path:
    """The bundled demo home's world file."""
    return resource_dir("data") / "demo_home" / "world.xml"
