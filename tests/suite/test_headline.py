"""`hearth suite`'s first line counts the scenarios its tables count: warm-up runs (which fill
the learned search order) are named apart, not added in."""
from __future__ import annotations

from hearth.executive import suite_report


def _result(i: int, learned: bool) -> dict:
    return {"key": f"k{i}", "mission": "fetch_object", "world": "home_1", "seed": i,
            "learned": learned, "achievable": True, "correct": True, "outcome": "succeeded",
            "reason": "", "wall_time_s": 1.0, "sim_time_s": 2.0, "positions_visited": 1}


def test_the_headline_counts_the_scenarios_of_the_table_and_names_warm_ups_apart():
    results = [_result(i, learned=i >= 4) for i in range(11)]       # 4 warm-ups, 7 counted
    rep = suite_report.report(results)
    rep["engine"] = "local"
    table = sum(c["scenarios"] for c in rep["per_mission"].values())
    assert table == 7 and rep["warmup_runs"] == 4
    line = suite_report.headline(rep, ran=11, wall_s=3.0)
    assert line.startswith("7 scenarios and 4 warm-up runs (11 run now on local")
    assert suite_report.render_text(rep).splitlines()[2].split()[1] == "7"
