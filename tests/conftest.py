"""Shared fixtures."""
from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DEMO_WORLD = ROOT / "data" / "demo_home" / "world.xml"


@pytest.fixture
def demo_world_path() -> Path:
    return DEMO_WORLD


@pytest.fixture
def demo_world():
    from worldmodel import load_world
    return load_world(DEMO_WORLD)
