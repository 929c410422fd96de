"""Fitting the knob reader (hearth/perception/knobs.py) for one home, from its knobs as the map
describes them.

``train(world, cfg, knob)`` makes the reader of ``world``'s knobs in seconds: the label-map
templates of every knob shape of the home (``KnobTemplates.fit``: renderings, nothing
learned), then the gates calibrated on validation views rendered from the map
(hearth/perception/knob_data.py: the home's own panels, neighbours, lighting and sensor noise, seeds
other than the benchmark's):

- ``detect_gate``: the fit (R^2) a knob's region needs to count as holding the knob, the
  middle of the lowest-error range between regions with the knob found where it is and
  regions without it (or with it found elsewhere);
- ``state_gate`` (and ``state_gate_hard``, ``state_gate_very_hard`` for harder views,
  ``view_level``): the margin over the best other state a reading needs, just above the
  largest margin of any validation reading of its level whose state was wrong (times
  ``margin_safety``, at least ``margin_floor``), so that no wrong reading of the validation
  views would pass. Readings of a round body's marker (evidence ``dot``) get gates of their
  own (``KnobReader.dot_gates``, their margin is in units of the angle's expected error), at
  least ``dot_margin_floor``: a state needs its angle at least that many expected errors
  inside its half step with a clear marker, however few wrong readings validation had; and
  ``dot_margin_safety`` (1.25) times the largest wrong margin. It was 2 until the rival
  gate (``dot_rival_gates``, which keeps out the dot read from a speck beside it): held-out
  views of home 1 had had wrong dot readings 1.14 and 1.32 times over a gate of 1.25 times.
  With the rival gate, 1.5 and then 1.25 let no held-out reading through wrong on homes
  0-19 and 777-796 (docs/knobs.md, "The marker's safety at 1.25");
- ``half_turn_gates``: for a knob without symmetry (other than a round body's dot reading),
  what a reading's comparison with itself turned by half a turn (``KnobReader._half_turn``)
  needs, chosen with the state gate of its level (the pair that lets the most right readings
  through while no wrong one passes both); with a half-turn gate, the state gate is
  calibrated on the level's readings and the next harder level's;
- ``dot_rival_gates``: the same for a round body's marker reading, of its comparison with
  the nearest other state where the two renderings differ (evidence ``rival``), chosen
  with the level's dot gate.

The gates are fitted on readings with the views' depth images, and again on readings of
colour alone (``KnobReader.colour_gates``, for a caller without depth).

``world_signature(world)`` is what of the home the result depends on, and
``configuration(cfg, knob)`` everything else: together they key the stored model
(hearth/worldmodel/model_store.py), so a model made for one home stays current when another home is
trained, and goes stale when a trained setting or a knob of its home changes.

Pure: the world object in, estimators out; nothing is written here.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from hearth.perception.knob_data import KnobDataConfig, KnobScenes, render_views, true_center_m
from hearth.perception.knob_canvas import off_axis_deg, to_rgb
from hearth.perception.knob_config import KnobConfig
from hearth.perception.knob_gates import CalibratedThreshold, hard_view, not_there, view_level
from hearth.perception.knob_priors import canon
from hearth.perception.knob_reading import KnobReader, snap_to_state
from hearth.perception.knob_shapes import knob_shape
from hearth.perception.knob_templates import KnobTemplates

#: Bump when the templates, the views or the gates change in a way the configuration misses.
CODE_VERSION = 37   # 37: the relief gate within relief_sigmas standard errors of the depth's slope (stands_se: a flat knob's relief is what the depth cannot pin); 36: the validation readings kept with the reader (``validation_``, each with its knob id), so gates can be calibrated again on other homes' readings (the knob bench's held-out families); 35: a dot reading's fit the exact check at the body centre and the dot's angle, neither moved; 34: no knob where the depth shows under min_relief of its relief (stands) or beyond max_offset_searches search radii (offset), the detect gate fitted on the others (the middle of the floor and the lowest positive where no negative is left); 33: the best coarse angle's half turn checked at the allowed angle nearest it (a knob that turns one way only); 32: body_center stops at steps under 0.1 mm, not 0.02; 31: dot_max_off_axis_deg 60, not 55 (the dot gates' readings); 30: the same with half a radius of slack; 29: a round body's measured top pixels kept by where their points are, not only by their projection on the top's plane (body_center); 28: a round body's depth put on its rendering by its top, not by the panel (body_center), and the marker's side seen obliquely in its profile (dot_profile); 27: a marker's readings beyond dot_max_off_axis_deg left out of the dot gates; 26: the dot margin's expected error as noise over contrast, the dominance cubed, no weak-marker factor (_dot_reading); 25: the coarse offset search's correlations as BLAS products of the canvas's windows (_windows), not matchTemplate calls (sums in another order); 24: readings the snap check refuses left out of the calibration at levels 0-1 (snap_free_levels); 23: a dot reading against the nearest other state (rival, dot_rival_gates); 22: the state next to the reading fitted, and taken where it fits better (_next_state); 21: the simulated noise draws changed order (colour levels)

_canon = canon   # the name earlier code imported


@dataclass(frozen=True)
class TrainingConfig:
    """``validation_views``: views the gates are calibrated on (``validation_missing`` of them
    without the knob), drawn with ``seed``; ``margin_safety`` / ``margin_floor``: the state
    gate's threshold is the largest margin of a wrong validation reading times the safety,
    and at least the floor (one threshold for views that are not hard, ``hard_view``, when
    there are at least ``min_easy_readings`` of them, and one, never lower, for hard ones);
    ``snap_free_levels``: at view levels below it, a reading (not of a round body's marker)
    whose angle the snap check refuses (``KnobConfig.max_snap``: it never gives a state,
    whatever the gates) is left out of the gates' calibration; at harder levels it counts;
    ``pool_nearest_levels``: a view level with fewer than ``min_easy_readings`` readings is
    calibrated together with the nearest levels, one at a time, the next harder first, until
    there are enough (False: with every harder level and the easier one, as before);
    ``data``: how views are drawn (hearth/perception/knob_data.py). Every field is part of the
    stored model's configuration."""
    validation_views: int = 400
    validation_missing: float = 0.25
    seed: int = 4
    margin_safety: float = 1.25
    margin_floor: float = 0.002
    dot_margin_floor: float = 1.0
    dot_margin_safety: float = 1.25
    min_easy_readings: int = 40
    snap_free_levels: int = 2
    pool_nearest_levels: bool = True
    data: KnobDataConfig = field(default_factory=lambda: KnobDataConfig(at_states=True))

    def tiny(self) -> "TrainingConfig":
        """A small configuration for tests (seconds)."""
        return replace(self, validation_views=80)


# -- what the models depend on ------------------------------------------------------------------

def _mesh_digests(world, knob) -> list:
    """SHA-256 prefixes of the mesh files a knob's shape names (a changed file is another
    design, though its name is the same)."""
    from hearth.worldmodel.geometry import knob_parts
    out = []
    for _role, v, _turns in knob_parts(knob, world.apartment.library):
        if v.shape == "mesh" and v.file:
            path = Path(world.base_dir or ".") / v.file
            try:
                out.append(hashlib.sha256(path.read_bytes()).hexdigest()[:16])
            except OSError:
                out.append("unreadable")
    return out


def world_signature(world) -> dict:
    """What of a home the knob reader is made from: every knob's shape (radius, depth,
    colours, its base, grip and marker and the contents of their mesh files, symmetry),
    where it sits on its appliance, how high its face is and how its axis leans (the views
    stand 0.25-2 m above the floor), and the geometry of the appliances that carry knobs
    (their models, parts, joints and handles in the appliance's frame). Left out: the knobs'
    discrete states, which way they turn and their off state (the templates cover the full
    turn; the reader snaps to the map's states when it reads), current knob angles and door
    states, where an appliance stands in the home, and the rest of the furniture: they
    change as the robot works or the user edits the map, and the reader needs no refitting
    for them."""
    from hearth.worldmodel.geometry import model_visuals
    lib = world.apartment.library
    knobs, carriers = [], {}
    for k in sorted(world.knobs(), key=lambda k: k.id):
        T = world.T_world(k.id)
        knobs.append(dict(canon(k, frozenset({"state", "angle", "off_state", "states", "turns"})),
                          shape_models=[canon(model_visuals(m, lib)) for m in (k.base, k.grip, k.marker)
                                        if m is not None],
                          meshes=_mesh_digests(world, k),
                          face_height=round(float((T @ [0, 0, k.depth, 1])[2]), 4),
                          axis_z=round(float(T[2, 2]), 4)))
        obj = world.large_object_of(k.id)
        carriers.setdefault(obj.id, obj)

    def part(p):
        return dict(id=p.id, model=canon(model_visuals(p.model, lib)),
                    joint=canon(p.joint, frozenset({"state"})),
                    handles=canon(p.handles), parts=[part(c) for c in p.parts])

    return dict(knobs=knobs, appliances=[
        dict(id=o.id, model=canon(model_visuals(o.model, lib)),
             handles=canon(getattr(o, "handles", [])),
             parts=[part(p) for p in getattr(o, "parts", [])])
        for o in carriers.values()])


def configuration(cfg: TrainingConfig, knob: KnobConfig, noise: Optional[Callable] = None) -> dict:
    """Everything but the home the reader depends on: the training configuration, the
    reader's trained fields (``KnobConfig.trained_fields``) and the sensor noise model."""
    return {"code_version": CODE_VERSION, "training": asdict(cfg), "reader": knob.trained_fields(),
            "noise": None if noise is None else f"{noise.__module__}.{noise.__qualname__}"}


# -- fitting ----------------------------------------------------------------------------------------

Progress = Callable[[str, int, int], None]


def shapes_of(world) -> list:
    """The ``KnobShape`` of every knob of the home (one per design)."""
    lib = world.apartment.library
    out = {}
    for k in world.knobs():
        s = knob_shape(k, lib, world.base_dir)
        out.setdefault(s.key, s)
    return list(out.values())


def validation_readings(reader: KnobReader, views, use_depth: bool = True) -> list[dict]:
    """The reader's evidence on rendered views (no gates): per view whether the knob was
    there, found where it is (within half a radius of its true centre), the fit, the margin
    and whether the state its angle snaps to is the true one."""
    out = []
    for v in views:
        r = reader.evidence(to_rgb(v.image), v.K, v.T_world_camera, v.believed,
                            v.depth if use_depth else None)
        near = False
        if r.found and v.present:
            cx, cy = true_center_m(v)
            near = math.hypot(r.detection.center_m[0] - cx, r.detection.center_m[1] - cy) <= 0.5 * v.truth.radius
        state, inside = snap_to_state(r.angle, v.believed) if r.found else (None, 1.0)
        out.append(dict(knob=v.truth.knob_id, present=bool(v.present), found=bool(r.found), near=near,
                        score=float(r.evidence.get("score", 0.0)),
                        margin=float(r.evidence.get("margin", 0.0)),
                        half_turn=r.evidence.get("half_turn"), rival=r.evidence.get("rival"),
                        stands=r.evidence.get("stands"), stands_se=r.evidence.get("stands_se"),
                        offset=r.evidence.get("offset"),
                        angle=r.angle,
                        right=bool(state == v.state), off=bool(state == v.believed.off_state),
                        snap=round(1.0 - float(inside), 6),
                        shape=v.believed.shape, dot=bool(r.evidence.get("dot", False)),
                        radius_px=float(r.evidence.get("radius_px", 0.0)),
                        off_axis=off_axis_deg(v.T_world_camera, v.believed),
                        hard=hard_view(float(r.evidence.get("radius_px", 0.0)),
                                       off_axis_deg(v.T_world_camera, v.believed)),
                        level=view_level(float(r.evidence.get("radius_px", 0.0)),
                                         off_axis_deg(v.T_world_camera, v.believed))))
    return out


def _level_of(r: dict) -> int:
    """A validation reading's ``view_level`` (readings made before the levels: 0 or 1 by
    ``hard``)."""
    return r.get("level", int(bool(r.get("hard"))))


def calibrate(reader: KnobReader, readings: list[dict], cfg: TrainingConfig) -> KnobReader:
    """The reader with its gates fitted on validation readings (module docstring)."""
    # a reading whose depth shows too little of the knob's relief, or that stands far beyond
    # where the knob was looked for, is no knob whatever its fit (``not_there``): the detect
    # gate is fitted on the others
    readings = [r for r in readings if not not_there(r, reader.config)]
    looked = [r for r in readings if r["found"] or not r["present"]]
    det = CalibratedThreshold("fewest_errors").fit(
        np.array([[r["score"]] for r in looked] or [[0.0]]),
        np.array([r["present"] and r["near"] for r in looked] or [False]))
    passed = [r for r in readings if r["found"] and r["present"] and r["near"] and r["score"] > det.threshold_]
    # a reading the snap check refuses (its angle in the outer part of the half step between
    # two states) gives no state whatever the gates, so at the easier levels it need not set
    # them: wrong readings 20-30 degrees off, between two states, held the gates of small
    # knobs seen from above (home 16: a half-turn gate of 0.81 at every level). At the very
    # hard level they still count: there they stand for wrong readings just inside the
    # limit (left out there too, two held-out very hard views of homes 16 and 18 were read
    # wrong; docs/knobs.md, "Readings the snap check refuses")
    max_snap = reader.config.max_snap
    passed = [r for r in passed if r.get("dot") or r.get("snap") is None or r["snap"] <= max_snap
              or _level_of(r) >= cfg.snap_free_levels]
    # readings whose angle came from a round body's marker (``KnobReader._dot_reading``) have
    # a margin of their own (in expected errors of the angle), so they get gates of their own,
    # never under ``dot_margin_floor`` (a tiny validation set may hold no wrong one: a dot
    # too small to see then read a fixed speck of noise as a state at margin 0.02). Those seen
    # more obliquely than ``KnobConfig.dot_max_off_axis_deg`` never give a state: they set
    # no gate either
    dots = [r for r in passed if r.get("dot") and r.get("off_axis", 0.0) <= reader.config.dot_max_off_axis_deg]
    passed = [r for r in passed if not r.get("dot")]
    gates, turns = _level_gates(passed, cfg)
    out = KnobReader(reader.templates, det, gates[0], reader.config, state_gate_hard=gates[1])
    out.state_gate_very_hard = gates[2]
    out.half_turn_gates = [float(t) for t in turns]
    # dot readings carry no half-turn comparison but one with the nearest other state
    # (``rival``), which takes its place in their gates: each level's pair of dot gate and
    # rival gate lets the most right readings through while no wrong one passes both
    if dots:
        out.dot_gates, rival = _level_gates([dict(r, half_turn=r.get("rival")) for r in dots], cfg,
                                            cfg.dot_margin_floor, cfg.dot_margin_safety)
        out.dot_rival_gates = [float(t) for t in rival]
    return out


def gates_from(reader: KnobReader, readings: dict, cfg: TrainingConfig = TrainingConfig()) -> KnobReader:
    """``reader`` (its templates and read-time settings) with every gate chosen again on
    ``readings`` ({"depth": [...], "colour": [...]}, ``validation_readings`` of any homes'
    views: the knob bench pools other design families' readings here, so that the figure of
    a family is read through gates none of its readings chose)."""
    out = calibrate(reader, list(readings["depth"]), cfg)
    out.colour_gates = calibrate(reader, list(readings["colour"]), cfg)
    out.validation_ = readings
    return out


def _level_gates(passed: list[dict], cfg: TrainingConfig, floor: Optional[float] = None,
                 safety: Optional[float] = None) -> tuple[list[CalibratedThreshold], list[float]]:
    """The state gates and the half-turn gates of the three view levels, calibrated on
    ``passed`` readings, the state gates at least ``floor`` (default: ``margin_floor``),
    ``safety`` times the largest wrong margin (default: ``margin_safety``)."""
    floor = cfg.margin_floor if floor is None else floor
    safety = cfg.margin_safety if safety is None else safety

    def gate(rs):
        return CalibratedThreshold("no_false_accepts", safety=safety, floor=floor).fit(
            np.array([[r["margin"]] for r in rs] or [[0.0]]), np.array([r["right"] for r in rs] or [True]))

    def turned(r, g):
        """Whether a reading passes the half-turn gate ``g``."""
        return r.get("half_turn") is None or r["half_turn"] > g

    def gates_of(rs, wider):
        """The half-turn gate and the state gate of a level (its readings ``rs``): none and
        the state gate of ``rs`` as without the half-turn test, or a half-turn gate just above
        one wrong reading's ``half_turn`` (times the safety, and at least 0: a reading that
        explains where it and its half turn differ worse than the half turn does is never
        enough) with the state gate calibrated on the readings of ``wider`` (the level and
        the next harder one) that it lets through; whichever lets the most right readings of
        the level through (none of equals)."""
        s = gate(rs)
        best = (sum(r["right"] and r["margin"] > s.threshold_ for r in rs), -math.inf, s)
        for h in sorted({r["half_turn"] for r in wider if not r["right"] and r.get("half_turn") is not None}):
            g = max(0.0, h * cfg.margin_safety)
            s = gate([r for r in wider if turned(r, g)])
            n = sum(r["right"] and r["margin"] > s.threshold_ and turned(r, g) for r in rs)
            if n > best[0]:
                best = (n, g, s)
        return best[1], best[2]
    # one gate for every view, and one for the hard ones (far, small, oblique: hard_view),
    # never below the first, so that a few confident wrong readings far away do not make
    # every near knob unknown, and a hard view needs what the hard views of validation needed
    # and the hard views split again: the very hard ones (view_level 2: under 8 px, more than
    # 55 degrees off) get their own, so that one confident wrong reading at 59 degrees does
    # not make every view at 46 unknown. A level with too few readings takes the gate of
    # itself and its nearest levels together, one level at a time (the next harder first)
    # until there are enough (``pool_nearest_levels``): taken with every harder level, the
    # near, clear views of a hob seen from above (home 12: 16 validation readings at level 0)
    # got the gates of its very hard views (knobs 5-7 px across, wrong readings with
    # ``half_turn`` up to 0.72), and so did level 1, whose gate may not be below level 0's;
    # no level's gate is below an easier one's.
    # A reading of a knob without symmetry also needs to explain the pixels where it and
    # itself turned by half a turn differ better than the turned knob does (``half_turn``,
    # KnobReader._half_turn): most confident wrong readings were such half turns. Each level
    # has a half-turn gate too, chosen with its state gate (``gates_of``), neither below an
    # easier level's: still no wrong validation reading passes both. With the half turns
    # left out, a level's state gate rests on its few other wrong readings (home 4: a level-0
    # gate on one reading's margin, 0.006, let through a wrong reading of held-out views), so
    # with a half-turn gate the state gate is calibrated on the level's readings and those of
    # the next harder level together.
    gates, turns = [], []
    for level in range(3):
        rs = [r for r in passed if _level_of(r) == level]
        if len(rs) < cfg.min_easy_readings and cfg.pool_nearest_levels:
            # the next harder level first, then the easier one, one level at a time
            lo, hi = level, level
            while len(rs) < cfg.min_easy_readings and (lo > 0 or hi < 2):
                lo, hi = (lo, hi + 1) if hi < 2 else (lo - 1, hi)
                rs = [r for r in passed if lo <= _level_of(r) <= hi]
        elif len(rs) < cfg.min_easy_readings:
            rs = [r for r in passed if _level_of(r) >= max(level - 1, 0)]
        harder = [] if any(_level_of(r) == level + 1 for r in rs) else [
            r for r in passed if _level_of(r) == level + 1]
        t, g = gates_of(rs, rs + harder)
        if gates and g.threshold_ < gates[-1].threshold_:
            g = gates[-1]
        if turns and t < turns[-1]:
            t = turns[-1]
        gates.append(g)
        turns.append(t)
    return gates, turns


def _read_views(reader: KnobReader, views, jobs: int = -1) -> tuple[list[dict], list[dict]]:
    """``validation_readings`` of ``views`` with their depth images and on colour alone, in
    the views' order; the work split in chunks over ``jobs`` processes (joblib)."""
    import multiprocessing
    import os
    n_jobs = min(4, os.cpu_count() or 1) if jobs in (None, -1) else max(1, int(jobs))
    if multiprocessing.current_process().daemon:
        # a worker of a pool (the mission suite's): it may start no processes of its own
        # (joblib would fall back to one with a warning on every training)
        n_jobs = 1
    if n_jobs == 1 or len(views) < 40:
        return validation_readings(reader, views), validation_readings(reader, views, use_depth=False)
    from joblib import Parallel, delayed
    k = 2 * n_jobs
    chunks = [views[i * len(views) // k:(i + 1) * len(views) // k] for i in range(k)]
    tasks = [(c, d) for d in (True, False) for c in chunks]
    out = Parallel(n_jobs=n_jobs)(delayed(validation_readings)(reader, c, d) for c, d in tasks)
    flat = lambda parts: [r for part in parts for r in part]
    return flat(out[:k]), flat(out[k:])


def train(world, cfg: TrainingConfig = TrainingConfig(), knob: KnobConfig = KnobConfig(),
          noise: Optional[Callable] = None, progress: Optional[Progress] = None,
          jobs: int = -1) -> KnobReader:
    """Make the reader of ``world``'s knobs: templates of their shapes, then the gates on
    validation views. ``noise(rendering, rng)``: the sensor model applied to every view (e.g.
    the simulated robot's Kinect noise); ``progress(stage, done, total)`` is called now and
    then. ``jobs``: processes reading the validation views (-1: one per core, at most 4; 1:
    in this process)."""
    say = progress or (lambda stage, done, total: None)
    shapes = shapes_of(world)
    say(f"rendering templates of {len(shapes)} knob shape{'s' if len(shapes) != 1 else ''}", 0, len(shapes))
    tm = KnobTemplates(px_per_radius=knob.px_per_radius, window_radii=knob.window_radii,
                       alpha_step_deg=knob.alpha_step_deg, theta_step_deg=knob.theta_step_deg,
                       max_theta_deg=knob.max_theta_deg).fit(shapes)
    say("rendering templates", len(shapes), len(shapes))
    # gates that let everything through until they are calibrated
    open_gate = CalibratedThreshold("no_false_accepts", floor=-1.0).fit([[0.0]], [True])
    reader = KnobReader(tm, open_gate, open_gate, knob)
    if not cfg.validation_views:
        return reader
    scenes = KnobScenes(world)
    views = render_views(world, cfg.validation_views, cfg.seed,
                         replace(cfg.data, missing_rate=cfg.validation_missing), knob, noise=noise,
                         scenes=scenes, progress=lambda d, n: say("rendering validation views", d, n))
    say("reading validation views", 0, len(views))
    # the gates of readings with the depth image, and those of readings on colour alone
    # (a caller without depth): the two passes over the views, in chunks, on ``jobs``
    # processes (joblib; -1: every core, at most 4)
    with_depth, colour_only = _read_views(reader, views, jobs)
    colour = calibrate(reader, colour_only, cfg)
    reader = calibrate(reader, with_depth, cfg)
    reader.colour_gates = colour
    # the evidence the gates were chosen on, kept so that gates can be chosen again on other
    # readings (the knob bench's leave-one-family-out protocol pools other homes' readings)
    reader.validation_ = dict(depth=with_depth, colour=colour_only)
    d, s = reader.detect_gate, reader.state_gate
    say(f"gates: fit > {d.threshold_:.3f} ({d.validation_['positives_passed']}/"
        f"{d.validation_['positives']} knobs, {d.validation_['negatives_passed']}/"
        f"{d.validation_['negatives']} empty regions pass); margin > {s.threshold_:.4f} "
        f"({s.validation_['negatives']} wrong readings, none pass); half turn > "
        f"{', '.join(f'{t:.2f}' for t in reader.half_turn_gates)}", len(views), len(views))
    return reader
