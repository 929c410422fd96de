"""Training the knob models (perception/knobs.py) for one home, from renderings of its knobs.

``train(world, cfg, knob)`` renders views of the knobs as ``world`` describes them (their
designs, sizes, states and the appliances they sit on, see perception/knob_data.py), cuts
windows from them and fits the detector (with one round of hard negatives and a threshold
calibrated on validation views), the angle forest and the angle SVR; it returns a
``KnobReader``. ``world_signature(world)`` is what of the home the result depends on, and
``configuration(cfg, knob)`` everything else: together they key the stored model
(worldmodel/model_store.py), so a model trained for one home stays current when another home
is trained, and goes stale when a trained setting or a knob of its home changes.

Pure: the world object in, estimators out; nothing is read or written here.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from typing import Callable, Optional

import numpy as np

from perception.knob_data import (
    KnobDataConfig, KnobScenes, calibrate_threshold, hard_negatives, render_views, scene_negatives,
    training_patches,
)
from perception.knobs import (
    ANGLE_HOG, KnobAngleForest, KnobAngleSVR, KnobConfig, KnobDetector, KnobReader, hog_features,
)

#: Bump when the training data or the features change in a way the configuration misses.
CODE_VERSION = 5


@dataclass(frozen=True)
class TrainingConfig:
    """``views``: rendered knob views; ``angle_patches`` / ``positives`` / ``negatives``:
    windows cut from each; ``scene_views``: views of other surfaces for negatives (4 windows
    each); ``hard_negatives``: at most this many windows the first detector wrongly scores
    high are added for a second fit (0: none); ``validation_views``: views (``validation_missing``
    of them without the knob) on which the detector's threshold is calibrated
    (``calibrate_threshold``; 0: the SVM's boundary, 0); ``seed``: training seeds are ``seed``
    .. ``seed + 3`` (benchmarks use others). Every field is part of the stored model's
    configuration."""
    views: int = 3000
    angle_patches: int = 4
    positives: int = 3
    negatives: int = 6
    scene_views: int = 400
    seed: int = 1
    detector_C: float = 0.01
    hard_negatives: int = 8000
    validation_views: int = 600
    validation_missing: float = 0.3
    forest_trees: int = 100
    svr_C_grid: tuple[float, ...] = (0.03, 0.3)
    data: KnobDataConfig = field(default_factory=KnobDataConfig)

    def tiny(self) -> "TrainingConfig":
        """A small configuration for tests (seconds, not minutes)."""
        return replace(self, views=260, angle_patches=3, scene_views=40, forest_trees=30,
                       svr_C_grid=(0.1,), hard_negatives=1000, validation_views=120)


# -- what the models depend on ------------------------------------------------------------------

def _canon(value, drop: frozenset = frozenset()):
    """A JSON-able, rounded copy of map nodes (dataclasses) without ``line`` fields, and
    without the fields of ``value`` itself named in ``drop``."""
    if is_dataclass(value):
        return {f.name: _canon(getattr(value, f.name)) for f in fields(value)
                if f.name != "line" and f.name not in drop}
    if isinstance(value, (list, tuple)):
        return [_canon(v) for v in value]
    if isinstance(value, float):
        return round(value, 6)
    return value


def world_signature(world) -> dict:
    """What of a home the knob models are trained from: every knob's design (radius, depth,
    colours), where it sits on its appliance, how high its face is and how its axis leans
    (the training cameras stand 0.25-2 m above the floor), and the geometry of the appliances
    that carry knobs (their models, parts, joints and handles in the appliance's frame).
    Left out: the knobs' discrete states (the models read any angle over the full turn; the
    reader snaps it to the map's states when it reads), current knob angles and door states,
    where an appliance stands in the home, and the rest of the furniture (seen behind the
    knobs and used for negatives): they change as the robot works or the user edits the map,
    and the models do not need retraining for them."""
    from worldmodel.geometry import model_visuals
    lib = world.apartment.library
    knobs, carriers = [], {}
    for k in sorted(world.knobs(), key=lambda k: k.id):
        T = world.T_world(k.id)
        knobs.append(dict(_canon(k, frozenset({"state", "angle", "off_state", "states"})),
                          face_height=round(float((T @ [0, 0, k.depth, 1])[2]), 4),
                          axis_z=round(float(T[2, 2]), 4)))
        obj = world.large_object_of(k.id)
        carriers.setdefault(obj.id, obj)

    def part(p):
        return dict(id=p.id, model=_canon(model_visuals(p.model, lib)),
                    joint=_canon(p.joint, frozenset({"state"})),
                    handles=_canon(p.handles), parts=[part(c) for c in p.parts])

    return dict(knobs=knobs, appliances=[
        dict(id=o.id, model=_canon(model_visuals(o.model, lib)),
             handles=_canon(getattr(o, "handles", [])),
             parts=[part(p) for p in getattr(o, "parts", [])])
        for o in carriers.values()])


def configuration(cfg: TrainingConfig, knob: KnobConfig, noise: Optional[Callable] = None) -> dict:
    """Everything but the home the models depend on: the training configuration, the reader's
    trained fields (``KnobConfig.trained_fields``) and the sensor noise model."""
    return {"code_version": CODE_VERSION, "training": asdict(cfg), "reader": knob.trained_fields(),
            "noise": None if noise is None else f"{noise.__module__}.{noise.__qualname__}"}


# -- training ---------------------------------------------------------------------------------------

Progress = Callable[[str, int, int], None]


def train(world, cfg: TrainingConfig = TrainingConfig(), knob: KnobConfig = KnobConfig(),
          noise: Optional[Callable] = None, progress: Optional[Progress] = None,
          jobs: int = -1) -> KnobReader:
    """Render the training views of ``world``'s knobs, cut windows and fit the three
    estimators. ``noise(rendering, rng)``: the sensor model applied to every view (e.g. the
    simulated robot's Kinect noise); ``progress(stage, done, total)`` is called now and then;
    ``jobs``: threads for the forest's trees and the SVR's fits (-1: every core). The angle
    models are fitted in threads of their own while the detector is (scikit-learn's solvers
    and OpenCV release the GIL); the result does not depend on the threads."""
    say = progress or (lambda stage, done, total: None)
    scenes = KnobScenes(world)
    views = render_views(world, cfg.views, cfg.seed, cfg.data, knob, noise=noise, scenes=scenes,
                         progress=lambda d, n: say("rendering knob views", d, n))
    say("rendering knob views", cfg.views, cfg.views)
    det_p, det_y, ang_p, ang_y = training_patches(views, cfg.seed + 1, knob, cfg.positives,
                                                  cfg.negatives, cfg.angle_patches)
    ang_f = hog_features(ang_p, ANGLE_HOG)      # once, for both angle models
    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="angle-models") as pool:
        say(f"fitting angle forest ({cfg.forest_trees} trees) and SVR on {len(ang_y)} windows, "
            f"beside the detector", 0, 2)
        forest = pool.submit(KnobAngleForest(n_estimators=cfg.forest_trees, random_state=cfg.seed,
                                             n_jobs=jobs).fit, ang_f, ang_y)
        svr = pool.submit(KnobAngleSVR(C_grid=cfg.svr_C_grid, random_state=cfg.seed,
                                       n_jobs=jobs).fit, ang_f, ang_y)
        detector = _fit_detector(world, views, det_p, det_y, scenes, cfg, knob, noise, say)
        forest, svr = forest.result(), svr.result()
    say("done", 3, 3)
    return KnobReader(detector, forest, svr, knob)


def _fit_detector(world, views, det_p, det_y, scenes, cfg: TrainingConfig, knob: KnobConfig,
                  noise, say) -> KnobDetector:
    """Negatives from other surfaces, a first fit, hard negatives and a second fit, and the
    threshold calibrated on validation views."""
    say("rendering other surfaces", 0, cfg.scene_views)
    neg = scene_negatives(world, cfg.scene_views, cfg.seed + 2, knob, cfg.data, scenes=scenes)
    say("rendering other surfaces", cfg.scene_views, cfg.scene_views)
    det_p = np.concatenate([det_p, neg])
    det_y = np.concatenate([det_y, np.zeros(len(neg), dtype=int)])
    say(f"fitting detector (HOG + linear SVM, {len(det_y)} windows)", 0, 3)
    detector = KnobDetector(C=cfg.detector_C).fit(det_p, det_y)
    if cfg.hard_negatives:
        hard = hard_negatives(views, detector, knob, limit=cfg.hard_negatives)
        say(f"refitting detector with {len(hard)} hard negatives", 1, 3)
        det_p = np.concatenate([det_p, hard])
        det_y = np.concatenate([det_y, np.zeros(len(hard), dtype=int)])
        detector = KnobDetector(C=cfg.detector_C).fit(det_p, det_y)
    if cfg.validation_views:
        val = render_views(world, cfg.validation_views, cfg.seed + 3,
                           replace(cfg.data, missing_rate=cfg.validation_missing), knob, noise=noise,
                           scenes=scenes, progress=lambda d, n: say("rendering validation views", d, n))
        cal = calibrate_threshold(val, detector, knob)
        detector.threshold_ = cal.threshold
        detector.calibration_ = asdict(cal)
        say(f"detector threshold {cal.threshold:+.3f} (validation: recall {cal.recall:.3f}, "
            f"false detections {cal.false_positive_rate:.3f} of {cal.empty} empty regions)", 2, 3)
    return detector
