"""docs/architecture.md's worked example (a skill and a mission that uses it) runs as written:
the skill, the mission and the Python that runs it on the simulated home are the page's own
code blocks."""
from __future__ import annotations

import json
import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)


def test_the_worked_example_counts_and_says_it(tmp_path, monkeypatch):
    skill_code, run_code = blocks("python")
    (mission_text,) = blocks("yaml")
    mission = tmp_path / "count_things.yaml"
    mission.write_text(mission_text, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "worked_example"}
    exec(compile(skill_code, "docs/architecture.md (skill)", "exec"), ns)
    exec(compile(run_code.replace("missions/count_things.yaml", str(mission)),
                 "docs/architecture.md (run)", "exec"), ns)
    result = ns["handle"].result
    assert result.outcome == "succeeded"
    tally = result.outputs["tally"]
    assert tally["place"] == "kitchen table" and tally["count"] >= 1
    said = [line for line in (tmp_path / "runs").glob("*.jsonl")
            for line in line.read_text().splitlines() if "I count" in line]
    assert said, "Say did not speak the count"
    counted = [json.loads(line) for f in (tmp_path / "runs").glob("*.jsonl")
               for line in f.read_text().splitlines() if "objects on" in line]
    assert any((e.get("values") or {}).get("count") == tally["count"] for e in counted), \
        "the skill's feedback does not carry its count as a value"
