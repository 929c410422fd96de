"""The mission suite's navigation figures (docs/navigation.md, "Measured"): path length
against the straight line, and the drives the simulated robot refused with their reasons."""
from __future__ import annotations

import re
from pathlib import Path

from hearth.executive.scenarios import _drives, _refused_drives, navigation_summary
from hearth.robot.adapter import wait
from hearth.robot.clock import SimClock
from hearth.robot.simulated import SimulatedRobot
from hearth.worldmodel import parse_world

FLAT = re.search(rb'FLAT = b"""(.*?)"""', (Path(__file__).parents[1] / "worldmodel"
                                          / "test_rooms_doorways.py").read_bytes(), re.S).group(1)


def test_the_suite_counts_path_over_straight_and_refused_drives_with_their_reasons():
    world = parse_world(FLAT, "flat.xml")
    clock = SimClock()
    robot = SimulatedRobot(world.copy(), clock, start_pose=world.parking_pose("table", "south"))
    for goal in [("counter", "front"), ("shelf", "front"), ("table", "north"),
                 ("shelf", "front")]:
        wait(robot.navigate_to(world.parking_pose(*goal)), clock)
    drives, refused = _drives(robot), _refused_drives(robot)
    assert len(drives) == 2 and len(refused) == 2
    assert all(p >= s for p, s in drives)
    out = navigation_summary([{"drives": drives, "refused_drives": refused}])
    assert out["drives"] == 2 and out["refused_drives"] == 2
    assert out["path_over_straight_median"] >= 1.0
    # both refusals are the same kind: the store room has no doorway
    (kind, n), = out["refused_reasons"].items()
    assert n == 2 and kind.startswith("no path to (x, y): no way from (x, y) to (x, y)")
