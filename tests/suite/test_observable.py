"""The suite counts a fetch case as achievable only where the robot can see the object:
some pose a search can take shows enough pixels of it (hearth.executive.scenarios.observable)."""
from __future__ import annotations

import numpy as np

from hearth.executive.scenarios import MIN_VISIBLE_PX, observable, place_observably, place_on
from hearth.benchmarks.objects import box_object
from hearth.robot.scenario import visible_pixels
from hearth.worldmodel.pose import Pose


def _enclose(world, object_id: str) -> None:
    """A closed box over the object: no ray reaches it."""
    obj = world.get(object_id)
    world.add_small_object(box_object("lid", (0.3, 0.3, 0.35), (0.5, 0.5, 0.5),
                                      Pose(obj.pose.x, obj.pose.y, obj.pose.z - 0.01)),
                           world.parent(object_id).id)


def test_an_object_on_a_table_is_seen_and_one_boxed_in_is_not(demo_world):
    n, pose = visible_pixels(demo_world, "blue_cup")
    assert n >= MIN_VISIBLE_PX and pose is not None
    assert observable(demo_world, "blue_cup")
    _enclose(demo_world, "blue_cup")
    assert visible_pixels(demo_world, "blue_cup") == (0, None)
    assert not observable(demo_world, "blue_cup")


def test_an_unobservable_spot_is_drawn_again_elsewhere(demo_world):
    # Every spot of the kitchen table is under a box: the cup goes to the next place.
    assert place_on(demo_world, "blue_cup", "kitchen_table", np.random.default_rng(0))
    world = demo_world
    top = world.get("kitchen_table").surfaces[0]
    world.add_small_object(box_object("cover", (top.size_x + 0.1, top.size_y + 0.1, 0.4),
                                      (0.5, 0.5, 0.5), Pose(top.pose.x, top.pose.y, top.pose.z)),
                           "kitchen_table")
    assert place_observably(world, "blue_cup", "kitchen_table", np.random.default_rng(1),
                            fallback=["side_table"])
    assert world.parent("blue_cup").id == "side_table"
    assert observable(world, "blue_cup")
