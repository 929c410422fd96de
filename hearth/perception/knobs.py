"""Knob reading by analysis by synthesis: each knob is rendered as the map describes it, at each
angle it could stand at, from where the camera is, and compared with the image.

RAMCIP D3.1 (5.2.1.2 to 5.2.1.4) detects knobs with HOG + SVM and reads their angle with
models trained on pictures of one knob design; such models read the design they were
trained on and little else. Here nothing is learned about a knob's look: the map gives its
shape (``hearth.worldmodel.nodes.Knob``: base, grip, marker, symmetry; ``knob_shape``), and the
reader asks which angle of that shape explains the pixels around the knob best.

**Rectification.** The region around a knob is warped by a homography of its front-face
plane (the plane z = ``KnobShape.face`` of its frame, from the map's registered or believed
pose) into a *canvas* that shows the plane head-on at a fixed scale (pixels per knob radius),
turned about the knob's axis so that the camera always lies towards canvas-up
(``KnobPrior.canvas_frame``). Seen from a camera centre C, a canvas is the central
projection of the knob onto that plane from C; turning the knob by ``a`` is turning C by
``-a`` about the axis, so in the turned canvas the knob at angle ``a`` looks like the knob at
``a - psi`` seen from the canvas's up side, whatever the azimuth of the view. What it looks
like then depends on that relative angle and on how far off-axis the camera is (theta) only.

**Templates** (``KnobTemplates``, fitted per home from the map's knob shapes: rendering, no
learning): for every shape, off-axis angle (``theta_step_deg`` bins) and relative angle
(``alpha_step_deg`` steps over 360/symmetry degrees), a *label map* of the canvas: which
visual of the knob, and which way its surface faces (front, or a side facing up, left, down
or right in the canvas), each pixel shows, or the background. Rays are parallel (the knob is
small against its distance); the final check renders the exact perspective.

**Scoring.** A label map says which pixels should look alike: the pixels of one label are
one surface under one light. How well an image fits a label map is the share of its colour
variance that the labels explain, R^2 = between-label variance / total variance over the
window, in RGB (so a red tip on a black grip, equal in grey, still tells the angle). It is
blind to gain, offset and the actual colours, so it holds under other lighting, cameras and
renderers, and needs no rendering of colour at all; the colours of the map are not trusted.

**Depth.** Given the registered depth image, the reader also compares the knob's height
above its face plane, as the templates (``ShapeTemplates.heights``) and the exact renderings
give it, with the measured depth (``canvas_heights``; squared correlation, so blind to the
believed plane's height and the depth scale), and adds that fit to the colour's: the knob's
body stands out of its panel whatever its colours, so depth says where a knob without colour
contrast is (its marker alone fits as well flipped by half a turn a radius away), and which
way a protruding grip lies. The centre is then taken from the depth, each candidate angle at
the centre the depth gives the shape at that angle.

**Round bodies** (``round_body_levels``: every visual but the marker a cylinder or disc on
the axis, such as a skirt with a cap, and a marker off the axis no wider than
``dot_max_size`` of its distance from it, ``marker_dot``): the body says nothing of the
angle and, in its panel's colour, only depth says where it is, while a centre a millimetre
off turns a dot 6-11 mm from the axis by 5-9 degrees. So the centre comes from the depth of
the top's rim at the image's own pixels (``body_center``: the measured and the rendered
masks of the top, centroid against centroid) and the angle from the dot's
colour about that centre (``dot_profile``, ``KnobReader._dot_reading``), with a margin in
units of the angle's expected error and state gates of its own (``dot_gates``).

**Reading a knob** (``KnobReader.read``): (1) the canvas at the coarse scale; (2) where the
knob is: the labels averaged over every angle (what the knob looks like whatever its angle)
are fitted at every offset within ``search_m`` of where the map puts it (a soft-label
regression, by correlation), with a Gaussian prior on the offset (the registration error);
(3) the coarse angle: every template of the off-axis bin at that offset and its neighbours;
(4) the best angle and the best angle of the best *other* state are rendered exactly (the
real camera centre, perspective, fixed parts in place) at three angles each, at the fine
scale, scored over small offsets; a parabola through the three gives the angle; (5) the
state: the nearest state to the angle (modulo the symmetry), given only when the fit is
good enough (``detect_gate``: a knob is there), the margin over the best other state is
wide enough (``state_gate`` / ``state_gate_hard`` / ``state_gate_very_hard`` by
``view_level``, calibrated on rendered validation views so that no wrong reading passed
it; an "off" reading needs more; a reading without depth has gates of its own,
``colour_gates``), and the angle lies well inside the state's
half step. Otherwise "unknown", with the reason.

**Half turns.** A knob without symmetry looks much like itself turned by half a turn (the
grip of a pointer or tip mostly coincides), so over the whole window the two fit nearly
alike. The reading is also compared with the exact check nearest its half turn only where
the two renderings differ (``KnobReader._half_turn``), and needs that comparison above a
gate calibrated like the state gate (``half_turn_gates``).

Everything here is pure: images and poses in, readings out. Estimators have the scikit-learn
shape (the constructor stores parameters, ``fit`` returns self, learned attributes end in
``_``, every other method starts with ``check_is_fitted``). Training is
hearth/perception/knob_training.py; storing the models is hearth/worldmodel/model_store.py, asked by
hearth/skills/knob_models.py.

Frames: ``T_world_camera`` maps camera points (OpenCV axes) to the world; a knob's
``T_world_knob`` is its frame at angle 0 (+z out of the panel, angles counter-clockwise about
+z); angles are radians in (-pi, pi].

**Where it lives.** This module is the method's description and the names callers import;
the code is split by job: ``knob_config`` (``KnobConfig``), ``knob_shapes`` (``KnobShape``,
``knob_shape``, ray casting), ``knob_templates`` (``ShapeTemplates``, ``KnobTemplates``),
``knob_priors`` (``KnobPrior``, ``knob_priors``, ``standing_profile``, ``near_round``),
``knob_canvas`` (rectification, heights above a face plane), ``knob_scoring`` (colour, depth
and label fits), ``knob_gates`` (``CalibratedThreshold``, ``view_level``, ``not_there``, the
travel's allowed angles), ``knob_window`` (the exact check's window fit), ``knob_round_bodies``
(``body_center``, ``dot_profile``) and ``knob_reading`` (``KnobReader``, ``KnobReading``,
``snap_to_state``, ``OffViews``), all under hearth/perception/; the panel's shift is
``knob_panel``, the training data ``knob_data`` and the fitting ``knob_training``.
"""

