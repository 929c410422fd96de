"""`hearth scenario make`, `hearth record` and replaying the recording with `hearth run`."""
from __future__ import annotations

import json

from hearth.cli.main import main


def test_record_a_simulated_oven_mission_and_replay_it(tmp_path, capsys):
    sc, rec, runs = tmp_path / "sc", tmp_path / "rec", tmp_path / "runs"
    assert main(["scenario", "make", "--seed", "5", "--out", str(sc)]) == 0
    assert "knob: knob=oven_knob_2, state=4" in capsys.readouterr().out
    status = main(["record", "missions/turn_off_oven.yaml", "--scenario", str(sc), "--out",
                   str(rec), "--runs-dir", str(runs), "--quiet"])
    err = capsys.readouterr().err
    assert status == 0, err
    assert "turn_off_oven: succeeded (completed); recorded 4 captures to" in err
    manifest = json.loads((rec / "manifest.json").read_text())
    captures = [json.loads(line) for line in (rec / "captures.jsonl").read_text().splitlines()]
    actions = [json.loads(line) for line in (rec / "actions.jsonl").read_text().splitlines()]
    assert manifest["version"] == 2 and len(captures) == 4
    assert all(c["truth"]["T_world_camera"] for c in captures)
    assert [a.get("action") for a in actions].count("turn_knob") == 1
    status = main(["run", "missions/turn_off_oven.yaml", "--recording", str(rec),
                   "--world", str(sc / "belief.xml"), "--runs-dir", str(runs)])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "ReadKnobs: knobs: oven_knob_1 off, oven_knob_2 4" in out


def test_run_on_a_recording_of_unknown_version_is_one_clear_line(tmp_path, capsys):
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "manifest.json").write_text('{"format": "hearth-recording", "version": 3}')
    assert main(["run", "missions/turn_off_oven.yaml", "--recording", str(rec),
                 "--runs-dir", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"{rec / 'manifest.json'}: unknown recording version 3 (this Hearth reads versions 1, 2)")
