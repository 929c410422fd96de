"""`hearth bench robot` times the simulated camera on every world it is given, not only the
demo home."""
from __future__ import annotations

import json


def test_bench_robot_renders_the_demo_and_a_generated_home(capsys):
    from hearth.cli.main import main
    assert main(["bench", "robot", "--json", "--quick", "--homes", "1"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["worlds"] == ["demo", "home:0"]
    assert set(out["per_world"]) == {"demo", "home:0"}
    for w in out["per_world"].values():
        assert w["render_640x480_ms"] > 0 and w["views"] >= 1 and w["triangles"] > 100
    medians = sorted(w["render_640x480_ms"] for w in out["per_world"].values())
    assert medians[0] <= out["render_640x480_ms_pooled"] <= medians[-1]
    assert out["per_world"]["demo"]["render_640x480_ms"] == out["render_640x480_ms"]
