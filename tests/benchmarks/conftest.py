"""A tiny generated home (one turned kitchen, a few small objects) for the benchmarks' JSON
tests: every benchmark on worlds must run on a home it has never seen."""
from __future__ import annotations

import pytest


def make_tiny_home(directory):
    from hearth.worldmodel.homegen import HomeConfig, make_home
    return make_home(1, directory, HomeConfig(rooms=(1, 1), small_objects=(3, 4)))


@pytest.fixture(scope="session")
def tiny_home(tmp_path_factory):
    return make_tiny_home(tmp_path_factory.mktemp("tiny_home"))


def bench_json(capsys, *argv) -> dict:
    """What `hearth bench ARGV --json` prints, parsed."""
    import json
    from hearth.cli.main import main
    capsys.readouterr()
    assert main(["bench", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)
