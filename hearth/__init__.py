"""Hearth's own namespace: the packages we added to the specified layout (``hearth.robot``,
``hearth.benchmarks``), the version, and where the shipped data lives.

``robot`` and ``benchmarks`` are too generic to install as top-level packages (``robot`` is
Robot Framework's import name), so they live here. The specified top-level packages
(``executive``, ``skills``, ``perception``, ``worldmodel``) keep their names. Importing this
package is cheap: nothing heavy is imported here.
"""
from __future__ import annotations

from pathlib import Path

__version__ = "0.2.0"

_HERE = Path(__file__).resolve().parent


def resource_dir(name: str) -> Path:
    """The shipped folder ``name`` ("missions" or "data").

    A wheel carries them inside this package (``hearth/missions``, ``hearth/data``, see
    pyproject.toml); in a source checkout or an editable install they are the top-level
    folders of the repository.
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
