"""Tiny knob models, trained once per test session in a temporary model directory."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def knob_model_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("knob_models")


@pytest.fixture(scope="session")
def reader(knob_model_dir):
    from hearth.skills.knob_models import TrainingConfig, load_or_train
    from tests.conftest import DEMO_WORLD
    from hearth.worldmodel import load_world
    r, info = load_or_train(load_world(DEMO_WORLD), TrainingConfig().tiny(), directory=knob_model_dir)
    assert info.source in ("trained", "memory")
    return r
