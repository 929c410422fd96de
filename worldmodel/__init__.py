"""The hierarchical semantic map of the home (RAMCIP D3.1 section 3.2).

``load_world(path)`` gives a ``World``: typed nodes, queries, updates with history, and
``save_world`` writes it back atomically. See docs/world-format.md.
"""
from worldmodel.errors import UnknownNode, WorldError, WorldValidationError
from worldmodel.io import load_world, parse_world, save_world, to_xml, validate_file
from worldmodel.nodes import (
    Apartment, DefaultPosition, GraspPoint, Handle, Joint, Knob, KnobState, LargeArticulatedObject,
    LargeObject, Model, ParkingPosition, Part, Room, SmallObject, Surface, Switch, Visual,
)
from worldmodel.pose import Pose
from worldmodel.world import MapChange, Match, World

__all__ = [
    "Apartment", "DefaultPosition", "GraspPoint", "Handle", "Joint", "Knob", "KnobState",
    "LargeArticulatedObject", "LargeObject", "MapChange", "Match", "Model", "ParkingPosition",
    "Part", "Pose", "Room", "SmallObject", "Surface", "Switch", "UnknownNode", "Visual", "World",
    "WorldError", "WorldValidationError", "load_world", "parse_world", "save_world", "to_xml",
    "validate_file",
]
