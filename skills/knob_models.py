"""The knob models (detector, angle forest, angle SVR): training from the map's knobs,
storage (skills/models_store.py) and loading with staleness checks.

**Trained on first use**, not shipped: ``load_or_train(world)`` looks for ``knobs.joblib``
in the model directory (``$HEARTH_MODEL_DIR``, default ``~/.cache/hearth``); when it is
missing or stale (trained with another configuration or other knobs) it trains (about two
to three minutes on two cores with the default configuration) and stores the result. The
stored configuration holds ``TrainingConfig``, the reader's ``KnobConfig`` and the map's
knobs (id, radius, depth, colours, pose): a changed knob makes the model stale.
``hearth train knobs --world W`` trains ahead of time and shows progress.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from perception.errors import PerceptionError
from perception.knob_data import (
    KnobDataConfig, KnobScenes, calibrate_threshold, hard_negatives, render_views, scene_negatives,
    training_patches,
)
from perception.knobs import KnobAngleForest, KnobAngleSVR, KnobConfig, KnobDetector, KnobReader
from skills import models_store

MODEL_NAME = "knobs"
#: Bump when the training data or the features change in a way the configuration misses.
CODE_VERSION = 4


@dataclass(frozen=True)
class TrainingConfig:
    """``views``: rendered knob views; ``angle_patches`` / ``positives`` / ``negatives``:
    windows cut from each; ``scene_views``: views of other surfaces for negatives (4 windows
    each); ``hard_negatives``: at most this many windows the first detector wrongly scores
    high are added for a second fit (0: none); ``validation_views``: views (``validation_missing``
    of them without the knob) on which the detector's threshold is calibrated
    (``calibrate_threshold``; 0: the SVM's boundary, 0); ``seed``: training seeds are ``seed``
    .. ``seed + 3`` (benchmarks use others)."""
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


def knob_signature(world) -> list[dict]:
    """What of the map's knobs the models depend on."""
    out = []
    for k in sorted(world.knobs(), key=lambda k: k.id):
        out.append(dict(id=k.id, radius=round(float(k.radius), 5), depth=round(float(k.depth), 5),
                        color=[round(float(c), 3) for c in k.color],
                        marker=[round(float(c), 3) for c in k.marker_color],
                        pose=[round(float(v), 4) for v in k.pose.as_tuple()]))
    return out


def _noise():
    """The simulated robot's Kinect noise model when it is there."""
    try:
        from hearth.robot.noise import add_kinect_noise
        return add_kinect_noise
    except ImportError:
        return None


#: The KnobConfig fields the training depends on; the others (thresholds, the angle method)
#: are read-time settings and can change without retraining.
TRAINED_FIELDS = ("px_per_radius", "search_px", "scales", "view_aligned")


def configuration(world, cfg: TrainingConfig, knob: KnobConfig) -> dict:
    reader = {k: v for k, v in asdict(knob).items() if k in TRAINED_FIELDS}
    return {"code_version": CODE_VERSION, "training": asdict(cfg), "reader": reader,
            "knobs": knob_signature(world), "robot_noise": _noise() is not None}


def _with_config(reader: KnobReader, knob: KnobConfig) -> KnobReader:
    return reader if reader.config == knob else KnobReader(reader.detector, reader.forest,
                                                           reader.svr, knob)


Progress = Callable[[str, int, int], None]


def train(world, cfg: TrainingConfig = TrainingConfig(), knob: KnobConfig = KnobConfig(),
          progress: Optional[Progress] = None) -> KnobReader:
    """Render the training views, cut windows and fit the three estimators."""
    say = progress or (lambda stage, done, total: None)
    scenes = KnobScenes(world)
    views = render_views(world, cfg.views, cfg.seed, cfg.data, knob, noise=_noise(), scenes=scenes,
                         progress=lambda d, n: say("rendering knob views", d, n))
    say("rendering knob views", cfg.views, cfg.views)
    det_p, det_y, ang_p, ang_y = training_patches(views, cfg.seed + 1, knob, cfg.positives,
                                                  cfg.negatives, cfg.angle_patches)
    say("rendering other surfaces", 0, cfg.scene_views)
    neg = scene_negatives(world, cfg.scene_views, cfg.seed + 2, knob, cfg.data, scenes=scenes)
    say("rendering other surfaces", cfg.scene_views, cfg.scene_views)
    det_p = np.concatenate([det_p, neg])
    det_y = np.concatenate([det_y, np.zeros(len(neg), dtype=int)])
    say(f"fitting detector (HOG + linear SVM, {len(det_y)} windows)", 0, 3)
    detector = KnobDetector(C=cfg.detector_C).fit(det_p, det_y)
    if cfg.hard_negatives:
        hard = hard_negatives(views, detector, knob, limit=cfg.hard_negatives)
        say(f"refitting detector with {len(hard)} hard negatives", 0, 3)
        det_p = np.concatenate([det_p, hard])
        det_y = np.concatenate([det_y, np.zeros(len(hard), dtype=int)])
        detector = KnobDetector(C=cfg.detector_C).fit(det_p, det_y)
    if cfg.validation_views:
        val = render_views(world, cfg.validation_views, cfg.seed + 3,
                           replace(cfg.data, missing_rate=cfg.validation_missing), knob, noise=_noise(),
                           scenes=scenes, progress=lambda d, n: say("rendering validation views", d, n))
        cal = calibrate_threshold(val, detector, knob)
        detector.threshold_ = cal.threshold
        detector.calibration_ = asdict(cal)
        say(f"detector threshold {cal.threshold:+.3f} (validation: recall {cal.recall:.3f}, "
            f"false detections {cal.false_positive_rate:.3f} of {cal.empty} empty regions)", 0, 3)
    say(f"fitting angle forest ({cfg.forest_trees} trees, {len(ang_y)} windows)", 1, 3)
    forest = KnobAngleForest(n_estimators=cfg.forest_trees, random_state=cfg.seed).fit(ang_p, ang_y)
    say("fitting angle SVR (cos, sin)", 2, 3)
    svr = KnobAngleSVR(C_grid=cfg.svr_C_grid, random_state=cfg.seed).fit(ang_p, ang_y)
    say("done", 3, 3)
    return KnobReader(detector, forest, svr, knob)


_CACHE: dict = {}


@dataclass
class ModelInfo:
    path: Path
    source: str   # "memory", "disk" or "trained"
    seconds: float = 0.0
    reason: str = ""


def load_or_train(world, cfg: TrainingConfig = TrainingConfig(), knob: KnobConfig = KnobConfig(),
                  directory: Optional[Path] = None, retrain: bool = True, force: bool = False,
                  progress: Optional[Progress] = None) -> tuple[KnobReader, ModelInfo]:
    """The knob reader for ``world``: from memory, from disk, or trained now and stored; it
    reads with ``knob``'s read-time settings. With ``retrain=False`` a missing or stale model is a PerceptionError instead."""
    config = configuration(world, cfg, knob)
    key = (str(models_store.path_of(MODEL_NAME, directory)), models_store.fingerprint(config))
    if key in _CACHE and not force:
        return _with_config(_CACHE[key], knob), ModelInfo(Path(key[0]), "memory")
    loaded = models_store.load(MODEL_NAME, config, directory)
    if loaded.ok and not force:
        _CACHE[key] = loaded.model
        return _with_config(loaded.model, knob), ModelInfo(loaded.path, "disk")
    if not retrain and not force:
        raise PerceptionError(f"knob models {loaded.reason} ({loaded.path}); "
                              "run `hearth train knobs`")
    t0 = time.perf_counter()
    reader = train(world, cfg, knob, progress)
    seconds = time.perf_counter() - t0
    try:
        path = models_store.save(MODEL_NAME, reader, config, directory)
    except OSError:
        path = loaded.path   # read-only model directory: keep the model in memory only
    _CACHE[key] = reader
    return reader, ModelInfo(path, "trained", seconds, loaded.reason if not force else "forced")
