"""Every small object of the demo home is fetched from where the map says it is (the
simulated robot, real perception and skills): not one favourite object, each of them."""
from __future__ import annotations

import pytest

from hearth import demo_world_path, missions_dir
from hearth.worldmodel import load_world

OBJECTS = sorted(o.id for o in load_world(demo_world_path()).small_objects() if o.graspable)


@pytest.mark.parametrize("object_id", OBJECTS)
def test_each_small_object_of_the_demo_home_is_fetched_where_the_map_says(object_id):
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock
    from hearth.robot.simulated import SimulatedRobot

    belief = load_world(demo_world_path())
    clock = SimClock()
    robot = SimulatedRobot(belief.copy(), clock=clock, seed=0)
    ex = Executive(world=belief, robot=robot, clock=clock, tick_hz=10.0, runs_dir=None,
                   background=False)
    handle = ex.submit(str(missions_dir() / "fetch_object.yaml"), object=object_id,
                       propose_new=False)
    ex.run_until_idle(200_000)
    result = handle.result
    assert result.outcome == "succeeded", result.reason
    label = belief.label(object_id)
    assert robot.said[-1].startswith(f"the {label} was "), robot.said[-1]


def test_an_object_handed_over_is_fetched_again_from_where_it_was_put_down():
    from hearth.executive.executive import Executive
    from hearth.robot.clock import SimClock
    from hearth.robot.simulated import SimulatedRobot

    belief = load_world(demo_world_path())
    target = OBJECTS[0]
    clock = SimClock()
    robot = SimulatedRobot(belief.copy(), clock=clock, seed=0)
    ex = Executive(world=belief, robot=robot, clock=clock, tick_hz=10.0, runs_dir=None,
                   background=False)
    results = []
    for _ in range(2):
        h = ex.submit(str(missions_dir() / "fetch_object.yaml"), object=target,
                      propose_new=False)
        ex.run_until_idle(200_000)
        results.append(h.result)
    assert [r.outcome for r in results] == ["succeeded", "succeeded"], results[-1].reason
    # the map knew where the user put it down: the second search found it at the first place
    assert len(results[1].outputs["searched"]) == 1
    assert robot.handed_over == [target, target]
