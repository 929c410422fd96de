"""The semantic-segmentation forest, asked of the model store and trained on first use.

``load_or_train()`` gives the forest: from memory, from ``segmentation.joblib`` in
``$HEARTH_MODEL_DIR`` (default ``~/.cache/hearth``), or trained now on rendered random rooms
and generated homes (hearth/perception/segmentation_training.py, a few minutes on two cores) and
stored (hearth/worldmodel/model_store.py). The rooms and homes are not the user's home, so one forest
serves every home: its file is keyed by the training configuration (``TrainingConfig`` and
``SegmentationConfig.trained_fields``) only, and a file trained with other settings is stale
and retrained. Training views get the simulated robot's Kinect noise (``noisy``); the homes
come from hearth.worldmodel.homegen (``training_home``; their meshes go to its cache directory).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Optional

import numpy as np

from hearth.perception.errors import PerceptionError
from hearth.perception.segmentation import PatchClassifier, SegmentationConfig
from hearth.perception import segmentation_training as _training
from hearth.perception.segmentation_training import TrainingConfig, class_of_node, ground_truth
from hearth.worldmodel import model_store
from hearth.worldmodel.model_store import ModelInfo, model_dir

MODEL_NAME = "segmentation"
MODEL_FILE = model_store.path_of(MODEL_NAME, directory=Path(".")).name

__all__ = ["MODEL_FILE", "MODEL_NAME", "ModelInfo", "TrainingConfig", "check", "class_of_node",
           "get", "ground_truth", "load_or_train", "model_dir", "noisy", "render_random", "train",
           "training_home"]


def noise_model() -> Callable:
    """The simulated robot's Kinect noise model."""
    from hearth.robot.noise import add_kinect_noise
    return add_kinect_noise


def training_home(seed: int):
    """A generated home to train on (hearth.worldmodel.homegen, meshes in its cache directory)."""
    from hearth.worldmodel.homegen import generate_home
    return generate_home(seed)


def _home_version() -> int:
    from hearth.worldmodel import homegen
    return int(getattr(homegen, "GENERATOR_VERSION", 1))


def noisy(rendering, rng: np.random.Generator):
    """The simulated robot's Kinect noise on a rendering, in place."""
    return _training.noisy(rendering, rng, noise_model())


def render_random(seed: int, K=None, look_up: float = 0.0):
    """One random training-style view with the robot's noise (see
    ``hearth.perception.segmentation_training.render_random``)."""
    return _training.render_random(seed, K, look_up, noise_model())


def train(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None,
          progress: Optional[Callable[[str, int, int], None]] = None) -> PatchClassifier:
    """A forest trained now with the robot's noise model (not stored)."""
    return _training.train(cfg, seg, noise_model(), progress=progress, home=training_home)


def _configuration(cfg: TrainingConfig, seg: SegmentationConfig) -> dict:
    return _training.configuration(cfg, seg, noise_model(), training_home, _home_version())


def check(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None,
          directory: Optional[Path] = None) -> model_store.Loaded:
    """Whether a current forest is stored (``Loaded.ok``, ``reason``)."""
    return model_store.load(MODEL_NAME, _configuration(cfg or TrainingConfig(),
                                                       seg or SegmentationConfig()),
                            directory=directory)


def get(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None,
        directory: Optional[Path] = None, retrain: bool = True, force: bool = False,
        log: Optional[Callable[[str], None]] = None,
        progress: Optional[Callable[[str, int, int], None]] = None
        ) -> tuple[PatchClassifier, ModelInfo]:
    """The forest and where it came from; ``retrain=False``: a missing or stale model is a
    PerceptionError."""
    cfg, seg = cfg or TrainingConfig(), seg or SegmentationConfig()
    try:
        clf, info = model_store.load_or_train(MODEL_NAME, _configuration(cfg, seg),
                                              lambda: train(cfg, seg, progress), directory=directory,
                                              retrain=retrain, force=force)
    except model_store.ModelUnavailable as err:
        raise PerceptionError(f"segmentation forest: {err}; run `hearth train segmentation`") from None
    if log and info.source == "trained":
        log(f"trained segmentation forest in {info.seconds:.0f} s -> {info.path}")
    return clf, info


def load_or_train(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None,
                  directory: Optional[Path] = None, log: Optional[Callable[[str], None]] = None
                  ) -> PatchClassifier:
    """The forest alone (see ``get``)."""
    return get(cfg, seg, directory, log=log)[0]
