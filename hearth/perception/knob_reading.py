"""Reading knobs: ``KnobReader`` (templates + gates + configuration; ``read`` gives one
``KnobReading`` per prior), the snapping of an angle to a state (``snap_to_state``), and the
views that together make a knob off (``OffViews``). The method is described in
hearth/perception/knobs.py."""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from hearth.perception import knob_kernels
from hearth.perception.camera import Intrinsics
from hearth.perception.registration import single_threaded_blas
from hearth.perception.knob_canvas import _canvas_to_plane, canvas_heights, image_of_plane, off_axis_deg, plane_homography, rectify, rotate_xy, to_rgb
from hearth.perception.knob_config import KnobConfig
from hearth.perception.knob_gates import CalibratedThreshold, _with_half_turn, allowed_angle, allowed_angles, not_there, view_level
from hearth.perception.knob_priors import KnobPrior
from hearth.perception.knob_round_bodies import body_center, dot_profile, marker_dot, round_body_levels
from hearth.perception.knob_scoring import DEPTH_MIN_VALID, _candidates, _depth_center, _next_state, _states_of, _wrap, depth_offset_scores, depth_scores, depth_slope_se, label_scores, measured_heights, measured_sums, offset_scores, template_onehot
from hearth.perception.knob_shapes import _Caster
from hearth.perception.knob_templates import KnobTemplates
from hearth.perception.knob_window import _Window, _box_rays, _contrast_ratio


@dataclass
class KnobDetection:
    """Where the knob was found: centre in the face plane (m, knob x and y at angle 0), the
    image pixel of it, the fit there (``score``: R^2 of the best angle), and the turn ``psi``
    (rad) of the canvas it was found in."""
    center_m: tuple[float, float]
    score: float
    pixel: tuple[float, float]
    psi: float = 0.0
    scale: float = 1.0


@dataclass
class KnobReading:
    """One knob read. ``state`` is a state name or "unknown"; ``angle`` (rad) is None when no
    knob was found; ``confidence`` in [0, 1]; ``evidence``: the fit (``score``), the margin
    over the best other state (``margin``, and that state: ``runner_up``), the snap (share of
    half a state step) and the knob's radius in the image (``radius_px``)."""
    knob_id: str
    found: bool
    state: str = "unknown"
    angle: Optional[float] = None
    confidence: float = 0.0
    detection: Optional[KnobDetection] = None
    angles: dict = field(default_factory=dict)
    evidence: dict = field(default_factory=dict)
    reason: str = ""

    @property
    def angle_deg(self) -> Optional[float]:
        return None if self.angle is None else math.degrees(self.angle)


#: How far apart (m) two cameras must be for their "off" readings to count as two views.
OFF_VIEWS_APART_M = 0.25


class OffViews:
    """"Off" from two places: a reading that passes every check but the off factor
    (``KnobConfig.off_margin_factor``; evidence ``off_one_view``) is remembered per knob, and
    a second such reading from a camera at least ``apart_m`` from the first makes the knob
    off. A reading that leans to another state, or one that gives a state, forgets the knob;
    so does turning it or another knob of its appliance (``forget``: a turn can nudge a
    neighbour). A knob that is on would have to be read off wrongly,
    each time over the calibrated margin, from two places for this to fail: the factor asks
    more of one view, this asks the same of two (docs/knobs.md, "Off from two places").
    Hand-written: a small rule over readings, no library does it."""

    def __init__(self, apart_m: float = OFF_VIEWS_APART_M):
        self.apart_m = float(apart_m)
        self._seen: dict[str, list[np.ndarray]] = {}

    def forget(self, knob_id: str) -> None:
        self._seen.pop(knob_id, None)

    def add(self, reading: "KnobReading", off_state: str, camera: np.ndarray) -> bool:
        """Take ``reading`` (made from a camera at world position ``camera``); True when it
        makes its knob off (a second "off from this view alone" from far enough away)."""
        ev = reading.evidence or {}
        if reading.state != "unknown" or (reading.found and ev.get("leaning") not in (None, off_state)):
            self.forget(reading.knob_id)
            return False
        if not ev.get("off_one_view"):
            return False
        c = np.asarray(camera, dtype=float)[:3]
        seen = self._seen.setdefault(reading.knob_id, [])
        if any(np.linalg.norm(c - o) >= self.apart_m for o in seen):
            self.forget(reading.knob_id)
            return True
        seen.append(c)
        return False


def snap_to_state(angle: float, prior: KnobPrior, proba=None, psi: float = 0.0) -> tuple[str, float]:
    """The nearest discrete state to ``angle`` (rad; modulo the shape's period for a
    symmetric knob) and how far inside half a state step of it the angle lies (1 on the
    state, 0 half-way to the next)."""
    period = 2 * math.pi / max(1, prior.symmetry)
    a = np.asarray(prior.state_angles)
    d = np.abs(np.remainder(a - angle + period / 2, period) - period / 2)
    k = int(np.argmin(d))
    if len(a) > 1:
        diffs = np.abs(np.remainder(a[:, None] - a[None, :] + period / 2, period) - period / 2)
        diffs = diffs[diffs > 1e-6]
        half = float(diffs.min()) / 2 if len(diffs) else period / 2
    else:
        half = period / 2
    return prior.state_names[k], float(max(0.0, 1.0 - d[k] / half))



