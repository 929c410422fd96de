"""The knob reader for a home: asked of the model store, trained for that home when it has none.

``load_or_train(world)`` gives the ``KnobReader`` trained for ``world``'s knobs: from memory,
from ``$HEARTH_MODEL_DIR`` (default ``~/.cache/hearth``, file ``knobs-<home>.joblib``), or
made now (hearth/perception/knob_training.py: a few seconds) and stored
(hearth/worldmodel/model_store.py). Each home has its own file, keyed by what of it the training
depends on (``world_signature``: its knobs and the appliances carrying them), so homes do not
invalidate each other; a file trained with other trained settings (``TrainingConfig``,
``KnobConfig.trained_fields``) is stale and retrained. ``hearth train knobs --world W`` trains
ahead of time and shows progress.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

from hearth.perception.errors import PerceptionError
from hearth.perception.knob_training import Progress, TrainingConfig, configuration, train, world_signature
from hearth.perception.knobs import KnobConfig, KnobReader
from hearth.worldmodel import model_store
from hearth.worldmodel.model_store import ModelInfo

MODEL_NAME = "knobs"

__all__ = ["MODEL_NAME", "ModelInfo", "TrainingConfig", "load_or_train", "check", "noise_model"]


def noise_model():
    """The simulated robot's Kinect noise model, applied to every training view."""
    from hearth.robot.noise import add_kinect_noise
    return add_kinect_noise


_noise = noise_model   # the name hearth/benchmarks/knobs.py imports


def _about(world) -> dict:
    return {"world": world.apartment.id, "file": str(getattr(world, "path", "") or "")}


def check(world, cfg: TrainingConfig = TrainingConfig(), knob: KnobConfig = KnobConfig(),
          directory: Optional[Path] = None) -> model_store.Loaded:
    """Whether a current knob model for ``world`` is stored (``Loaded.ok``, ``reason``)."""
    return model_store.load(MODEL_NAME, configuration(cfg, knob, noise_model()),
                            world_signature(world), directory)


def load_or_train(world, cfg: TrainingConfig = TrainingConfig(), knob: KnobConfig = KnobConfig(),
                  directory: Optional[Path] = None, retrain: bool = True, force: bool = False,
                  progress: Optional[Progress] = None) -> tuple[KnobReader, ModelInfo]:
    """The knob reader for ``world``, reading with ``knob``'s read-time settings. With
    ``retrain=False`` a missing or stale model is a PerceptionError instead."""
    noise = noise_model()
    try:
        reader, info = model_store.load_or_train(
            MODEL_NAME, configuration(cfg, knob, noise),
            lambda: train(world, cfg, knob, noise=noise, progress=progress),
            world=world_signature(world), directory=directory, retrain=retrain, force=force,
            about=_about(world))
    except model_store.ModelUnavailable as err:
        raise PerceptionError(f"knob models for this home: {err}; run `hearth train knobs "
                              f"--world {_about(world)['file'] or 'WORLD'}`") from None
    if reader.config != knob:
        # the gates as calibrated, the read-time settings the caller's (rebuilding the reader
        # from its state gates alone dropped its half-turn and dot gates)
        reader = reader.with_config(knob)
    return reader, info
