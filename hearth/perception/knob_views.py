"""Where to read a knob from again: base poses on free floor around its appliance, ranked by how
likely the reader is to give the knob's state from there.

A knob left unknown (the reader's gates refused its reading) is most often one seen small or
obliquely: a round grip's marker a few pixels across, a front panel at 0.3 m looked down on
from a camera 1.3 m up. The declared parking positions and the one pose straight in front of
the panel are a few fixed places (and the one in front is often not free: a table, a wall);
here any free pose around the appliance may be chosen, by what the reader would make of the
knob from it.

**Geometry of a view** (``view_of``): from a camera pose, a knob's radius in pixels
(``fx * radius / range``, as ``KnobReader.evidence`` measures it) and how far off its axis
the camera is (``off_axis_deg``); whether its centre falls in the image with a margin.

**What the reader makes of such a view** (``readability``): the reader keeps the validation
readings its gates were calibrated on (``KnobReader.validation_``: rendered views of each knob
of this home from 0.5-1.5 m and up to 60 degrees off axis, each with its ``radius_px``,
``off_axis``, margin and whether its angle snapped to the true state). A reading *is given*
when its state is the true one and its margin (and half-turn or rival check) passes the gate of
its view level, the gate as ``KnobReader.read_one`` applies it. The chance a new view of knob k
is given is the kernel-weighted share of k's validation readings that were, near that view
(Gaussian in log radius, ``size_sigma``, and in off-axis degrees, ``angle_sigma``), with
``prior_weight`` pseudo-readings of the knob's share over its views of the same view level
(so that a view smaller or more oblique than any validation view takes the share of the
smallest, most oblique ones, not of all): a knob no view of which was given scores 0 everywhere, and the ranking then says so with numbers rather than
driving about. A reader without validation readings (made before they were kept) falls back on
the view level alone (``LEVEL_PRIOR``).

**Ranking** (``rank_views``): every candidate base pose (the caller's: free floor, with the
camera aimed at the knobs' centre) scores the expected number of unread knobs read from it
(the sum of their readabilities; a knob whose line of sight passes through another large
object's box scores 0 there); poses closer than ``min_apart`` to a better one, or to a pose
already read from, are dropped (a second reading needs another place: ``OffViews``), and so
are poses that score no more than the view the knobs were just left unread from (``beat``:
another view no better is not a better view; the mission's straight looks follow anyway).
Ties go to the pose nearer the robot.

Pure functions: poses, priors and readings in, ranked poses out. Choosing the candidates on
the map's free floor and aiming the head are the caller's (hearth/skills/knob_views.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional, Sequence

import numpy as np

from hearth.perception.camera import Intrinsics
from hearth.perception.knob_canvas import off_axis_deg
from hearth.perception.knob_gates import view_level
from hearth.perception.knob_priors import KnobPrior

#: A view's score by its view level (0 near, 1 hard, 2 very hard) when the reader kept no
#: validation readings (readers made before training code version 36; ``load_or_train``
#: retrains those, so only a reader passed in by hand lacks them). An ordering, not a measured
#: chance: near before hard before very hard, each under the readings a reader gives.
LEVEL_PRIOR = (0.6, 0.3, 0.2)


@dataclass(frozen=True)
class KnobViewConfig:
    """``size_sigma`` (natural log of the radius in pixels) and ``angle_sigma`` (degrees): the
    kernel over validation readings; ``prior_weight``: pseudo-readings of the knob's own mean;
    ``edge_px``: a knob's centre must lie this far inside the image; ``min_apart`` (m): poses
    kept at least this far apart, and from poses already read from; ``max_off_axis_deg`` and
    ``min_radius_px``: a view more oblique or smaller is not read at all (the reader's own,
    ``KnobConfig``; ``for_reader``)."""
    size_sigma: float = 0.25
    angle_sigma: float = 10.0
    prior_weight: float = 2.0
    edge_px: float = 30.0
    min_apart: float = 0.3
    max_off_axis_deg: float = 75.0
    min_radius_px: float = 4.0
    #: nearer (camera to knob, m) the depth sensor has no reading (hearth.robot.noise's
    #: ``min_range`` 0.45) and the reader no validation view (they start at 0.5 m)
    min_range_m: float = 0.5

    @staticmethod
    def for_reader(reader, **kw) -> "KnobViewConfig":
        """The configuration with the reader's own limits of a view."""
        cfg = reader.config
        return KnobViewConfig(max_off_axis_deg=float(cfg.max_off_axis_deg),
                              min_radius_px=float(cfg.min_radius_px), **kw)


@dataclass
class KnobView:
    """One knob from one camera pose: its radius in pixels, degrees off its axis, whether it
    is in the image, its view level and the chance its state is given (``readability``)."""
    knob_id: str
    radius_px: float
    off_axis: float
    in_image: bool
    level: int
    p_read: float = 0.0
    occluded: bool = False


