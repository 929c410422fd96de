"""Suite tests: the stand-in runner (standins.py) importable by name, so that spawned workers
find it, and one Ray instance with 2 CPUs for every Ray test of the session."""
from __future__ import annotations

import logging
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope="session")
def ray_instance():
    """A local Ray instance with 2 CPUs (skipped, with the reason, without Ray). The engines
    use it and leave it running; it stops at the end of the session."""
    ray = pytest.importorskip("ray", reason="Ray is not installed: pip install 'hearth[ray]'")
    if not ray.is_initialized():
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
                 logging_level=logging.ERROR)
    yield ray
    ray.shutdown()
