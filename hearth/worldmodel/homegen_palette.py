"""Colours, materials and words of generated homes: furniture woods and paints, small-object
colours by name (``COLOURS``, ``CLOSE_HUES``), knob colour designs and the names an off state
goes by."""
from __future__ import annotations


# -- colours, materials and words ---------------------------------------------------------------

WOODS = [(0.55, 0.38, 0.22), (0.45, 0.3, 0.2), (0.72, 0.58, 0.4), (0.33, 0.22, 0.14),
         (0.82, 0.7, 0.52)]
PAINTS = [(0.92, 0.92, 0.9), (0.85, 0.86, 0.88), (0.93, 0.89, 0.78), (0.55, 0.62, 0.66),
          (0.3, 0.36, 0.42), (0.64, 0.7, 0.58)]
STEEL = (0.72, 0.73, 0.75)
WHITE = (0.93, 0.93, 0.92)
DARK = (0.12, 0.12, 0.13)
BLACK = (0.06, 0.06, 0.07)

#: Small-object colours by name. Pairs close in hue have different words, so "blue cup" and
#: "navy cup" are both unambiguous.
COLOURS = {
    "red": (0.8, 0.1, 0.1), "crimson": (0.62, 0.05, 0.16), "orange": (0.95, 0.5, 0.1),
    "amber": (0.9, 0.64, 0.1), "yellow": (0.95, 0.85, 0.2), "green": (0.15, 0.6, 0.2),
    "olive": (0.45, 0.52, 0.14), "teal": (0.05, 0.5, 0.5), "blue": (0.1, 0.25, 0.8),
    "navy": (0.08, 0.12, 0.45), "purple": (0.5, 0.2, 0.65), "pink": (0.95, 0.55, 0.7),
    "white": (0.95, 0.95, 0.95), "black": (0.1, 0.1, 0.1), "grey": (0.5, 0.5, 0.52),
    "brown": (0.45, 0.28, 0.15),
}
CLOSE_HUES = [("blue", "navy"), ("red", "crimson"), ("orange", "amber"), ("green", "olive"),
              ("blue", "teal")]

#: Knob designs: body colour, marker colour, radius range, depth range.
KNOB_DESIGNS = [
    ("white", (0.9, 0.9, 0.88), (0.05, 0.05, 0.05), (0.018, 0.026), (0.018, 0.026)),
    ("black", (0.08, 0.08, 0.09), (0.92, 0.92, 0.9), (0.017, 0.024), (0.015, 0.024)),
    ("steel", (0.74, 0.75, 0.77), (0.05, 0.05, 0.05), (0.022, 0.03), (0.02, 0.032)),
    ("cream", (0.93, 0.88, 0.75), (0.35, 0.2, 0.1), (0.013, 0.018), (0.012, 0.02)),
    ("red marker", (0.15, 0.15, 0.16), (0.85, 0.1, 0.1), (0.02, 0.028), (0.02, 0.03)),
]
OFF_NAMES = ["off", "0", "aus", "OFF", "min", "Off", "O", "stop", "standby", "zero", "Aus"]