@dataclass
class RankedPose:
    """A base pose (x, y, yaw; world), the point to aim the camera at, the expected number of
    unread knobs read from it (``score``) and each knob's view."""
    x: float
    y: float
    yaw: float
    look_at: tuple
    score: float
    views: list

    def as_place(self) -> dict:
        """The pose as a search place NavigateTo and LookAt take."""
        return dict(x=round(self.x, 4), y=round(self.y, 4), yaw=round(self.yaw, 4),
                    look_at=[round(float(c), 4) for c in self.look_at],
                    expected_read=round(self.score, 3))


def view_of(prior: KnobPrior, T_world_camera: np.ndarray, K: Intrinsics,
            cfg: KnobViewConfig = KnobViewConfig()) -> KnobView:
    """The geometry of ``prior``'s knob seen from ``T_world_camera`` (its front face's centre)."""
    T_wc = np.asarray(T_world_camera, dtype=float)
    pc = (np.linalg.inv(T_wc) @ np.append(prior.T_world_face()[:3, 3], 1.0))[:3]
    rng = float(np.linalg.norm(pc))
    off = off_axis_deg(T_wc, prior)
    if pc[2] <= 0.05:
        return KnobView(prior.knob_id, 0.0, off, False, 2)
    u, v = K.fx * pc[0] / pc[2] + K.cx, K.fy * pc[1] / pc[2] + K.cy
    inside = (cfg.edge_px <= u < K.width - cfg.edge_px and cfg.edge_px <= v < K.height - cfg.edge_px
              and off <= cfg.max_off_axis_deg and rng >= cfg.min_range_m)
    r_px = K.fx * prior.radius / max(rng, 1e-6)
    return KnobView(prior.knob_id, r_px, off, bool(inside), view_level(r_px, off))


def given(reading: dict, reader) -> bool:
    """Whether a validation reading (``knob_training.validation_readings``) would have given
    its state, and the right one: right, its margin over the gate of its view level, and its
    half-turn (or, for a marker reading, rival) check over its gate."""
    if not (reading.get("found") and reading.get("near") and reading.get("right")):
        return False
    level, dot = int(reading.get("level", int(bool(reading.get("hard"))))), bool(reading.get("dot"))
    if reading.get("margin", 0.0) <= reader.margin_threshold_for(level, dot):
        return False
    turn = reading.get("rival") if dot else reading.get("half_turn")
    return turn is None or turn > reader.half_turn_gate_for(level, dot)


def validation_table(reader) -> dict:
    """Per knob id, an array of its validation views with depth: (ln radius px, degrees off
    axis, 1 if given else 0, view level). Empty for a reader that kept none."""
    kept = getattr(reader, "validation_", None) or {}
    rows: dict = {}
    for r in kept.get("depth", []) if isinstance(kept, dict) else []:
        if not r.get("present", True) or r.get("radius_px", 0.0) <= 0:
            continue
        off = float(r.get("off_axis", 0.0))
        rows.setdefault(r.get("knob"), []).append(
            (math.log(float(r["radius_px"])), off, float(given(r, reader)),
             float(view_level(float(r["radius_px"]), off))))
    return {k: np.asarray(v, dtype=float) for k, v in rows.items()}


def readability(table: dict, view: KnobView, cfg: KnobViewConfig = KnobViewConfig()) -> float:
    """The chance the reader gives ``view``'s knob its state from that view: the kernel share
    of the knob's validation views given near it (module docstring); ``LEVEL_PRIOR`` by its
    level without them; 0 out of the image."""
    if not view.in_image or view.radius_px < max(cfg.min_radius_px, 1e-6):
        return 0.0
    rows = table.get(view.knob_id)
    if rows is None or not len(rows):
        return LEVEL_PRIOR[view.level]
    d2 = (((rows[:, 0] - math.log(view.radius_px)) / cfg.size_sigma) ** 2
          + ((rows[:, 1] - view.off_axis) / cfg.angle_sigma) ** 2)
    w = np.exp(-0.5 * d2)
    same = rows[:, 3] == view.level if rows.shape[1] > 3 else np.ones(len(rows), bool)
    mean = float(rows[same, 2].mean() if same.any() else rows[:, 2].mean())
    return float((w @ rows[:, 2] + cfg.prior_weight * mean) / (w.sum() + cfg.prior_weight))


