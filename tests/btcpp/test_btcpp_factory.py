"""BehaviorTree.CPP's own factory (behaviortreepy) loads and ticks what `hearth export`
writes, with Hearth's node types registered as stand-ins from the file's model."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("behaviortreepy")

from hearth.executive.btcpp import export_mission  # noqa: E402
from hearth.benchmarks import _btcpp  # noqa: E402
from hearth.benchmarks.executive import Work, mission_yaml  # noqa: E402


def test_every_shipped_mission_loads_in_btcpps_factory(shipped_mission):
    import behaviortreepy as bt
    st = _btcpp.standin_tree(export_mission(shipped_mission))
    assert st.tree.tick_exactly_once() == bt.NodeStatus.SUCCESS
    assert st.calls, "BT.CPP ticked no stand-in"


def test_btcpp_ticks_the_exported_tree_in_the_missions_order():
    st = _btcpp.standin_tree(export_mission(Path(_btcpp.__file__).parents[2] / "missions"
                                            / "refine_localisation.yaml"))
    st.tree.tick_exactly_once()
    # Every stand-in succeeds: "$at == here" holds, the first fix succeeds, then report.
    assert st.calls == ["Check", "RefineLocalisation", "DescribeCorrection", "report"]


def test_btcpps_factory_refuses_what_is_wrong(tmp_path):
    """The check is BT.CPP's own: a subtree's mandatory port left out, a built-in node's
    port that does not convert, a SubTree ID that names no tree."""
    xml = export_mission(Path(_btcpp.__file__).parents[2] / "missions" / "search_object.yaml")
    missing_port = xml.replace('<SubTree ID="look_here" object_id="{object_id}" place="{place}" pose="{pose}"/>',
                               '<SubTree ID="look_here" place="{place}" pose="{pose}"/>')
    assert missing_port != xml
    with pytest.raises(RuntimeError, match=r"mandatory port called \[object_id\]"):
        _btcpp.standin_tree(missing_port)
    no_tree = xml.replace('<SubTree ID="note"', '<SubTree ID="nowhere"')
    with pytest.raises(RuntimeError):
        _btcpp.standin_tree(no_tree)
    oven = export_mission(Path(_btcpp.__file__).parents[2] / "missions" / "turn_off_oven.yaml")
    bad_count = oven.replace('num_attempts="2"', 'num_attempts="two"')
    assert bad_count != oven
    with pytest.raises(RuntimeError):
        _btcpp.standin_tree(bad_count)
    with pytest.raises(ValueError, match="has no port 'speed'"):
        _btcpp.standin_tree(oven.replace('<NavigateTo target="{oven}"/>',
                                         '<NavigateTo target="{oven}" speed="2"/>'))


def test_the_benchmark_tree_runs_the_same_leaves_in_btcpp_and_hearth(tmp_path):
    """hearth bench executive's BT.CPP figure ticks the same work: over the same ticks,
    BT.CPP starts the Python leaves as often as Hearth starts its skills."""
    path = tmp_path / "bench.yaml"
    path.write_text(mission_yaml(0))
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock
    ticks = 40
    ex = Executive(clock=SimClock(), runs_dir=str(tmp_path / "runs"),
                   skills={"BenchWork": Work}, background=False)
    handle = ex.submit(str(path))
    for _ in range(ticks):
        ex.tick()
    handle.cancel("done")
    ex.run_until_idle(100)
    events = [json.loads(line) for line in open(handle.log_path)]
    hearth_starts = sum(1 for e in events if e["e"] == "status" and e["tick"] < ticks
                        and e["path"].rsplit("/", 1)[-1].startswith("w")
                        and e["previous"] != "RUNNING" and e["status"] != "INVALID")
    starts = []
    times = _btcpp.tick_times(str(path), {"BenchWork": Work}, ticks, warmup=0,
                              on_start=lambda name: starts.append(name))
    assert len(times) == ticks
    assert len(starts) == hearth_starts > 144
