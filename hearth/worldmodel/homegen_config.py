"""What the home generator draws from: ``HomeConfig`` (ranges, probabilities, the robot that
must see and reach) and ``HomeGenError`` for a setting it cannot use."""
from __future__ import annotations

import math
from dataclasses import dataclass

from hearth.worldmodel.errors import WorldError


class HomeGenError(WorldError):
    """A configuration the generator cannot use (one line naming the setting)."""


# -- configuration ------------------------------------------------------------------------------

@dataclass(frozen=True)
class HomeConfig:
    """Ranges the generator draws from (metres, radians, counts as (min, max) inclusive).

    The camera and reach values describe the robot that must see and reach the furniture from
    its parking positions; they match hearth/robot/sim.py ``HeadMount`` and the simulated
    robot's reach (a test checks they agree)."""
    rooms: tuple[int, int] = (2, 5)
    turned_room_probability: float = 0.5        #: the home turned by any angle, else by a multiple of 90 deg
    room_gap: float = 0.3                       #: between rooms' floors (walls are 0.1 thick)
    l_shaped_probability: float = 0.35          #: a room (3.2 m or more each way) with a corner cut out
    corridor_probability: float = 0.35          #: a room reached through a corridor, not a doorway of its own
    corridor_width: tuple[float, float] = (1.3, 1.7)
    corridor_length: tuple[float, float] = (2.5, 6.0)
    door_width: tuple[float, float] = (0.85, 1.0)    #: doorways (the robot is 0.6 m across)
    table_height: tuple[float, float] = (0.4, 1.1)
    round_table_probability: float = 0.35
    mesh_probability: float = 0.35              #: furniture parts drawn as PLY meshes
    free_standing_probability: float = 0.2      #: shelves, cupboards, drawers away from walls
    tall_cupboard_probability: float = 0.3
    wall_cabinet_probability: float = 0.3
    two_door_probability: float = 0.5
    drawers: tuple[int, int] = (1, 4)
    shelf_levels: tuple[int, int] = (2, 6)
    knobs_per_appliance: tuple[int, int] = (2, 6)
    max_knobs: int = 8                          #: per home (knob models train per home)
    knob_states: tuple[int, int] = (2, 12)
    flush_front_probability: float = 0.5
    top_knobs_probability: float = 0.5          #: a hob's knobs on its top, not its front
    second_appliance_probability: float = 0.35
    knob_on_probability: float = 0.1            #: a knob left on in the map
    plain_knob_probability: float = 0.1         #: a row of format-1 plain knobs (else the design space)
    off_mid_travel_probability: float = 0.2     #: a knob whose off lies between its settings
    low_panel_probability: float = 0.2          #: an oven's knob panel below its door
    raised_oven_probability: float = 0.25       #: an oven raised on a cabinet (knobs up to 1.4 m)
    small_objects: tuple[int, int] = (7, 14)
    close_hue_probability: float = 0.6          #: a pair of objects close in hue (blue, navy)
    under_table_probability: float = 0.4
    front_turn_probability: float = 0.25        #: object turned inside its own frame
    robot_radius: float = 0.3
    parking_distance: tuple[float, float] = (0.6, 0.9)   #: robot centre to the front face
    camera_height: float = 1.30
    camera_ahead: float = 0.15                  #: camera ahead of the base centre
    tilt_limits: tuple[float, float] = (-math.radians(45), math.radians(75))
    min_range: float = 0.45                     #: depth sensor
    reach: float = 1.45                         #: base centre to a handle, knob or surface
    max_object_height: float = 1.25             #: small objects only on surfaces up to here
    placement_tries: int = 40

    def check(self) -> None:
        """HomeGenError naming the first setting out of range."""
        for name in ("rooms", "table_height", "drawers", "shelf_levels", "knobs_per_appliance",
                     "knob_states", "small_objects", "parking_distance", "corridor_width",
                     "corridor_length", "door_width"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise HomeGenError(f"home config: {name} must be (min, max) with min <= max, "
                                   f"not {(lo, hi)}")
        if not 1 <= self.rooms[0] <= self.rooms[1] <= 6:
            raise HomeGenError(f"home config: rooms must be within 1..6, not {self.rooms}")
        if self.door_width[0] < 2 * self.robot_radius + 0.2:
            raise HomeGenError(f"home config: door_width must leave the robot (radius "
                               f"{self.robot_radius} m) 0.1 m each side, not {self.door_width}")
        if self.corridor_width[0] < self.door_width[1] + 0.3:
            raise HomeGenError(f"home config: corridor_width must be at least the widest door "
                               f"and 0.3 m, not {self.corridor_width}")
        if self.knob_states[0] < 2 or self.knob_states[1] > 12:
            raise HomeGenError(f"home config: knob_states must be within 2..12, not "
                               f"{self.knob_states}")
        if self.knobs_per_appliance[0] < 1 or self.max_knobs < self.knobs_per_appliance[0]:
            raise HomeGenError("home config: max_knobs must be at least knobs_per_appliance[0] "
                               "(every kitchen has an appliance with knobs)")
        if not (0.35 <= self.table_height[0] and self.table_height[1] <= 1.15):
            raise HomeGenError(f"home config: table_height must be within 0.35..1.15 m (the "
                               f"camera must see the top), not {self.table_height}")
        for name, v in self.__dict__.items():
            if name.endswith("_probability") and not 0.0 <= v <= 1.0:
                raise HomeGenError(f"home config: {name} must be within 0..1, not {v}")


