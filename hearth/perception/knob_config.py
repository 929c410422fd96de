"""The knob reader's configuration (``KnobConfig``): what its templates are made with and, declared
``read_time``, what changes only how it reads. The method is described in
hearth/perception/knobs.py."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from hearth.perception.trained import read_time, trained_fields


@dataclass(frozen=True)
class KnobConfig:
    """Trained (part of the stored templates): ``px_per_radius`` (coarse canvas pixels per
    knob radius), ``window_radii`` (the template window's half width, in knob radii),
    ``alpha_step_deg`` / ``theta_step_deg`` / ``max_theta_deg`` (template angle steps and the
    most off-axis bin). Read time: ``fine_px_per_radius`` (the exact check's scale),
    ``search_m`` / ``search_radii`` (how far from where the map puts it the knob is looked
    for: the larger of the two), ``offset_sigma_m`` (the registration error the offset prior
    assumes), ``fine_shift_px`` (offsets tried in the exact check), ``min_radius_px`` (a
    knob smaller in the image is not read), ``max_off_axis_deg``, ``max_snap`` (the angle
    must lie within this share of half a state step of its state), ``off_margin_factor``
    (an "off" reading needs this many times the calibrated margin; one over the margin but
    under this passes every other check gets evidence ``off_one_view``: two of them from
    places apart make the knob off, ``OffViews``), ``off_rival_min`` (an "off" reading must
    explain the pixels where off and the best "on" candidate differ better than that by this
    much: evidence ``off_rival``, not calibrated), ``min_confidence`` (a
    reading less confident than this is "unknown"), ``threshold`` /
    ``margin_threshold`` (override the calibrated gates; None: the fitted ones).
    A knob whose body is round about its axis (``round_body_levels``) with a marker off the
    axis no larger than ``dot_max_size`` of its distance from it: ``round_body_center``
    (its centre from the depth of its rims, ``body_center``), ``dot_angle`` (its angle from
    the marker's colour, ``KnobReader._dot_reading``, with ``dot_noise_floor`` (grey
    levels), ``dot_center_px`` and ``dot_blob_px`` (the expected errors of the centre and of
    the marker, image pixels, the marker's over its contrast to noise) and
    ``dot_dominance_power`` for its margin); such a reading seen more than
    ``dot_max_off_axis_deg`` off the knob's axis gives no state. ``min_relief``: with depth,
    a knob is found only where the depth shows at least this share of its rendered relief
    (evidence ``stands``, ``depth_slope``) within ``relief_sigmas`` standard errors of the
    slope (``stands_se``: what the depth can show of the described relief; a flat knob's is
    wide), and ``max_offset_searches``: only within this
    many search radii of where the map puts it (evidence ``offset``), whatever its fit
    (``not_there``)."""
    px_per_radius: float = 8.0
    window_radii: float = 1.25
    alpha_step_deg: float = 5.0
    theta_step_deg: float = 5.0
    max_theta_deg: float = 70.0
    fine_px_per_radius: float = read_time(12.0)
    search_m: float = read_time(0.014)
    search_radii: float = read_time(0.6)
    offset_sigma_m: float = read_time(0.008)
    offset_weight: float = read_time(0.05)
    align_iterations: int = read_time(5)
    angle_stages: int = read_time(2)
    candidates: int = read_time(3)
    decimate_above_px: float = read_time(16.0)
    min_radius_px: float = read_time(4.0)
    max_off_axis_deg: float = read_time(70.0)
    max_snap: float = read_time(0.7)
    off_margin_factor: float = read_time(1.5)
    min_confidence: float = read_time(0.0)
    angle_span_steps: int = read_time(2)
    fine_ridge_px: float = read_time(0.0)
    depth_weight: float = read_time(1.0)
    depth_settle_radii: float = read_time(0.03)
    round_body_center: bool = read_time(True)
    min_relief: float = read_time(0.45)
    relief_sigmas: float = read_time(2.0)
    off_rival_min: float = read_time(0.1)
    max_offset_searches: float = read_time(1.5)
    dot_angle: bool = read_time(True)
    dot_noise_floor: float = read_time(2.0)
    dot_max_size: float = read_time(0.6)
    dot_center_px: float = read_time(0.25)
    dot_blob_px: float = read_time(1.0)
    dot_dominance_power: float = read_time(3.0)
    dot_max_off_axis_deg: float = read_time(60.0)
    threshold: Optional[float] = read_time(None)
    margin_threshold: Optional[float] = read_time(None)

    def trained_fields(self) -> dict:
        """The fields the templates are made with (the others, declared ``read_time``,
        change how a reader reads and need no refitting)."""
        return trained_fields(self)


#: Stored readers (joblib files, hearth/worldmodel/model_store.py) name their classes by module:
#: these keep the module they were stored under before the reader was split into modules
#: (hearth.perception.knobs, which still exports them), so a stored model reads alike with this
#: code and earlier code, and neither makes the other retrain.
for _cls in (KnobConfig,):
    _cls.__module__ = "hearth.perception.knobs"