def _segment_hits_box(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether the segment a -> b passes through the axis-aligned box [lo, hi] (slab test)."""
    d = b - a
    t0, t1 = 0.0, 1.0
    for i in range(3):
        if abs(d[i]) < 1e-12:
            if a[i] < lo[i] or a[i] > hi[i]:
                return False
            continue
        ta, tb = (lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        if t0 > t1:
            return False
    return True


def occluded(eye, point, boxes: Sequence[tuple]) -> bool:
    """Whether the line of sight from ``eye`` to ``point`` (world) passes through one of
    ``boxes`` ((lo, hi) world bounds), its last 2 cm aside (the knob's own panel)."""
    a, b = np.asarray(eye, dtype=float), np.asarray(point, dtype=float)
    d = b - a
    n = float(np.linalg.norm(d))
    if n < 1e-6:
        return False
    b = a + d * max(0.0, (n - 0.02) / n)
    return any(_segment_hits_box(a, b, np.asarray(lo, float), np.asarray(hi, float)) for lo, hi in boxes)


def pose_views(want: Sequence[KnobPrior], aim, pose: tuple,
               camera_at: Callable[[float, float, float, np.ndarray], np.ndarray], K: Intrinsics,
               table: dict, blockers: Sequence[tuple] = (),
               cfg: KnobViewConfig = KnobViewConfig()) -> tuple[float, list]:
    """From base pose ``pose`` (x, y, yaw) with the camera aimed at ``aim``: the expected
    number of the ``want`` knobs read (the sum of their readabilities) and each one's view."""
    x, y, yaw = (float(c) for c in pose)
    T_wc = camera_at(x, y, yaw, np.asarray(aim, dtype=float))
    views = []
    for p in want:
        v = view_of(p, T_wc, K, cfg)
        if v.in_image and blockers and occluded(T_wc[:3, 3], p.T_world_face()[:3, 3], blockers):
            v.occluded, v.in_image = True, False
        v.p_read = readability(table, v, cfg)
        views.append(v)
    return float(sum(v.p_read for v in views)), views


def rank_views(priors: Sequence[KnobPrior], unread: Sequence[str], candidates: Sequence[tuple],
               camera_at: Callable[[float, float, float, np.ndarray], np.ndarray], K: Intrinsics,
               table: dict, robot_xy=(0.0, 0.0), tried: Sequence = (), blockers: Sequence[tuple] = (),
               cfg: KnobViewConfig = KnobViewConfig(), keep: int = 3,
               beat: float = 0.0) -> tuple[list[RankedPose], dict]:
    """The best ``keep`` of ``candidates`` ((x, y, yaw) base poses) to read the ``unread``
    knobs from, best first (module docstring), and per unread knob its best view over every
    candidate (a ``KnobView``: what the best free pose makes of it). ``camera_at(x, y, yaw,
    point)``: the camera pose there with the head aimed at ``point``; ``tried``: (x, y)
    already read from; ``blockers``: (lo, hi) world boxes a line of sight may not cross;
    ``beat``: a pose is kept only when it scores more than this (the score of the view the
    knobs were just left unread from: another view no better than it is not a better view)."""
    want = [p for p in priors if p.knob_id in set(unread)]
    if not want:
        return [], {}
    aim = np.mean([p.T_world_face()[:3, 3] for p in want], axis=0)
    scored = []
    for x, y, yaw in candidates:
        score, views = pose_views(want, aim, (x, y, yaw), camera_at, K, table, blockers, cfg)
        travel = math.hypot(x - robot_xy[0], y - robot_xy[1])
        scored.append((-round(score, 3), travel, RankedPose(float(x), float(y), float(yaw),
                                                            tuple(aim), score, views)))
    scored.sort(key=lambda s: s[:2])
    out: list[RankedPose] = []
    taken = [tuple(t) for t in tried]
    for _, _, r in scored:
        if r.score <= max(0.0, round(beat, 3)):
            break
        if any(math.hypot(r.x - tx, r.y - ty) < cfg.min_apart for tx, ty in taken):
            continue
        out.append(r)
        taken.append((r.x, r.y))
        if len(out) >= keep:
            break
    best: dict = {}
    for _, _, r in scored:
        for v in r.views:
            if v.knob_id not in best or (v.p_read, v.radius_px) > (best[v.knob_id].p_read,
                                                                   best[v.knob_id].radius_px):
                best[v.knob_id] = v
    return out, best


def ring(centre_xy, normal_xy: Optional[Sequence[float]], distances: Sequence[float],
         bearings_deg: Sequence[float]) -> list[tuple]:
    """Base poses around ``centre_xy`` facing it: at each distance, at each bearing (degrees)
    from ``normal_xy`` (the knobs' panel normal in the plane; None: all round)."""
    cx, cy = float(centre_xy[0]), float(centre_xy[1])
    base = 0.0 if normal_xy is None else math.atan2(normal_xy[1], normal_xy[0])
    out = []
    for d in distances:
        for b in bearings_deg:
            a = base + math.radians(b)
            x, y = cx + d * math.cos(a), cy + d * math.sin(a)
            out.append((x, y, math.atan2(cy - y, cx - x)))
    return out


def marker_width(shape) -> Optional[float]:
    """The width (m) of a knob's marker across its length (``shape``: a KnobShape), from the
    marker's vertices seen along the knob's axis; None for a knob without a marker."""
    pts = [v[:, :2] for v, r in zip(shape.vertices, shape.roles) if r == "marker"]
    if not pts:
        return None
    m = np.concatenate(pts)
    m = m - m.mean(0)
    return float(np.ptp(m @ np.linalg.svd(m, full_matrices=False)[2][-1]))
