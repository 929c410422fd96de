"""A suite killed half-way (kill -9) resumes where it stopped: the results already in the
file are kept as they are, only the rest is run, and the report covers all of them."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

from hearth.cli.main import main

ARGS = ["suite", "--no-demo", "--homes", "1", "--missions", "refine_localisation",
        "--scenarios", "4", "--jobs", "1", "--engine", "local"]


def lines(path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.endswith("}")]


def test_a_killed_suite_resumes_without_running_again_what_was_done(tmp_path, capsys):
    out = tmp_path / "suite"
    results = out / "results.jsonl"
    proc = subprocess.Popen([sys.executable, "-m", "hearth", *ARGS, "--out", str(out),
                             "--quiet"], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t0 = time.monotonic()
        while len(lines(results)) < 2 and proc.poll() is None and time.monotonic() - t0 < 300:
            time.sleep(0.2)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    before = lines(results)
    assert 2 <= len(before) < 4, "the suite was not stopped half-way"
    capsys.readouterr()
    status = main([*ARGS, "--out", str(out), "--resume", "--json"])
    report = json.loads(capsys.readouterr().out)
    after = lines(results)
    assert status == 0
    assert after[:len(before)] == before                 # kept as they were, not run again
    assert len(after) == 4 and len({r["key"] for r in after}) == 4
    assert report["resumed"] == len(before) and report["ran"] == 4 - len(before)
    assert report["results"] == 4 and (out / "summary.png").stat().st_size > 0


def test_a_mission_the_suite_has_no_scenarios_for_is_one_line_and_exit_2(capsys):
    import pytest
    for argv in (["suite", "--missions", "fetch_object,nope", "--homes", "0"],
                 ["bench", "missions", "--missions", "nope", "--homes", "0"]):
        with pytest.raises(SystemExit) as stop:
            main(argv)
        assert stop.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err[-1].endswith("argument --missions: no scenarios for 'nope'; the suite has "
                                "scenarios for fetch_object, search_object, turn_off_oven, "
                                "refine_localisation")
        assert not any("Traceback" in line for line in err)
