"""A short soak through the HTTP API (the long one is `hearth bench soak`): every cancel
answered 202 is honoured, no cancelled or preempted run leaves the simulated robot's timed
actions going, every submitted run has a log that ends with its outcome, none is stuck."""
from __future__ import annotations

from hearth.benchmarks.soak import soak


def test_soak_of_submits_cancels_preempts_and_parameter_changes_keeps_every_promise(tmp_path):
    r = soak(missions=12, clients=2, seed=3, tick_hz=50.0, drain_s=60.0,
             runs_dir=str(tmp_path / "runs"))
    assert r["errors"] == [] and r["missions"] == 12
    assert r["cancels_accepted"] >= 1 and r["parameter_changes"] >= 1
    assert (r["cancels_not_honoured"], r["robot_left_moving"], r["runs_without_log_end"],
            r["runs_stuck"]) == (0, 0, 0, 0)
    assert len(list((tmp_path / "runs").glob("*.jsonl"))) == 12
