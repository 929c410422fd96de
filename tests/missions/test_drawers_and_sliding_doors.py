"""Objects inside drawers and behind sliding doors that share a track (issue 43), on
generated homes: the format holds them, the map moves them with their part, the search
opens the drawer or the right half and the fetch brings them."""
from __future__ import annotations

import numpy as np
import py_trees
import pytest

from hearth.executive.executive import Executive
from hearth.executive.scenarios import MISSIONS, resolve_world
from hearth.robot.clock import SimClock
from hearth.robot.simulated import SimulatedRobot
from hearth.skills.base import Bindings, Key, Literal
from hearth.skills.map import ClosedParts, Uncovered, UpdateObjectLocation
from hearth.worldmodel.io import parse_world, to_xml
from hearth.worldmodel.pose import Pose

#: Generated homes (generator version 11): home:11 has a remote in the top drawer of a chest
#: of drawers, home:10 a mug on a shelf of a wardrobe with two sliding doors on one track.
#: home:11 has such a wardrobe too, and from its one parking position the far half's pull is
#: 1.70 m from the base, beyond the arm's 1.60 m: the search drives within reach of it first.
DRAWER_HOME, SLIDING_HOME = "home:11", "home:10"


@pytest.fixture
def drawer_home():
    world = resolve_world(DRAWER_HOME)
    return world, next(o for o in world.small_objects() if o.part)


@pytest.fixture
def sliding_home():
    world = resolve_world(SLIDING_HOME)
    wardrobe = next(o for o in world.large_objects() if any(p.track for p in getattr(o, "parts", ())))
    inside = next(c for c in wardrobe.children if c.relation == "in")
    return world, wardrobe, inside


def _fetch(belief, truth, words):
    clock = SimClock()
    robot = SimulatedRobot(truth, clock=clock, seed=0)
    said = []
    inner = robot.say
    robot.say = lambda text: (said.append(text), inner(text))[1]
    ex = Executive(world=belief, robot=robot, clock=clock, tick_hz=10.0, background=False)
    done = []
    ex.subscribe(lambda e: done.append(e.data.get("message", "")) if e.kind == "feedback" else None)
    h = ex.submit(str(MISSIONS / "fetch_object.yaml"), object=words)
    ex.run_until_idle(200_000)
    return h.result, robot, said, done


def test_a_drawer_holds_an_object_that_moves_with_it_and_the_file_keeps_it(drawer_home):
    world, obj = drawer_home
    drawer = world.get(obj.part)
    assert drawer.surfaces and drawer.joint.type == "prismatic"
    before = world.T_world(obj.id)[:3, 3].copy()
    world.set_joint_state(drawer.id, 0.2)
    moved = world.T_world(obj.id)[:3, 3] - before
    axis = world.T_world(drawer.id)[:3, :3] @ np.asarray(drawer.joint.axis)
    assert np.allclose(moved, 0.2 * axis, atol=1e-9)              # pulled out with the drawer
    assert world.describe_location(obj.id).startswith(f"in {drawer.name} of the ")
    again = parse_world(to_xml(world.apartment), base_dir=world.base_dir)
    assert again.apartment == world.apartment                       # part=, part surfaces
    levels = [lv for lv in world.surfaces_of(obj.id) if lv.part == drawer.id]
    assert levels and levels[0].relation == "in"


def test_an_object_seen_in_an_open_drawer_is_written_in_the_drawer(drawer_home, clean_blackboard):
    world, obj = drawer_home
    drawer = world.get(obj.part)
    world.set_joint_state(drawer.id, 0.8 * drawer.joint.upper)
    seen = world.world_pose(obj.id)
    place = world.parent(obj.id).id
    world.move_object(obj.id, place, Pose(0, 0, 2.0), relation="on")     # believed on top
    assert world.get(obj.id).part == ""
    skill = UpdateObjectLocation(bindings=Bindings(
        {"object_id": Literal(obj.id), "place": Literal(place), "pose": Literal(seen),
         "relation": Literal("in")}, {}))
    skill.setup(world=world, robot=None)
    skill.tick_once()
    assert skill.status == py_trees.common.Status.SUCCESS
    assert world.get(obj.id).part == drawer.id
    assert np.allclose(world.T_world(obj.id), seen.matrix(), atol=1e-6)
    world.set_joint_state(drawer.id, 0.0)                     # closed: it goes in with it
    assert world.T_world(obj.id)[0, 3] != pytest.approx(seen.x, abs=0.05) or \
        world.T_world(obj.id)[1, 3] != pytest.approx(seen.y, abs=0.05)


