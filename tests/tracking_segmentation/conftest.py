"""Shared fixtures: a small segmentation forest trained once per session on a few random
rendered rooms (the shipped configuration trains on 200 in the model cache)."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def small_forest():
    from hearth.skills.segmentation_model import TrainingConfig, train
    return train(TrainingConfig(frames=30, n_estimators=25, seed=77, homes=2, views_per_home=3))
