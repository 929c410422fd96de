"""The segmentation forest's views of generated homes (hearth/perception/segmentation_training.py
``home_views``) stand on free floor: a step back from a parking position never puts the camera
inside a piece of furniture, whose inside gives a view with no depth (training home 700008 of
generator version 10 stepped back into its fridge)."""
from __future__ import annotations

import numpy as np

from hearth.perception.segmentation_training import home_views
from hearth.worldmodel.homegen import generate_home
from hearth.worldmodel.navigation import nav_grid


def test_training_views_of_a_home_stand_on_free_floor():
    world = generate_home(700008)
    grid = nav_grid(world)
    rng = np.random.default_rng(700008)
    views = home_views(world, rng, 300)      # no rendering: poses only
    assert len(views) >= 250
    for T in views:
        x, y = T[0, 3], T[1, 3]
        # the eye is 0.1 m ahead of where the robot stands: the floor under it is free
        # of furniture
        assert grid.label[grid.cell(x, y)] <= 0, grid.blocked_by(x, y)
