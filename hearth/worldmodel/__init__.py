"""The hierarchical semantic map of the home (RAMCIP D3.1 section 3.2).

``load_world(path)`` gives a ``World``: typed nodes, queries, updates with history, and
``save_world`` writes it back atomically. See docs/world-format.md.

The names below are re-exported lazily (PEP 562 module ``__getattr__``): importing
``hearth.worldmodel.errors`` or any one module does not load the whole package.
"""
from __future__ import annotations

import importlib

_EXPORTS = {
    "hearth.worldmodel.errors": ("UnknownNode", "WorldError", "WorldValidationError"),
    "hearth.worldmodel.io": ("load_world", "parse_world", "save_world", "to_xml", "validate_file"),
    "hearth.worldmodel.nodes": (
        "Apartment", "Charger", "DefaultPosition", "Doorway", "GraspPoint", "Handle", "Joint", "Knob", "KnobState",
        "LargeArticulatedObject", "LargeObject", "Model", "ParkingPosition", "Part", "Room",
        "SmallObject", "Surface", "Switch", "Visual",
    ),
    "hearth.worldmodel.pose": ("Pose",),
    "hearth.worldmodel.world": ("MapChange", "Match", "World"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(_WHERE)


# The modules that importing the package used to load, still reachable as attributes.
_SUBMODULES = ("errors", "io", "nodes", "pose", "validate", "world")


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f"hearth.worldmodel.{name}")
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'hearth.worldmodel' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value          # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