def test_the_search_opens_the_sliding_half_in_front_of_the_object_first(sliding_home,
                                                                        clean_blackboard):
    world, wardrobe, inside = sliding_home
    from hearth.worldmodel.containers import covering_door
    skill = ClosedParts(bindings=Bindings({"place": Literal(wardrobe.id),
                                           "object_id": Literal(inside.id)},
                                          {"parts": Key("/first"), "other_half": Key("/then")}))
    skill.setup(world=world, robot=None)
    skill.tick_once()
    first = py_trees.blackboard.Blackboard.get("/first")
    then = py_trees.blackboard.Blackboard.get("/then")
    assert [p["part"] for p in first] == [covering_door(world, inside.id)]
    assert len(then) == 1 and then[0]["part"] != first[0]["part"]


def test_an_object_seen_behind_the_half_slid_over_it_is_not_taken_for_within_reach(
        sliding_home, clean_blackboard):
    """Looking in at an angle through the half slid open, the camera can see an object
    behind the other half (home:100, teal bottle, seed 101: then "could not pick it up"):
    Uncovered fails while a sliding door stands in front of it, so the search slides the
    halves and looks again."""
    world, wardrobe, inside = sliding_home
    from hearth.worldmodel.containers import covering_door, sliding_open_state

    def uncovered():
        skill = Uncovered(bindings=Bindings({"object_id": Literal(inside.id)}, {}))
        skill.setup(world=world, robot=None)
        skill.tick_once()
        return skill.status, skill.feedback_message

    front = covering_door(world, inside.id)                 # closed, in front of it
    other = next(p for p in wardrobe.parts if p.track and p.id != front)
    assert uncovered() == (py_trees.common.Status.FAILURE, f"{inside.id} is behind {front}")
    world.set_joint_state(other.id, sliding_open_state(other))    # slid over it
    assert covering_door(world, inside.id) is not None
    assert uncovered()[0] == py_trees.common.Status.FAILURE
    world.set_joint_state(other.id, other.joint.lower)
    world.set_joint_state(front, sliding_open_state(world.get(front)))   # its own half open
    assert uncovered() == (py_trees.common.Status.SUCCESS, f"no sliding door in front of {inside.id}")


def test_an_object_in_a_drawer_is_fetched(drawer_home):
    world, obj = drawer_home
    drawer = world.get(obj.part).name
    result, robot, said, _ = _fetch(world, world.copy(), obj.id)
    assert result.outcome == "succeeded", result.reason
    assert robot.handed_over == [obj.id]
    assert said[-1].startswith(f"the {world.label(obj.id)} was in {drawer} of ")


def test_a_bypass_wardrobe_is_searched_behind_one_half_then_the_other(sliding_home):
    """The map believes the jar behind the right half; it stands behind the left one: the
    search opens the half in front of where it is believed, then closes it, opens the other
    and finds it there."""
    world, wardrobe, jar = sliding_home
    truth = world.copy()
    p = jar.pose
    truth.move_object(jar.id, wardrobe.id, Pose(p.x, -p.y, p.z, 0, 0, p.yaw), relation="in")
    from hearth.worldmodel.containers import covering_door
    first, other = covering_door(world, jar.id), covering_door(truth, jar.id)
    assert first != other
    result, robot, said, feedback = _fetch(world, truth, jar.id)
    assert result.outcome == "succeeded", result.reason
    assert robot.handed_over == [jar.id]
    acts = [m for m in feedback if m.startswith(("opening ", "closing ")) and m.endswith("done")]
    order = [m for i, m in enumerate(acts) if i == 0 or m != acts[i - 1]]   # said once per tick
    assert order[:3] == [f"opening {first}: done", f"closing {first}: done",
                         f"opening {other}: done"]


