"""Mapping a home from a walk-through (docs/mapping.md): `hearth map build REC --out DIR` runs
named stages (hearth/mapping/build.py), each writing its output under DIR; the metric stages
(keyframes and odometry, pose graph, TSDF fusion, the picture) are in hearth/mapping/metric.py
over the pure functions of hearth/perception/mapping.py.

Importing this package is cheap: the stages import open3d when they run.
"""
from __future__ import annotations

from hearth.util.errors import HearthError


class MappingError(HearthError):
    """A recording a map cannot be built from (empty, a dark frame, frames missing), or a
    stage's output that is missing or corrupt; one line naming the file."""

    file_line_optional = True
