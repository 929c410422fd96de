"""Every accuracy benchmark is a function of its seed: run twice on the same small set, it
prints the same JSON, timings aside (a figure that moves between identical runs cannot tell
a change from noise, and a scene a user reports could not be replayed)."""
from __future__ import annotations

import re

import pytest

from tests.benchmarks.conftest import bench_json

#: Keys that are measurements of time or of the machine's load, not of accuracy.
_TIMING = re.compile(r"(^|_)(ms|s|hz|cpu|wall|load|time|avg|average|fps)(_|$)|_s_|per_s")


def without_timings(value):
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if not _TIMING.search(str(k))}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def test_timing_keys_are_told_from_figures():
    out = without_timings({"ms_per_view_median": 3, "plan_cpu_ms_median": 1, "train_s": 2,
                           "load_average_1min": 0.5, "hz": 30, "scenes": 4, "scenes_tried": 9,
                           "recognised_within_two_views": 0.9, "occlusion_avoided": 0.8,
                           "per_world": {"w": {"ms_per_knob": 8, "state_accuracy": 0.93}}})
    assert out == {"scenes": 4, "scenes_tried": 9, "recognised_within_two_views": 0.9,
                   "occlusion_avoided": 0.8, "per_world": {"w": {"state_accuracy": 0.93}}}


@pytest.mark.parametrize("argv", [
    ("nbv", "--quick", "--scenarios", "2"),
    ("objects", "--quick", "--scenarios", "3"),
    ("tracking", "--quick", "--scenarios", "1", "--frames", "12"),
    ("registration", "--quick", "--scenarios", "1"),
], ids=lambda a: a[0])
def test_a_benchmark_run_twice_prints_the_same_figures(capsys, tiny_home, argv):
    args = [*argv, "--no-demo", "--world", str(tiny_home), "--no-progress"]
    first = without_timings(bench_json(capsys, *args))
    second = without_timings(bench_json(capsys, *args))
    assert first == second
