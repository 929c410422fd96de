"""Shared fixtures."""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

# Property tests draw new examples on every run (they found the near-square table in
# search_positions); CI (.ci/run sets HYPOTHESIS_PROFILE=ci) draws the same ones every time,
# so that its verdict is about the change, not the draw.
settings.register_profile("ci", derandomize=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

ROOT = Path(__file__).resolve().parents[1]
DEMO_WORLD = ROOT / "data" / "demo_home" / "world.xml"


@pytest.fixture
def demo_world_path() -> Path:
    return DEMO_WORLD


@pytest.fixture
def demo_world():
    from hearth.worldmodel import load_world
    return load_world(DEMO_WORLD)


@pytest.fixture
def clean_blackboard():
    """An empty py_trees blackboard (it is global) before the test and after it."""
    import py_trees
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


def pytest_configure(config):
    # Before any fixture, whatever its scope, copies the environment for a subprocess: the
    # suite never keeps a map in the real ~/.local/share/hearth.
    config._hearth_state = os.environ["HEARTH_STATE_DIR"] = tempfile.mkdtemp(
        prefix="hearth-test-state-")


def pytest_unconfigure(config):
    state = getattr(config, "_hearth_state", None)
    if state:
        shutil.rmtree(state, ignore_errors=True)


@pytest.fixture(autouse=True)
def _state_dir(tmp_path_factory, monkeypatch):
    """Each test keeps the maps it runs on in a state directory of its own
    (``$HEARTH_STATE_DIR``; subprocesses inherit it): no test writes into
    ~/.local/share/hearth, and no test starts from what another one learned."""
    path = tmp_path_factory.mktemp("state")
    monkeypatch.setenv("HEARTH_STATE_DIR", str(path))
    return path
