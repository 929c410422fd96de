"""`hearth map draw` takes -o as every other command that writes a file does."""
from __future__ import annotations

import hearth
from hearth.cli.main import main


def test_map_draw_writes_the_png_named_by_short_o(tmp_path, capsys):
    png = tmp_path / "map.png"
    assert main(["map", "draw", str(hearth.demo_world_path()), "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
