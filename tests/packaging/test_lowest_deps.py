"""Dependency floors: every requirement has one, and at the lowest versions pyproject.toml
allows every module imports and the CLI validates and runs (scripts/lowest-deps.sh).

The full check downloads the oldest allowed wheels (about 250 MB) into a fresh virtual
environment and takes several minutes, so it runs only with HEARTH_LOWEST_DEPS=1
(`make lowest-deps` runs the script directly)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import lowest_pins  # noqa: E402


def test_every_dependency_has_a_floor_and_py_trees_has_for_each():
    reqs = {r.name.lower(): r for r in lowest_pins.requirements(ROOT / "pyproject.toml")}
    for r in reqs.values():
        assert any(s.operator in (">=", "==", "~=") for s in r.specifier), f"{r} has no floor"
    # hearth/executive/nodes.py subclasses py_trees.decorators.ForEach, new in py_trees 2.4.0
    assert not reqs["py_trees"].specifier.contains("2.3.0")
    assert reqs["py_trees"].specifier.contains("2.4.0")
    assert "joblib" in reqs and "filterpy" not in reqs


def test_every_module_imports_here():
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_all.py")],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "modules imported" in done.stdout


@pytest.mark.timeout(1800)
@pytest.mark.skipif(os.environ.get("HEARTH_LOWEST_DEPS") != "1",
                    reason="downloads the oldest allowed wheels (~250 MB, several minutes): "
                           "set HEARTH_LOWEST_DEPS=1 or run `make lowest-deps`")
def test_hearth_imports_and_runs_at_the_lowest_allowed_versions():
    done = subprocess.run(["bash", str(ROOT / "scripts" / "lowest-deps.sh")],
                          capture_output=True, text=True)
    if "cannot list the versions" in done.stderr:
        pytest.skip(f"the package index cannot be reached: {done.stderr.strip().splitlines()[-1]}")
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    assert "import-all:" in done.stdout and done.stdout.rstrip().endswith("lowest-deps: ok")