class KnobReader:
    """Templates + gates + configuration: ``read`` gives one KnobReading per prior (module
    docstring). ``detect_gate`` (a ``CalibratedThreshold`` on the fit) says whether a knob is
    in its region; ``state_gate`` (on the margin over the best other state) whether its
    state may be given, and ``state_gate_hard`` the same for hard views (``hard_view``; None:
    ``state_gate``)."""

    def __init__(self, templates: KnobTemplates, detect_gate: CalibratedThreshold,
                 state_gate: CalibratedThreshold, config: KnobConfig = KnobConfig(),
                 state_gate_hard: Optional[CalibratedThreshold] = None,
                 colour_gates: Optional["KnobReader"] = None):
        self.templates, self.detect_gate, self.state_gate, self.config = (
            templates, detect_gate, state_gate, config)
        self.state_gate_hard = state_gate_hard
        #: the gate of very hard views (``view_level`` 2; None: ``state_gate_hard``)
        self.state_gate_very_hard: Optional[CalibratedThreshold] = None
        #: the gates of readings made without a depth image (the fit and margins of colour
        #: alone are on another scale), as a reader whose gates they are; None: these gates
        self.colour_gates = colour_gates
        #: the state gates (view levels 0, 1, 2) of readings whose angle came from a round
        #: body's marker (evidence ``dot``: their margin is on a scale of its own); None: none
        self.dot_gates: Optional[list] = None
        #: the least ``half_turn`` (``_half_turn``) a reading of a knob without symmetry needs
        #: per ``view_level`` (0, 1, 2), calibrated with the state gates; None: no such gate
        self.half_turn_gates: Optional[list] = None
        #: the least ``rival`` (``_half_turn`` of the dot reading against the nearest other
        #: state) a round body's marker reading needs per ``view_level``, calibrated with the
        #: ``dot_gates``; None: no such gate
        self.dot_rival_gates: Optional[list] = None
        self._casters: dict = {}

    def __getstate__(self):
        d = dict(self.__dict__)
        d["_casters"] = {}
        return d

    def with_config(self, config: KnobConfig) -> "KnobReader":
        """This reader reading with ``config``'s read-time settings: its templates and every
        gate as they were calibrated (state, very hard, half-turn, dot and rival gates, and
        those of colour alone), only the configuration replaced."""
        out = copy.copy(self)
        out.config = config
        out._casters = {}
        if getattr(self, "colour_gates", None) is not None:
            out.colour_gates = self.colour_gates.with_config(config)
        return out

    def caster(self, key: str) -> _Caster:
        if key not in self._casters:
            self._casters[key] = _Caster(self.templates.shapes_[key])
        return self._casters[key]

    @property
    def detect_threshold(self) -> float:
        cfg = self.config
        return cfg.threshold if cfg.threshold is not None else self.detect_gate.threshold_

    @property
    def margin_threshold(self) -> float:
        cfg = self.config
        return cfg.margin_threshold if cfg.margin_threshold is not None else self.state_gate.threshold_

    def gates_for(self, depth: bool) -> "KnobReader":
        """The reader whose gates apply to a reading with (or without) depth."""
        g = getattr(self, "colour_gates", None)
        return g if (not depth and g is not None) else self

    def margin_threshold_for(self, hard, dot: bool = False) -> float:
        """The state gate of a view (``view_level``: 0, 1 or 2; or ``hard_view``): the hard
        or very hard views' own when it has one; of a reading from a round body's marker
        (``dot``), the level's ``dot_gates``."""
        cfg = self.config
        if cfg.margin_threshold is not None:
            return cfg.margin_threshold
        level = int(hard)
        if dot:
            dg = getattr(self, "dot_gates", None)
            # a reader made before the marker's readings had gates: never passes one
            return dg[min(level, len(dg) - 1)].threshold_ if dg else math.inf
        g = self.state_gate
        if level >= 1 and getattr(self, "state_gate_hard", None) is not None:
            g = self.state_gate_hard
        if level >= 2 and getattr(self, "state_gate_very_hard", None) is not None:
            g = self.state_gate_very_hard
        return g.threshold_

    def half_turn_gate_for(self, level, dot: bool = False) -> float:
        """The half-turn gate of a view (``view_level``); of a round body's marker reading
        (``dot``), its level's ``dot_rival_gates`` (the gate of its ``rival``); -inf when
        there is none."""
        g = getattr(self, "dot_rival_gates" if dot else "half_turn_gates", None)
        return float(g[min(int(level), len(g) - 1)]) if g else -math.inf

    # OpenBLAS on one thread while reading: the products here are small (windows of a few
    # thousand pixels, 3- and 4-column Gram matrices) and its threads spin on them, which
    # doubled the CPU of a reading for the same wall time (home 5: 115 against 62 ms per knob).
    @single_threaded_blas
    def read(self, image: np.ndarray, K: Intrinsics, T_world_camera: np.ndarray,
             priors: Sequence[KnobPrior], depth: Optional[np.ndarray] = None) -> list[KnobReading]:
        """One reading per prior. ``depth``: the depth image registered to ``image`` (m along
        the optical axis, 0 where there is no reading); read on colour alone without it."""
        rgb = to_rgb(np.asarray(image))
        T_wc = np.asarray(T_world_camera, dtype=float)
        if depth is not None:
            depth = np.asarray(depth, dtype=np.float32)
            if depth.shape[:2] != rgb.shape[:2]:
                raise ValueError(f"the depth image is {depth.shape[1]}x{depth.shape[0]}, the colour "
                                 f"image {rgb.shape[1]}x{rgb.shape[0]}: they must be registered")
        return [self.read_one(rgb, K, T_wc, p, depth) for p in priors]

    # one knob ------------------------------------------------------------------------------
    @single_threaded_blas
    def evidence(self, rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, prior: KnobPrior,
                 depth: Optional[np.ndarray] = None):
        """The knob's fit: a KnobReading with ``found`` and ``angle`` (no gates applied, no
        state) and, when it could be looked at, ``evidence`` (score, margin, runner_up).
        ``depth``: the registered depth image (m along the optical axis, 0: no reading; the
        image's size), fused with the colour fit when given (``depth_weight``)."""
        cfg = self.config
        tm = self.templates
        if prior.shape not in tm.templates_:
            from hearth.perception.errors import PerceptionError
            raise PerceptionError(f"knob {prior.knob_id}: its shape is not among the reader's "
                                  "templates (the models were made for another home)")
        shape = tm.shapes_[prior.shape]
        tpl = tm.templates_[prior.shape]
        theta = math.radians(off_axis_deg(T_wc, prior))
        if math.degrees(theta) > cfg.max_off_axis_deg:
            return KnobReading(prior.knob_id, False, reason="seen too obliquely")
        T_cam_face = np.linalg.inv(T_wc) @ prior.T_world_face()
        pc = T_cam_face[:3, 3]
        if pc[2] <= 0.05:
            return KnobReading(prior.knob_id, False, reason="behind the camera")
        u, v = K.fx * pc[0] / pc[2] + K.cx, K.fy * pc[1] / pc[2] + K.cy
        if not (0 <= u < K.width and 0 <= v < K.height):
            return KnobReading(prior.knob_id, False, reason="outside the image")
        r_px = K.fx * prior.radius / float(np.linalg.norm(pc))
        if r_px < cfg.min_radius_px:
            return KnobReading(prior.knob_id, False, evidence=dict(radius_px=round(r_px, 2)),
                               reason=f"too small in the image ({r_px:.1f} px radius)")
        T_c, psi = prior.canvas_frame(T_wc)
        C = (np.linalg.inv(T_c) @ np.append(T_wc[:3, 3], 1.0))[:3]       # camera, canvas frame

        # (1)-(2) where the knob is: the angle-averaged labels at every offset
        rho = tm.px_per_radius / prior.radius
        n = tm.window_px
        search_m = max(cfg.search_m, cfg.search_radii * prior.radius)
        S = int(math.ceil(search_m * rho))
        size = n + 2 * S
        H = plane_homography(K, T_wc, T_c, rho, size)
        canvas = rectify(rgb, H, size).astype(np.float32)
        ti = tm.bin_of(theta)
        r2 = offset_scores(canvas, tpl.soft[ti], tpl.gram_inv[ti])
        use_depth = depth is not None and tpl.heights is not None and cfg.depth_weight > 0
        if use_depth:
            # the depth image as heights above the believed face plane, the same canvas
            hc, hv = canvas_heights(depth, H, size, float(C[2]), shape.face)
            use_depth = bool(hv.mean() >= 0.3)
        if use_depth:
            dsums = measured_sums(hc, hv, n)
            r2 = r2 + cfg.depth_weight * depth_offset_scores(hc, hv, tpl.heights[ti].mean(0), sums=dsums)
        off = (np.arange(2 * S + 1) - S) / rho
        prior_pen = (off[None, :] ** 2 + off[:, None] ** 2) / (2 * cfg.offset_sigma_m ** 2)
        inside = (off[None, :] ** 2 + off[:, None] ** 2) <= search_m ** 2
        score = np.where(inside, r2 - cfg.offset_weight * prior_pen, -np.inf)
        i0, j0 = np.unravel_index(int(np.argmax(score)), score.shape)

        # (3) the coarse angle: every template at that offset and its neighbours
        cells = [(i, j) for i in range(i0 - 1, i0 + 2) for j in range(j0 - 1, j0 + 2)
                 if 0 <= i <= 2 * S and 0 <= j <= 2 * S]
        patches = np.stack([canvas[i:i + n, j:j + n].reshape(-1, 3) for i, j in cells])
        flat = tpl.labels[ti].reshape(len(tpl.alphas), -1)
        coarse = label_scores(patches, flat, tpl.counts[ti], tpl.n_labels,
                              template_onehot(tpl, ti))                        # (P, A)
        if use_depth:
            hp = np.stack([hc[i:i + n, j:j + n].ravel() for i, j in cells])
            vp = np.stack([hv[i:i + n, j:j + n].ravel() for i, j in cells])
            coarse = coarse + cfg.depth_weight * depth_scores(
                hp, vp, tpl.heights[ti].reshape(len(tpl.alphas), -1))
        best_cell = int(np.argmax(coarse.max(1)))
        ci, cj = cells[best_cell]
        centres: dict = {}

        def depth_center(k: int):
            """Where template ``k``'s heights fit the depth best (``_depth_center``), once."""
            if k not in centres:
                centres[k] = _depth_center(hc, hv, tpl.heights[ti][k], (ci, cj), inside, off, rho,
                                           sums=dsums)
            return centres[k]

        curve = coarse[best_cell]
        center = (off[cj], -off[ci])                     # canvas frame (canvas up = -rows)
        knob_angles = _wrap(tpl.alphas + psi)            # relative angle -> knob angle
        allowed = self._allowed(prior, knob_angles)
        if not allowed.any():
            allowed[:] = True
        state_of = _states_of(prior, knob_angles)
        picks = _candidates(curve, allowed, state_of, cfg.candidates)
        if use_depth:
            # the centre from the depth alone, with the shape at the best coarse angle (the
            # knob's body stands out of the panel whatever its colours), to a fraction of a
            # canvas pixel: colour alone can trade the centre against the angle. Then the
            # coarse angles again, in a canvas centred there.
            c_depth = depth_center(picks[0])
            if c_depth is not None:
                center = c_depth
                curve = self._coarse_at(rgb, depth, K, T_wc, T_c, C, prior, shape, tpl, ti,
                                        flat, center)
                picks = _candidates(curve, allowed, state_of, cfg.candidates)

        # a knob whose body is round about its axis (a skirt and cap) with a dot off the axis:
        # its angle is only where the dot stands about the centre, and only depth places that
        # centre; to a fraction of a pixel from the top's rim at the image's own pixels
        # (``body_center``), then the angle from the dot's colour about it
        fine, from_dot = None, False
        windows: dict = {}                  # the exact checks' windows, by centre (``_refine``)
        if use_depth and cfg.round_body_center:
            fine = self._round_body(rgb, K, T_wc, prior, shape, tpl, ti, T_c, C, center, picks,
                                    allowed, state_of, psi, r_px, depth, theta, flat, windows)
            if fine is not None:
                fine, again, picks, from_dot = fine
                curve = curve if again is None else again

        # (4) the exact check of the candidates at the fine scale; with depth, each candidate
        # at the centre the depth gives the shape at its own angle (a pointer flipped by 180
        # degrees stands elsewhere: the best candidate is the best centre and angle together)
        if fine is not None:
            pass
        elif use_depth:
            if shape.symmetry == 1:
                # and the best coarse angle turned by half a turn, whatever the coarse curve
                # says of it: a marker flipped a radius away is the mistake colour makes. The
                # allowed angle nearest the half turn, within 45 degrees: a knob that turns
                # one way only may stop short of it (home 4: states 0-223 degrees, the best
                # coarse angle 61 with the knob at 222; the half turn, 241, was not allowed,
                # and no angle near the knob's was checked)
                picks = _with_half_turn(tpl.alphas, picks, allowed)
            # candidates whose centres agree (a knob whose body looks the same at every
            # angle) share one window
            groups: list = []
            for c in picks:
                c_at = depth_center(c) or center
                for g in groups:
                    if math.hypot(g[0][0] - c_at[0], g[0][1] - c_at[1]) <= 0.05 * prior.radius:
                        g[1].append(tpl.alphas[c])
                        break
                else:
                    groups.append((c_at, [tpl.alphas[c]]))
            fine = []
            for c_at, alphas in groups:
                fine += self._refine(rgb, K, T_wc, prior, shape, T_c, C, c_at, alphas,
                                     psi, r_px, depth, theta, windows=windows)
        else:
            fine = self._refine(rgb, K, T_wc, prior, shape, T_c, C, center,
                                [tpl.alphas[c] for c in picks], psi, r_px, None, theta,
                                windows=windows)
        fine = [f for f in fine if allowed_angle(prior, f[1])] or fine
        fine.sort(key=lambda f: -f[0])
        best = fine[0]
        s_best = snap_to_state(best[1], prior)[0]
        if not from_dot:
            # the state next to the reading's angle, fitted exactly at its own angle at the
            # reading's centre when no exact check ended in it; where it fits better than the
            # reading, it is the reading (the exact checks' search can stop on the slope
            # between two states: home 787, a reading 10 degrees off between states 17
            # degrees apart, margin 0.35 over a state 35 degrees away, set its level's gate
            # to 0.43; the true state fitted at its own angle gave 1.91 against 1.81). Where
            # it fits worse it is left out: measuring every margin against it shrank right
            # readings' margins, and the recalibrated gates let a packed pointer through 90
            # degrees off (home 4; docs/knobs.md).
            s_next, a_next = _next_state(prior, best[1], s_best)
            if s_next is not None and not any(snap_to_state(f[1], prior)[0] == s_next
                                              for f in fine[1:]):
                probe = self._refine(rgb, K, T_wc, prior, shape, T_c, C, best[2],
                                     [a_next - psi], psi, r_px,
                                     depth if use_depth else None, theta, hold=True,
                                     exact_only=True, windows=windows)[0]
                if probe[0] > best[0]:
                    fine.insert(0, probe)
                    best = probe
                    s_best = s_next
        checked = list(fine)
        rivals = [f for f in fine[1:] if snap_to_state(f[1], prior)[0] != s_best]
        score_best, angle, center_c = best
        if rivals:
            margin = score_best - rivals[0][0]
        else:
            # every exact check ended in the best state (or none of another was allowed):
            # the margin is the coarse one, the best angle over the best of another state
            # among the allowed angles (0 when there is none: the state is not told apart)
            i_best = _states_of(prior, [angle])[0]
            others = np.flatnonzero(allowed & (state_of != i_best))
            margin = float(curve[picks[0]] - curve[others].max()) if len(others) else 0.0
            margin = max(0.0, min(margin, score_best))
        fine = [best] + rivals
        c_best = picks[0]
        half_turn = None
        # the reading against itself turned by half a turn (``_half_turn``), the rival the
        # margin tells worst: the best exact check that ended within 45 degrees of the half
        # turn; else the allowed template angle nearest to the half turn, within 45 degrees,
        # at the centre the depth gives the shape turned so (not refined: an exact check more
        # per knob tripled the CPU of a skirt knob, whose checks seldom end there). None
        # allowed: no half turn to fear.
        near = [f for f in checked[1:] if abs(_wrap(f[1] - angle - math.pi)) < math.radians(45)]
        turned = max(near, key=lambda f: f[0]) if near else None
        # (not for a round body's dot reading: its margin already weighs the dot against
        # every other dot-sized spot of the top, the half turn's place included)
        if shape.symmetry == 1 and turned is None and not from_dot:
            d = np.where(allowed, np.abs(_wrap(knob_angles - angle - math.pi)), np.inf)
            k = int(np.argmin(d))
            if d[k] < math.radians(45):
                c_at = center_c
                if use_depth:
                    c_at = depth_center(k) or center_c
                turned = (None, float(knob_angles[k]), c_at)
        if shape.symmetry == 1 and turned is not None and not from_dot:
            half_turn = self._half_turn(rgb, K, T_wc, prior, shape, T_c, C, (float(angle) - psi, center_c),
                                        (float(turned[1]) - psi, turned[2]), psi, r_px,
                                        depth if use_depth else None, theta, windows=windows)
        center_k = rotate_xy(center_c, psi)              # canvas frame -> knob face frame
        p_world = prior.T_world_face() @ np.array([center_k[0], center_k[1], 0.0, 1.0])
        pcam = np.linalg.inv(T_wc) @ p_world
        pixel = (K.fx * pcam[0] / pcam[2] + K.cx, K.fy * pcam[1] / pcam[2] + K.cy)
        det = KnobDetection((float(center_k[0]), float(center_k[1])), float(score_best),
                            (float(pixel[0]), float(pixel[1])), float(psi))
        ev = dict(score=round(float(score_best), 4), margin=round(float(margin), 4),
                  offset=round(math.hypot(*center_k) / search_m, 3),
                  runner_up=(snap_to_state(fine[1][1], prior)[0] if len(fine) > 1 else None),
                  coarse_score=round(float(curve[c_best]), 4), radius_px=round(r_px, 2),
                  depth=bool(use_depth))
        if use_depth:
            # how much of the knob's relief the depth shows where it was read (``depth_slope``:
            # a coarse canvas centred on the reading, the template nearest its angle)
            k = int(np.argmin(np.abs(_wrap(tpl.alphas - (float(angle) - psi)))))
            hr, vr = canvas_heights(depth, plane_homography(K, T_wc, T_c, rho, n, center_c), n,
                                    float(C[2]), shape.face)
            sl = depth_slope_se(hr, vr, tpl.heights[ti][k])
            if sl is not None:
                ev["stands"], ev["stands_se"] = round(sl[0], 3), round(sl[1], 4)
        if from_dot:
            ev["dot"] = True
            # the marker's reading against the nearest other state (``fine[1]``, at the same
            # centre), compared only where their renderings differ (``_half_turn``: the
            # marker at the one angle against the marker at the other): the dot's margin is
            # an expected error of the angle, blind to a dot read from a speck or a glint
            # beside it; on generated homes 0-19 the wrong validation readings of the marker
            # with the widest margins explained the rival's pixels no better than the rival
            # (docs/knobs.md, "The marker against the next state")
            versus = self._half_turn(rgb, K, T_wc, prior, shape, T_c, C, (float(angle) - psi, center_c),
                                     (float(fine[1][1]) - psi, fine[1][2]), psi, r_px,
                                     depth if use_depth else None, theta, windows=windows) if len(fine) > 1 else None
            if versus is not None:
                ev["rival"] = versus["half_turn"]
        if half_turn is not None:
            ev.update(half_turn)
        if snap_to_state(float(angle), prior)[0] == prior.off_state and not from_dot:
            # an "off" reading against the best "on" candidate, compared only where the two
            # renderings differ (``_half_turn`` with that state in place of the half turn):
            # the one promise the reader keeps is that a knob that is on is never read off, so
            # off must explain the pixels that tell it from on better than on does, whatever
            # the margin over the whole window (``KnobConfig.off_rival_min``)
            on = [(a, c) for _f, a, c in fine[1:] if snap_to_state(float(a), prior)[0] != prior.off_state]
            if not on:
                sa = np.asarray(prior.state_angles, dtype=float)
                names = np.asarray(prior.state_names)
                d = np.where(names == prior.off_state, np.inf, np.abs(_wrap(sa - float(angle))))
                on = [(float(sa[int(np.argmin(d))]), center_c)] if np.isfinite(d).any() else []
            if on:
                vs = self._half_turn(rgb, K, T_wc, prior, shape, T_c, C, (float(angle) - psi, center_c),
                                     (float(on[0][0]) - psi, on[0][1]), psi, r_px,
                                     depth if use_depth else None, theta, windows=windows)
                if vs is not None:
                    ev["off_rival"] = vs["half_turn"]
                    ev["off_rival_state"] = snap_to_state(float(on[0][0]), prior)[0]
        return KnobReading(prior.knob_id, True, angle=float(angle), detection=det,
                           angles={"fused": float(angle)}, evidence=ev)

    def read_one(self, rgb: np.ndarray, K: Intrinsics, T_wc: np.ndarray, prior: KnobPrior,
                 depth: Optional[np.ndarray] = None) -> KnobReading:
        r = self.evidence(rgb, K, T_wc, prior, depth)
        if not r.found:
            return r
        cfg = self.config
        ev = r.evidence
        gates = self.gates_for(bool(ev.get("depth")))
        why = not_there(ev, cfg)
        if why:
            return KnobReading(prior.knob_id, False, evidence=ev,
                               reason=f"no knob found in its region ({why})")
        if ev["score"] <= gates.detect_threshold:
            return KnobReading(prior.knob_id, False, evidence=ev,
                               reason=f"no knob found in its region (fit {ev['score']:.2f})")
        state, c_snap = snap_to_state(r.angle, prior)
        ev["snap"] = round(1.0 - c_snap, 3)
        oblique = off_axis_deg(T_wc, prior)
        hard = view_level(ev.get("radius_px", 0.0), oblique)
        gate = gates.margin_threshold_for(hard, bool(ev.get("dot")))
        is_off = state == prior.off_state
        need = gate * (cfg.off_margin_factor if is_off else 1.0)
        ev["leaning"] = state
        c_margin = ev["margin"] / max(need, 1e-6)
        r.confidence = float(min(1.0, 0.5 * min(c_margin, 2.0)) * c_snap)
        need_turn = gates.half_turn_gate_for(hard, bool(ev.get("dot")))

        def doubt(need_margin: float) -> Optional[str]:
            """Why the reading may not give its state with a margin gate of ``need_margin``
            (None: it may)."""
            if ev.get("dot") and oblique > cfg.dot_max_off_axis_deg:
                # a marker seen more obliquely than any view its reader was measured on
                # (the bench's views reach 60 degrees): before the centre kept to the knob's
                # own points, readings beyond 55 degrees were read a state or two off with
                # margins well over their gates (docs/knobs.md, "A dot seen obliquely")
                return (f"unsure ({state}: its marker is seen {oblique:.0f} degrees off the "
                        f"knob's axis, at most {cfg.dot_max_off_axis_deg:.0f})")
            if ev["margin"] <= need_margin:
                return (f"unsure ({state}: margin {ev['margin']:.3f} over {ev['runner_up']}, "
                        f"needs {need_margin:.3f})")
            if ev.get("half_turn") is not None and ev["half_turn"] <= need_turn:
                return (f"unsure ({state}: turned by half a turn it fits nearly as well, "
                        f"{ev['half_turn']:.2f}, needs {need_turn:.2f})")
            if ev.get("dot") and ev.get("rival") is not None and ev["rival"] <= need_turn:
                return (f"unsure ({state}: its marker fits nearly as well at {ev['runner_up']}, "
                        f"{ev['rival']:.2f}, needs {need_turn:.2f})")
            if is_off and ev.get("off_rival") is not None and ev["off_rival"] <= cfg.off_rival_min:
                return (f"unsure ({state}: {ev.get('off_rival_state')} fits nearly as well where "
                        f"the two differ, {ev['off_rival']:.2f}, needs {cfg.off_rival_min:.2f})")
            if 1.0 - c_snap > cfg.max_snap:
                return f"unsure ({state}: {math.degrees(r.angle):.0f} degrees lies between states)"
            if r.confidence < cfg.min_confidence:
                return f"unsure ({state}: confidence {r.confidence:.2f} under {cfg.min_confidence:.2f})"
            return None

        r.reason = doubt(need) or ""
        if not r.reason and is_off and getattr(prior, "round_grip", False):
            # a round body's angle rests on its marker alone: one view never says off (a
            # knurled grip with a dot, read 37 degrees off at its off state from one view,
            # passed every gate: home 102 of generator version 7); a second such reading from
            # another place does (``OffViews``)
            r.reason = f"unsure ({state}: a ridged round grip's marker alone says it"
            ev["off_one_view"] = True
            r.reason += ") from this view alone"
            return r
        if not r.reason:
            r.state = state
        elif is_off and need > gate and doubt(gate) is None:
            # every check an "on" state needs is passed; only the off factor is not: a second
            # such reading from another place makes it off (``OffViews``)
            ev["off_one_view"] = True
            r.reason += " from this view alone"
        return r

    def _allowed(self, prior: KnobPrior, angles: np.ndarray) -> np.ndarray:
        return allowed_angles(prior, angles)

    def _coarse_at(self, rgb, depth, K, T_wc, T_c, C, prior, shape, tpl, ti, flat, center):
        """The coarse fit (colour plus ``depth_weight`` times depth) of every template angle
        in a canvas centred at ``center`` (canvas frame, m)."""
        rho = self.templates.px_per_radius / prior.radius
        n = self.templates.window_px
        Hd = plane_homography(K, T_wc, T_c, rho, n, center)
        patch = rectify(rgb, Hd, n).astype(np.float32).reshape(1, -1, 3)
        hd, vd = canvas_heights(depth, Hd, n, float(C[2]), shape.face)
        return (label_scores(patch, flat, tpl.counts[ti], tpl.n_labels, template_onehot(tpl, ti))[0]
                + self.config.depth_weight * depth_scores(
                    hd.reshape(1, -1), vd.reshape(1, -1),
                    tpl.heights[ti].reshape(len(tpl.alphas), -1))[0])

    def _round_body(self, rgb, K, T_wc, prior, shape, tpl, ti, T_c, C, center, picks, allowed,
                    state_of, psi, r_px, depth, theta, flat, windows=None):
        """The candidates of a round-bodied knob (``round_body_levels``, a dot no wider than
        ``dot_max_size`` of its distance from the axis) read at the centre ``body_center``
        gives (from ``center``, the canvas depth fit's): the angle from the dot
        (``_dot_reading``), its fit the exact check's there, and, as rival, the nearest
        other state at the fit less the dot's margin; without a dot profile (``dot_angle``
        off, no top to see it on) the coarse angles again in a canvas centred there, the best
        ones and the best turned by half a turn checked exactly with the centre held. Returns
        (fine, coarse curve, picks, whether from the dot) as ``evidence`` uses them (the curve
        None from the dot: the one before stands), or None (not such a knob, or too few depth
        pixels)."""
        cfg = self.config
        levels = round_body_levels(shape)
        md = marker_dot(shape)
        if levels is None or md is None or md[2] > cfg.dot_max_size * md[1]:
            # a marker across the centre (the plain knob's bar) turns about it whatever the
            # centre's error: its reading needs none of this
            return None
        got = body_center(depth, K, T_wc, T_c, shape, self.caster(prior.shape), levels, center,
                          float(tpl.alphas[picks[0]]), psi)
        if got is None:
            return None
        center = got[0]
        dot = self._dot_reading(rgb, K, T_wc, prior, shape, T_c, center, psi, r_px) if cfg.dot_angle else None
        if dot is not None:
            # the angle from the marker's colour about that centre, the margin the marker's
            # evidence; the fit (for the detect gate) that of the exact check there, at that
            # angle: both come from the image already, and settling the offset by colour and
            # searching the angle (a round body in its panel's colour says little of either)
            # took a fifth of a skirt knob's reading (the coarse curve is the one before)
            a_dot, margin, rival = dot
            fit = self._refine(rgb, K, T_wc, prior, shape, T_c, C, center, [a_dot - psi], psi,
                               r_px, depth, theta, hold=True, exact_only=True, windows=windows)[0][0]
            return [(fit, a_dot, center), (fit - margin, rival, center)], None, picks, True
        curve = self._coarse_at(rgb, depth, K, T_wc, T_c, C, prior, shape, tpl, ti, flat, center)
        picks = _candidates(curve, allowed, state_of, cfg.candidates)
        picks = _with_half_turn(tpl.alphas, picks, allowed)
        fine = self._refine(rgb, K, T_wc, prior, shape, T_c, C, center,
                            [tpl.alphas[c] for c in picks], psi, r_px, depth, theta, hold=True,
                            windows=windows)
        return fine, curve, picks, False

    def _dot_reading(self, rgb, K, T_wc, prior, shape, T_c, center, psi, r_px):
        """The angle of a round-bodied knob from its marker's colour about ``center``
        (``dot_profile``: the best allowed angle, refined by a parabola), a margin and the
        angle of the nearest other state. The margin is what the marker's evidence says of
        the state: how far the angle lies from the edge of its state's half step, in units of
        the angle's expected error (the centre's error, ``dot_center_px`` image pixels, and
        the marker's own, ``dot_blob_px`` pixels over its contrast to noise: a blob's
        position error goes as the noise over its contrast; both seen from the marker's
        distance from the axis), times how much the marker's response stands out over the
        best response of a marker-sized disc anywhere else on the top (a second blob, a
        glint, a marker not seen), to the power ``dot_dominance_power``. None without a
        marker or a top to see it on."""
        cfg = self.config
        prof = dot_profile(rgb, K, T_wc, T_c, shape, center)
        if prof is None:
            return None
        alphas, S, noise = prof
        md = marker_dot(shape)
        knob_a = _wrap(alphas + psi)
        ok = self._allowed(prior, knob_a)
        if not ok.any():
            ok[:] = True
        Sm = np.where(ok, S, -np.inf)
        k = int(np.argmax(Sm))
        step = float(alphas[1] - alphas[0])
        y0, y1, y2 = S[k - 1], S[k], S[(k + 1) % len(S)]
        den = y0 - 2 * y1 + y2
        x = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den < 0 else 0.0
        a_dot = float(_wrap(knob_a[k] + x * step))
        base = float(np.median(S))
        peak = float(S[k]) - base
        if peak <= 0:
            return None
        width = 2 * md[2] / max(md[1], 1e-6) + step          # the marker's angular width
        far = np.abs(_wrap(knob_a - a_dot)) > width
        other = float(S[far & ok].max()) - base if (far & ok).any() else 0.0
        dominance = float(np.clip(1.0 - max(other, 0.0) / peak, 0.0, 1.0))
        snr = peak / max(noise, cfg.dot_noise_floor)
        state, inside = snap_to_state(a_dot, prior)
        sa = np.asarray(prior.state_angles)
        names = np.asarray(prior.state_names)
        steps = np.abs(_wrap(sa[:, None] - sa[None, :]))
        steps = steps[steps > 1e-6]
        half = float(steps.min()) / 2 if len(steps) else math.pi
        pix = prior.radius / max(r_px, 1e-6)                  # m per image pixel at the knob
        # the marker's own error as noise over contrast, not its square root, and no separate
        # factor for a weak marker (which counted its contrast twice); a rival blob weighs
        # as the cube of the dominance: on the dot readings of 16 homes' held-out views
        # (3,926 readings, gates calibrated on their validation views) 2,512 right readings
        # passed against 2,259, and 3 wrong ones against 4 (docs/knobs.md, "The marker's
        # expected error")
        sigma = math.hypot(cfg.dot_center_px, cfg.dot_blob_px / max(snr, 1e-3)) * pix / md[1]
        margin = inside * half / sigma * dominance ** cfg.dot_dominance_power
        d = np.abs(_wrap(sa - a_dot))
        d = np.where(names == state, np.inf, d)
        rival = float(sa[int(np.argmin(d))]) if np.isfinite(d).any() else float(_wrap(a_dot + math.pi))
        return a_dot, float(margin), rival

    def _half_turn(self, rgb, K, T_wc, prior, shape, T_c, C, reading, turned, psi, r_px,
                   depth=None, theta=0.0, windows: Optional[dict] = None) -> Optional[dict]:
        """How much better the reading (``reading`` = (relative angle rad, centre in the canvas
        frame m)) explains the image than the knob turned by half a turn from it
        (``turned``, the same: the exact check that ended nearest the half turn, or the half
        turn at the centre the depth gives it): a knob without symmetry
        looks much the same both ways (a pointer, a tip, a marker: most of the grip
        coincides), so a fit over the whole window tells them apart weakly and the state
        gate was set by such readings. Both are rendered exactly (as ``_refine`` renders,
        each at its own centre) in one window between them and compared only where they
        differ: the window pixels whose labels differ between the two renderings (the marker,
        tip or point under one, the grip, bezel or panel under the other), each weighted by
        the share of its label weights that differ. Each rendering's label colours are its
        own least-squares fit over the whole window; ``half_turn_colour`` is (SSE_turned -
        SSE) / (SSE_turned + SSE + 2 E) of the colour residuals over those pixels, E what
        their residual would be if they fitted as well as the window does on average (near
        1: only the reading explains them, near -1: only the turned knob, 0: both, or
        neither, or noise alone; ``_contrast_ratio``). With
        ``depth``, ``half_turn_depth`` is the same of the depth residuals over the image
        pixels whose rendered depths differ, each rendering put at the measured depth by the
        median difference over the pixels where the two agree (the believed plane's height
        error). ``half_turn``: the colour's plus ``depth_weight`` times the depth's, checked
        against ``half_turn_gate_for`` (calibrated like the state gate). None when the window
        leaves the image. ``windows``: the reading's exact checks' windows (``_refine``)."""
        cfg = self.config
        if r_px > cfg.decimate_above_px:
            rgb = rgb[::2, ::2]
            depth = None if depth is None else depth[::2, ::2]
            K = Intrinsics(K.fx / 2, K.fy / 2, K.cx / 2, K.cy / 2, rgb.shape[1], rgb.shape[0])
        rho = cfg.fine_px_per_radius / prior.radius
        n = 2 * int(math.ceil(self.templates.window_radii * cfg.fine_px_per_radius)) + 1
        mid = ((reading[1][0] + turned[1][0]) / 2, (reading[1][1] + turned[1][1]) / 2)
        # the exact checks' window there when they looked through one (``_refine``'s
        # ``windows``: the same window, rays and, at one centre for both, renderings)
        seen = (windows or {}).get((float(mid[0]), float(mid[1]), depth is None))
        win = seen or _Window(rgb, K, plane_homography(K, T_wc, T_c, rho, n, mid), n,
                              ridge=cfg.fine_ridge_px)
        if win.box is None:
            return None
        if seen is not None and tuple(reading[1]) == tuple(turned[1]):
            labs, ts = seen.render(np.array([reading[0], turned[0]]))
            dirs = (windows or {})[("pixels", win.box, depth is None)][0]
        else:
            dirs = win.rays_camera() @ (np.linalg.inv(T_c)[:3, :3] @ T_wc[:3, :3]).T
            # both in one cast: the rays of each from the camera as seen from its own centre
            origins = np.stack([np.broadcast_to(C - np.array([c[0], c[1], -shape.face]), dirs.shape)
                                for _, c in (reading, turned)])
            labs, ts = self.caster(prior.shape).labels(origins, dirs, np.array([reading[0], turned[0]]),
                                                       -psi, fine=True, with_t=True)
        colour = _contrast_ratio(*win.contrast(labs))
        out = dict(half_turn=colour, half_turn_colour=colour)
        if depth is not None:
            u0, v0, u1, v1 = win.box
            m = depth[v0:v1, u0:u1].ravel().astype(np.float64)
            dz = np.where(np.abs(dirs[:, 2]) > 1e-6, dirs[:, 2], 1e-6)
            panel = -(C[2] + shape.face) / dz          # the panel plane (z = 0 of the knob)
            slack = shape.face / max(math.cos(theta), 0.3) + 0.03
            valid = (m > 0) & (m > panel - slack) & (m < panel + 0.03)
            z = [np.where(np.isfinite(t), t, panel) for t in ts]
            differ = np.abs(z[0] - z[1]) > 1e-4
            agree, d = valid & ~differ, valid & differ
            if valid.mean() >= 0.3 and agree.sum() >= 10 and d.any():
                res, noise = [], 0.0
                for zh in z:
                    e = m - zh - float(np.median(m[agree] - zh[agree]))
                    res.append(float(e[d] @ e[d]))
                    noise += float(np.mean(e[agree] ** 2)) / 2
                out["half_turn_depth"] = _contrast_ratio(res[0], res[1], d.sum() * noise)
                out["half_turn"] += cfg.depth_weight * out["half_turn_depth"]
        return {k: round(float(v), 4) for k, v in out.items()}

    def _refine(self, rgb, K, T_wc, prior, shape, T_c, C, center, alphas0, psi, r_px,
                depth=None, theta=0.0, hold=False, exact_only=False, windows=None):
        """The exact check (module docstring, step 4): the knob rendered as the camera sees
        it, a ray through every image pixel around it from the real camera centre, at
        relative angles around each of ``alphas0`` (rad; the best coarse angle first), with
        its centre at the canvas offset ``center`` (m) and then where it fits best. A knob
        larger than ``decimate_above_px`` in the image is read in every other row and column
        of the image (point samples still, so the rendering models them exactly). Each
        label's pixels are sampled into the fine canvas exactly as the image is (bilinearly:
        soft label maps, ``_Window``) and the maps are fitted to the image (R^2). The
        offset: Gauss-Newton on a rendering (``_Window.settle``). The angle: renderings half a
        template step either side, a parabola through the best three (walking while an end
        is the best; the renderings of all candidates cast and fitted in one batch); with
        ``angle_stages`` 2, for the first candidate the offset again, then the same at a sixth
        of a step (one stage reads as well on most homes but lost packed pointers: home 4's
        state accuracy 0.34 -> 0.14). With ``depth``: each rendering's depth (the knob, else the panel plane) is
        correlated with the measured depth of the same image pixels, and the fit is the
        colour R^2 plus ``depth_weight`` times that squared correlation; the offset then stays
        within ``depth_settle_radii`` of where the depth put the knob (the colour alone of a
        knob without contrast can fit a marker flipped by 180 degrees a radius away).
        ``exact_only``: the fits at ``alphas0`` themselves, at ``center`` (no offset settled,
        no angle searched). ``windows``: a dict one reading keeps, of the windows its exact
        checks looked through by centre (a check at a centre another one ended at, the next
        state's, reuses its window: the same image, rays and fixed visuals' hits), and of
        the rays and depth fit of each image box (``pixels``; ``_half_turn`` reads both). Returns
        [(fit, knob angle, centre in the canvas frame)] per candidate."""
        cfg, tm = self.config, self.templates
        if r_px > cfg.decimate_above_px:
            rgb = rgb[::2, ::2]
            depth = None if depth is None else depth[::2, ::2]
            K = Intrinsics(K.fx / 2, K.fy / 2, K.cx / 2, K.cy / 2, rgb.shape[1], rgb.shape[0])
        rho = cfg.fine_px_per_radius / prior.radius
        n = 2 * int(math.ceil(tm.window_radii * cfg.fine_px_per_radius)) + 1
        caster = self.caster(prior.shape)
        R_canvas_cam = np.linalg.inv(T_c)[:3, :3] @ T_wc[:3, :3]
        max_shift = cfg.search_m * rho
        iterations = cfg.align_iterations
        if depth is not None:
            max_shift = min(max_shift, cfg.depth_settle_radii * cfg.fine_px_per_radius)
        slack = shape.face / max(math.cos(theta), 0.3) + 0.03
        w_depth = cfg.depth_weight

        H_plane = image_of_plane(K, T_wc, T_c)     # every window's homography: this, then its canvas

        def look(c) -> Optional[_Window]:
            key = (float(c[0]), float(c[1]), depth is None)
            if windows is not None and key in windows:
                return windows[key]
            win = _Window(rgb, K, H_plane @ _canvas_to_plane(rho, n, c), n, ridge=cfg.fine_ridge_px)
            if windows is not None:
                windows[key] = win if win.box is not None else None
            if win.box is None:
                return None
            O = C - np.array([c[0], c[1], -shape.face])
            dirs, depth_fit = pixels(win.box, O[2])
            # the fixed visuals' hits are the same for every rendering of this window
            fixed_hits: dict = {}
            win.render = lambda alphas: caster.labels(O, dirs, alphas, -psi, fine=True, with_t=True,
                                                      cache=fixed_hits)
            win.c = c
            win.depth_fit = depth_fit
            return win

        def pixels(box, height: float):
            """The rays of a box's pixels (canvas frame) and, with depth, the fit of the
            measured depth there to renderings' ray parameters (B, N) -> (B,), or None when
            under a third of it is valid. The same for every window on the same box (a
            window moved by a fraction of a pixel, ``settle``): the panel's place along a ray
            depends only on the camera's height over it (``height``, the same for every
            centre), so made once."""
            bkey = ("pixels", box, depth is None)
            got = windows.get(bkey) if windows is not None else None
            if got is not None:
                return got
            u0, v0, u1, v1 = box
            dirs = _box_rays(box, K) @ R_canvas_cam.T
            depth_fit = None
            if depth is not None:
                m = depth[v0:v1, u0:u1].ravel().astype(np.float64)
                dz = np.where(np.abs(dirs[:, 2]) > 1e-6, dirs[:, 2], 1e-6)
                panel = -height / dz                   # the panel plane (z = 0 of the knob)
                valid = (m > 0) & (m > panel - slack) & (m < panel + 0.03)
                if valid.mean() >= 0.3:
                    # ``depth_scores`` of the renderings' depths (compiled: the numpy calls
                    # cost more than the sums)
                    _, Wm, Sw, Sm, Smm, count = measured_heights(m[None], valid[None])
                    args = (panel, valid, Wm[0], float(Sw[0, 0]), float(Sm[0, 0]),
                            float(Smm[0, 0]), bool(count[0, 0] >= DEPTH_MIN_VALID * len(m)))

                    def depth_fit(ts, args=args):
                        out = np.empty(len(ts))
                        knob_kernels.depth_fits(np.ascontiguousarray(ts), *args, out)
                        return out
            got = (dirs, depth_fit)
            if windows is not None:
                windows[bkey] = got
            return got

        def scores(win, labs, ts) -> np.ndarray:
            """The fits of renderings (B, N) and their ray parameters, in one go."""
            f = win.fits(labs)
            return f + w_depth * win.depth_fit(ts) if win.depth_fit is not None else f

        def settle(win: _Window, alpha: float) -> Optional[_Window]:
            if hold:                       # the centre is held where it was given
                return win
            t = win.settle(win.render([alpha])[0][0], iterations, max_shift)
            if np.hypot(*t) <= 0.05:
                return win
            return look((win.c[0] + t[0] / rho, win.c[1] + t[1] / rho))

        win = look(center)
        win = settle(win, alphas0[0]) if win is not None and not exact_only else win
        if win is None:
            return [(0.0, float(_wrap(a + psi)), center) for a in alphas0]
        if exact_only:
            labs, ts = win.render([float(a) for a in alphas0])
            return [(float(sc), float(_wrap(a + psi)), win.c)
                    for sc, a in zip(scores(win, labs, ts), alphas0)]
        step = math.radians(tm.alpha_step_deg) / 2

        def search(win, starts, st, span=1):
            """Parabolic search of each start angle (one rendering for all of them), from
            ``span`` steps either side of it (the coarse angle of a small marker can be a
            few steps off)."""
            ks = list(range(-span, span + 1))
            labs, ts = win.render([a + k * st for a in starts for k in ks])
            fits = iter(scores(win, labs, ts).tolist())
            curves = [{k: next(fits) for k in ks} for _ in starts]     # by whole steps
            for _ in range(2):             # walk while an end is the best (all starts at once)
                steps = []
                for i, found in enumerate(curves):
                    top = max(found, key=found.get)
                    if top in (min(found), max(found)):
                        steps.append((i, top + (1 if top == max(found) else -1)))
                if not steps:
                    break
                labs, ts = win.render([starts[i] + k * st for i, k in steps])
                for (i, k), f in zip(steps, scores(win, labs, ts).tolist()):
                    curves[i][k] = f
            out = []
            for a, found in zip(starts, curves):
                top = max(found, key=found.get)
                y1, ym, yp = found[top], found.get(top - 1), found.get(top + 1)
                if ym is not None and yp is not None and ym - 2 * y1 + yp < 0:
                    x = float(np.clip(0.5 * (ym - yp) / (ym - 2 * y1 + yp), -0.5, 0.5))
                    out.append((float(y1 - 0.25 * (ym - yp) * x), a + (top + x) * st))
                else:
                    out.append((float(y1), a + top * st))
            return out

        found = search(win, [float(a) for a in alphas0], step, cfg.angle_span_steps)
        out = [(sc, float(_wrap(a + psi)), win.c) for sc, a in found]
        if cfg.angle_stages > 1:
            top = int(np.argmax([f[0] for f in found]))
            moved = settle(win, found[top][1])
            if moved is not None:
                sc, a = search(moved, [found[top][1]], step / 3)[0]
                out[top] = (sc, float(_wrap(a + psi)), moved.c)
        return out


def read_knobs(image, K, T_world_camera, priors, reader: KnobReader) -> tuple[list[KnobReading], float]:
    """Readings and the time they took (s)."""
    t0 = time.perf_counter()
    out = reader.read(image, K, T_world_camera, priors)
    return out, time.perf_counter() - t0


#: Stored readers (joblib files, hearth/worldmodel/model_store.py) name their classes by module:
#: these keep the module they were stored under before the reader was split into modules
#: (hearth.perception.knobs, which still exports them), so a stored model reads alike with this
#: code and earlier code, and neither makes the other retrain.
for _cls in (KnobReader,):
    _cls.__module__ = "hearth.perception.knobs"