from __future__ import annotations

from hearth.perception.knob_config import (  # noqa: F401
    KnobConfig,
)
from hearth.perception.knob_shapes import (  # noqa: F401
    N_FACE, FINE_AZIMUTHS, N_FACE_FINE, KnobShape, knob_shape,
)
from hearth.perception.knob_templates import (  # noqa: F401
    ShapeTemplates, KnobTemplates,
)
from hearth.perception.knob_priors import (  # noqa: F401
    KnobPrior, knob_travel, knob_priors, near_round, standing_profile, canon,
)
from hearth.perception.knob_canvas import (  # noqa: F401
    plane_homography, image_of_plane, rectify, canvas_heights, plane_heights, to_gray, to_rgb,
    rotate_xy, off_axis_deg,
)
from hearth.perception.knob_scoring import (  # noqa: F401
    offset_scores, measured_sums, depth_offset_scores, measured_heights, DEPTH_MIN_VALID,
    depth_scores, depth_slope, depth_slope_se, template_onehot, label_scores,
)
from hearth.perception.knob_gates import (  # noqa: F401
    CalibratedThreshold, not_there, HARD_RADIUS_PX, HARD_OFF_AXIS_DEG, VERY_HARD_RADIUS_PX,
    VERY_HARD_OFF_AXIS_DEG, hard_view, view_level, allowed_angle, allowed_angles,
)
from hearth.perception.knob_round_bodies import (  # noqa: F401
    round_body_levels, body_center, marker_dot, marker_proud, dot_profile,
)
from hearth.perception.knob_reading import (  # noqa: F401
    KnobDetection, KnobReading, OFF_VIEWS_APART_M, OffViews, snap_to_state, KnobReader, read_knobs,
)

__all__ = [
    "KnobConfig", "N_FACE", "FINE_AZIMUTHS", "N_FACE_FINE", "KnobShape", "knob_shape",
    "ShapeTemplates", "KnobTemplates", "KnobPrior", "knob_travel", "knob_priors", "near_round",
    "standing_profile", "canon", "plane_homography", "image_of_plane", "rectify",
    "canvas_heights", "plane_heights", "to_gray", "to_rgb", "rotate_xy", "off_axis_deg",
    "offset_scores", "measured_sums", "depth_offset_scores", "measured_heights",
    "DEPTH_MIN_VALID", "depth_scores", "depth_slope", "depth_slope_se", "template_onehot",
    "label_scores", "CalibratedThreshold", "not_there", "HARD_RADIUS_PX", "HARD_OFF_AXIS_DEG",
    "VERY_HARD_RADIUS_PX", "VERY_HARD_OFF_AXIS_DEG", "hard_view", "view_level", "allowed_angle",
    "allowed_angles", "round_body_levels", "body_center", "marker_dot", "marker_proud",
    "dot_profile", "KnobDetection", "KnobReading", "OFF_VIEWS_APART_M", "OffViews",
    "snap_to_state", "KnobReader", "read_knobs",
]