def test_a_pull_out_of_reach_is_reached_by_driving_closer_first(sliding_home, clean_blackboard):
    """Opening a sliding door from where a next best view or a second parking position left
    the robot (its pull 2 m away): NavigateTo with parking 'reach' drives within the arm's
    reach of the pull, then the door opens; already within reach, it does not drive."""
    import math
    from hearth.robot.adapter import wait
    from hearth.skills.manipulation import OpenArticulated
    from hearth.skills.navigation import NavigateTo
    from hearth.worldmodel.viewing import ARM_REACH
    world, wardrobe, _inside = sliding_home
    door = next(p for p in wardrobe.parts if p.track)
    pull = world.T_world(door.handles[0].id)[:3, 3]
    clock = SimClock()
    park = world.parking_positions(wardrobe.id)[0][1]
    away = np.array([park.x - pull[0], park.y - pull[1]])
    away /= np.linalg.norm(away)
    start = Pose.planar(float(pull[0] + 2.0 * away[0]), float(pull[1] + 2.0 * away[1]), 0.0)
    from hearth.worldmodel.viewing import floor_clear
    if not floor_clear(world, 0.3)(start.x, start.y):
        start = world.parking_positions(wardrobe.id)[-1][1]
    robot = SimulatedRobot(world.copy(), clock=clock, start_pose=start, seed=0,
                           localisation_error=Pose())

    def tick(skill):
        skill.setup(world=world, robot=robot)
        for _ in range(2000):
            skill.tick_once()
            if skill.status != py_trees.common.Status.RUNNING:
                return skill.status
            clock.advance(0.1)
        return skill.status

    part = {"part": door.id, "handle": door.handles[0].id}
    opened = OpenArticulated(bindings=Bindings({"part": Literal(part)}, {}))
    far = math.hypot(pull[0] - start.x, pull[1] - start.y)
    if far > robot.reach:
        assert tick(opened) == py_trees.common.Status.FAILURE
        assert "out of reach" in opened.feedback_message
    nav = NavigateTo(bindings=Bindings({"target": Literal(part), "parking": Literal("reach")}, {}))
    assert tick(nav) == py_trees.common.Status.SUCCESS
    here = robot.base_pose()
    assert math.hypot(pull[0] - here.x, pull[1] - here.y) <= ARM_REACH
    opened = OpenArticulated(bindings=Bindings({"part": Literal(part)}, {}))
    assert tick(opened) == py_trees.common.Status.SUCCESS, opened.feedback_message
    again = NavigateTo(bindings=Bindings({"target": Literal(door.id), "parking": Literal("reach")}, {}))
    log = len(robot.log)
    assert tick(again) == py_trees.common.Status.SUCCESS          # within reach: no drive
    assert not [e for e in robot.log[log:] if e["action"] == "navigate_to"]


def test_the_suite_holds_every_object_in_a_drawer_or_behind_a_sliding_door(drawer_home):
    from hearth.executive.scenarios import (Case, hidden_cases, hidden_where, make_case_scenario,
                                            suite_cases)
    world, obj = drawer_home
    hidden = hidden_cases(world)
    assert (obj.id, "stay") in hidden
    assert {hidden_where(world, o) for o, h in hidden if h == "stay"} == {"drawer", "sliding"}
    cases = [c for c in suite_cases(1, seed=5, missions=("fetch_object",), worlds=(DRAWER_HOME,),
                                    orders=("fixed",)) if c.hide]
    assert sorted((c.target, c.hide) for c in cases) == sorted(hidden)
    for c in cases:
        sc, _params, target = make_case_scenario(c)
        assert hidden_where(sc.truth, target) == hidden_where(world, target)


def test_an_object_is_put_behind_a_sliding_door_where_sliding_it_aside_uncovers_it(sliding_home):
    from hearth.executive.scenarios import place_behind_sliding_door
    from hearth.worldmodel.containers import covering_door, search_states
    world, wardrobe, _inside = sliding_home
    target = next(o.id for o in world.small_objects() if o.graspable and o.id != _inside.id)
    rng = np.random.default_rng(1)
    for _ in range(3):
        truth = world.copy()
        assert place_behind_sliding_door(truth, target, wardrobe.id, rng)
        assert truth.parent(target).id == wardrobe.id and covering_door(truth, target)
        for pid, state in search_states(truth, target).items():
            truth.set_joint_state(pid, state)
        assert covering_door(truth, target) is None
