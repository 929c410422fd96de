"""What docs/missions.md shows is what ships."""
from __future__ import annotations

import re
from pathlib import Path

from hearth import missions_dir

DOCS = Path(__file__).resolve().parents[2] / "docs"


def test_the_first_mission_in_the_docs_is_the_shipped_go_to_rest():
    text = (DOCS / "missions.md").read_text()
    section = text.split("## A first mission", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"```yaml\n(.*?)```", section, re.S).group(1)
    assert block == (missions_dir() / "go_to_rest.yaml").read_text()
