"""`hearth run`, `step` and `serve` keep the belief map on disk: a restarted process starts
from what the last one learned. The shipped demo home is never written (its map is a copy in
$HEARTH_STATE_DIR); --map-out and --no-save say where, or that nothing is written."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hearth.cli.main import main
from hearth.executive.replay import read_log
from hearth import demo_world_path
from hearth.worldmodel import load_world


def _search_orders(log: str) -> list[str]:
    """The places of each "search order" the mission's first PlanSearch said."""
    _, events, _ = read_log(log)
    said = [e["message"] for e in events if e["e"] == "feedback"
            and e["path"].endswith("/PlanSearch") and e["message"].startswith("search order: ")]
    return said[0][len("search order: "):].split(", ")


@pytest.fixture
def cup_moved(tmp_path):
    """A scenario of the demo home where the blue cup is, in truth, on the side table
    (the map believes it on the kitchen table)."""
    from hearth.executive.scenarios import place_on
    from hearth.robot.scenario import Scenario, save_scenario
    from hearth.worldmodel.pose import Pose
    belief = load_world(demo_world_path())
    truth = belief.copy()
    assert place_on(truth, "blue_cup", "side_table", np.random.default_rng(0))
    start = belief.parking_positions("kitchen_table")[0][1]
    return save_scenario(Scenario(seed=0, belief=belief, truth=truth, start_pose=start,
                                  localisation_error=Pose()), tmp_path / "scenario")


def test_a_second_process_searches_where_the_first_found_the_object(cup_moved, tmp_path,
                                                                    _state_dir):
    before = demo_world_path().read_bytes()
    logs = []
    for run in (1, 2):
        runs = tmp_path / f"runs{run}"
        done = subprocess.run([sys.executable, "-m", "hearth", "run",
                               "missions/fetch_object.yaml", "--scenario", str(cup_moved),
                               "--param", "object=blue cup", "--runs-dir", str(runs)],
                              capture_output=True, text=True, timeout=600,
                              env={**os.environ, "HEARTH_STATE_DIR": str(_state_dir)})
        assert done.returncode == 0, done.stdout + done.stderr
        assert f"map saved to {_state_dir / 'demo_home' / 'world.xml'}" in done.stdout
        (log,) = runs.glob("*.jsonl")
        logs.append(str(log))
    assert _search_orders(logs[0])[0] == "kitchen_table"      # what the shipped map believes
    assert _search_orders(logs[1])[0] == "side_table"         # what the first run learned
    kept = load_world(_state_dir / "demo_home" / "world.xml")
    stats = kept.search_stats("blue_cup")
    assert stats["side_table"].found == 2 and stats["kitchen_table"].found == 0
    assert demo_world_path().read_bytes() == before           # the shipped file is untouched


def _searched_world(tmp_path) -> Path:
    """A world file whose map a search_object run changes (searched places are counted)."""
    path = tmp_path / "home" / "world.xml"
    path.parent.mkdir()
    path.write_bytes(demo_world_path().read_bytes())
    return path


def test_the_world_file_given_is_the_map_and_is_saved_after_the_run(tmp_path, capsys):
    world = _searched_world(tmp_path)
    assert main(["run", "missions/search_object.yaml", "--world", str(world),
                 "--param", "object=blue cup", "--runs-dir", str(tmp_path / "runs")]) == 0
    assert f"map saved to {world}" in capsys.readouterr().out
    assert load_world(world).search_stats("blue_cup")["kitchen_table"].found == 1


def test_map_out_keeps_the_map_elsewhere_and_carries_on_from_it(tmp_path, capsys):
    world = _searched_world(tmp_path)
    before = world.read_bytes()
    out = tmp_path / "kept.xml"
    for _ in range(2):
        assert main(["run", "missions/search_object.yaml", "--world", str(world),
                     "--map-out", str(out), "--param", "object=blue cup",
                     "--runs-dir", str(tmp_path / "runs")]) == 0
    assert world.read_bytes() == before
    assert load_world(out).search_stats("blue_cup")["kitchen_table"].found == 2


def test_no_save_leaves_the_map_as_it_was(tmp_path, capsys, _state_dir):
    world = _searched_world(tmp_path)
    before = world.read_bytes()
    assert main(["run", "missions/search_object.yaml", "--world", str(world), "--no-save",
                 "--param", "object=blue cup", "--runs-dir", str(tmp_path / "runs")]) == 0
    assert "map saved" not in capsys.readouterr().out
    assert world.read_bytes() == before
    assert main(["run", "missions/go_to_rest.yaml", "--no-save",
                 "--runs-dir", str(tmp_path / "runs")]) == 0
    assert not (_state_dir / "demo_home").exists()         # not even the copy is made


def test_map_out_and_no_save_together_are_refused(capsys):
    with pytest.raises(SystemExit) as err:
        main(["run", "missions/go_to_rest.yaml", "--map-out", "m.xml", "--no-save"])
    assert err.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_replay_leaves_its_map_as_it_was_unless_map_out_says(tmp_path):
    from hearth.cli.main import build_parser
    from hearth.cli.util import keeps_map
    parse = build_parser().parse_args
    assert keeps_map(parse(["run", "m.yaml"]))
    assert keeps_map(parse(["step", "m.yaml"]))
    assert keeps_map(parse(["serve"]))
    assert not keeps_map(parse(["run", "m.yaml", "--recording", "rec"]))
    assert keeps_map(parse(["run", "m.yaml", "--recording", "rec", "--map-out", "x.xml"]))
    assert not keeps_map(parse(["record", "m.yaml", "--out", str(tmp_path / "r")]))
    assert keeps_map(parse(["record", "m.yaml", "--out", str(tmp_path / "r"), "--map-out", "x"]))


def test_a_map_out_that_cannot_be_written_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["run", "missions/go_to_rest.yaml", "--map-out", str(blocker / "m.xml"),
                 "--runs-dir", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"{blocker / 'm.xml'}: cannot keep the map there") or \
        err.startswith(f"{blocker}: cannot keep the map there"), err
    assert "\n" not in err


def test_hearth_serve_keeps_what_its_missions_learn(tmp_path):
    import httpx
    world = _searched_world(tmp_path)
    proc = subprocess.Popen([sys.executable, "-m", "hearth", "serve", "--port", "0",
                             "--world", str(world), "--runs-dir", str(tmp_path / "runs")],
                            stderr=subprocess.PIPE, text=True)
    try:
        url = None
        for line in proc.stderr:
            if "http://" in line:
                url = line.split("http://", 1)[1].split("/", 1)[0]
            if f"the map is kept in {world}" in line:
                break
        assert url, "hearth serve did not start"
        with httpx.Client(base_url=f"http://{url}", timeout=60.0) as client:
            run = client.post("/api/runs", json={"mission": "search_object",
                                                 "params": {"object": "blue cup"}}).json()["run"]
            with client.stream("GET", "/api/events", params={"run": run["id"], "since": 0,
                                                             "close_on_end": True}) as r:
                data = [json.loads(line[6:]) for line in r.iter_lines()
                        if line.startswith("data: ")]
        ended = [d for d in data if d.get("e") == "run"][-1]
        assert ended["state"] == "succeeded", ended
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
        proc.stderr.close()
    assert load_world(world).search_stats("blue_cup")["kitchen_table"].found == 1
