"""Map skills and robot-action skills ticked on their own, with a scripted robot."""
from __future__ import annotations

import math

import py_trees
import pytest

from hearth.skills.base import Bindings, Key, Literal
from hearth.skills.manipulation import OpenArticulated
from hearth.skills.map import ClosedParts, DescribeLocation, PlanSearch, RecordSearch, ResolveObject, UpdateObjectLocation
from hearth.skills.navigation import NavigateTo, OtherParkings
from hearth.worldmodel import Pose

S = py_trees.common.Status


class ScriptedAction:
    def __init__(self, ticks=2, ok=True, reason=""):
        self.ticks, self.ok, self.reason, self.cancelled = ticks, ok, reason, False
        self.progress = 0.0

    def status(self):
        if self.cancelled:
            return "cancelled"
        if self.ticks > 0:
            self.ticks -= 1
            return "running"
        return "succeeded" if self.ok else "failed"

    def cancel(self):
        self.cancelled = True


class FakeRobot:
    def __init__(self):
        self.calls = []
        self.next = ScriptedAction()

    def base_pose(self):
        return Pose.planar(1.0, 3.0, 0.0)

    def navigate_to(self, pose):
        self.calls.append(("navigate_to", pose))
        return self.next

    def open_articulated(self, part, handle, target):
        self.calls.append(("open", part, handle, target))
        return self.next


# py_trees' blackboard is global: each test here starts and ends with an empty one.
pytestmark = pytest.mark.usefixtures("clean_blackboard")


def make(cls, world, robot=None, inputs=None, outputs=None):
    b = Bindings({k: (v if isinstance(v, Key) else Literal(v)) for k, v in (inputs or {}).items()},
                 {k: Key(v) for k, v in (outputs or {}).items()})
    skill = cls(bindings=b)
    skill.setup(world=world, robot=robot or FakeRobot())
    return skill


def tick(skill, n=1):
    for _ in range(n):
        skill.tick_once()
    return skill.status


def bb(key):
    return py_trees.blackboard.Blackboard.get(key)


def test_resolve_blue_cup_gives_id_parent_and_room(demo_world):
    s = make(ResolveObject, demo_world, inputs={"object": "the blue cup"},
             outputs={"object_id": "/oid", "parent_id": "/parent", "room": "/room"})
    assert tick(s) == S.SUCCESS
    assert (bb("/oid"), bb("/parent"), bb("/room")) == ("blue_cup", "kitchen_table", "kitchen")


def test_resolve_ambiguous_cup_asks_which_one(demo_world):
    s = make(ResolveObject, demo_world, inputs={"object": "cup"}, outputs={"object_id": "/oid"})
    assert tick(s) == S.FAILURE
    assert "which cup" in s.feedback_message
    assert "red cup" in s.feedback_message and "blue cup" in s.feedback_message


def test_words_that_fit_two_objects_about_equally_ask_which_one(tmp_path):
    """A fuller description of one mug does not make it the mug a person meant."""
    import shutil
    from tests.conftest import DEMO_WORLD
    from hearth.worldmodel import load_world
    home = tmp_path / "home"
    shutil.copytree(DEMO_WORLD.parent, home)
    xml = (home / "world.xml").read_text()
    (home / "world.xml").write_text(xml.replace("<description>red ceramic mug</description>",
                                                "<description>red ceramic mug with a chipped "
                                                "rim</description>"))
    world = load_world(home / "world.xml")
    assert world.find("mug")[0].score != world.find("mug")[1].score      # not an exact tie
    s = make(ResolveObject, world, inputs={"object": "mug"}, outputs={"object_id": "/oid"})
    assert tick(s) == S.FAILURE
    assert s.feedback_message.startswith("which mug do you mean: the ")
    assert "red cup" in s.feedback_message and "blue cup" in s.feedback_message
    from hearth.executive.command.commands import resolve_slot
    asked = resolve_slot(world, "mug", "thing", "object").problem
    assert asked.text_id == "T_CLARIFY_WHICH" and len(asked.candidates) == 2


def test_resolve_unknown_object_says_so(demo_world):
    s = make(ResolveObject, demo_world, inputs={"object": "purple elephant"})
    assert tick(s) == S.FAILURE and "don't know" in s.feedback_message


def test_plan_search_starts_at_the_believed_place_and_learns(demo_world):
    # The robot stands beside the side table, the bathroom is across the flat: a glance at the
    # table on the way costs less than it is unlikely (HOBBIT's cost with looking effort). Of
    # the two bathroom places the one the map believes comes first.
    def order(**inputs):
        s = make(PlanSearch, demo_world, inputs={"object_id": "pill_box", **inputs},
                 outputs={"places": "/places"})
        assert tick(s) == S.SUCCESS
        return [p["place"] for p in bb("/places")]
    first = order()
    assert first.index("bathroom_cabinet") < first.index("bathroom_counter")
    # The pill box keeps turning up on the bathroom counter: the order learns it.
    for _ in range(6):
        demo_world.record_search("pill_box", "bathroom_cabinet", False)
        demo_world.record_search("pill_box", "bathroom_counter", True)
    learned = order()
    assert learned[0] == "bathroom_counter"
    fixed = order(learned=False)
    assert fixed.index("bathroom_cabinet") < fixed.index("bathroom_counter")


def test_planning_again_keeps_to_the_places_of_the_first_plan(demo_world):
    """The budget counts places in the plan: planning again from another position reorders
    the first plan's places that are left and never brings in one it ranked below the budget."""
    def plan(**inputs):
        s = make(PlanSearch, demo_world, inputs={"object_id": "pill_box", **inputs},
                 outputs={"places": "/places"})
        assert tick(s) == S.SUCCESS
        return bb("/places")
    everything = [p["place"] for p in plan()]
    first = plan(max_places=2)
    assert [p["place"] for p in first] == everything[:2]
    left = plan(max_places=1, exclude=[first[0]], among=first)
    assert [p["place"] for p in left] == [first[1]["place"]]
    # Without the first plan the next cheapest place of the whole home would come next.
    assert [p["place"] for p in plan(max_places=1, exclude=[first[0]])] == [everything[1]]
    s = make(PlanSearch, demo_world, inputs={"object_id": "pill_box", "exclude": first,
                                             "among": first})
    assert tick(s) == S.FAILURE and s.feedback_message == "no place left to search"


def test_record_search_and_update_location_write_the_map(demo_world):
    tick(make(RecordSearch, demo_world, inputs={"object_id": "blue_cup",
                                                "place": {"place": "side_table"}, "found": True}))
    assert demo_world.search_stats("blue_cup")["side_table"].found == 1
    s = make(UpdateObjectLocation, demo_world,
             inputs={"object_id": "blue_cup", "place": {"place": "side_table", "relation": "on"},
                     "pose": {"x": 1.5, "y": 1.3, "z": 0.72, "yaw": 0.3}},
             outputs={"location": "/where"})
    assert tick(s) == S.SUCCESS
    assert bb("/where") == "on the side table"
    assert demo_world.world_pose("blue_cup").x == pytest.approx(1.5)
    assert demo_world.history("blue_cup")[0].source == "UpdateObjectLocation"
    d = make(DescribeLocation, demo_world, inputs={"object_id": "blue_cup"}, outputs={"text": "/t"})
    tick(d)
    assert bb("/t") == "the blue cup was on the side table in the kitchen"


def test_closed_parts_lists_doors_of_a_closed_cupboard_only(demo_world):
    s = make(ClosedParts, demo_world, inputs={"place": "cupboard"}, outputs={"parts": "/p"})
    tick(s)
    assert [p["part"] for p in bb("/p")] == ["cupboard_door_left", "cupboard_door_right"]
    s = make(ClosedParts, demo_world, inputs={"place": "kitchen_table"}, outputs={"parts": "/p"})
    tick(s)
    assert bb("/p") == []


def test_navigate_runs_until_the_action_ends_and_cancels_when_halted(demo_world):
    robot = FakeRobot()
    s = make(NavigateTo, demo_world, robot, inputs={"target": "oven"}, outputs={"pose": "/goal"})
    assert tick(s) == S.RUNNING
    goal = robot.calls[0][1]
    assert (round(goal.x, 3), round(goal.y, 3)) == (3.0, 3.78)
    assert tick(s, 2) == S.SUCCESS and bb("/goal") == goal
    robot.next = ScriptedAction(ticks=10)
    s = make(NavigateTo, demo_world, robot, inputs={"target": {"x": 1, "y": 2, "yaw": 0}})
    assert tick(s) == S.RUNNING
    s.stop(S.INVALID)
    assert robot.next.cancelled


def test_navigate_to_another_parking_position_leaves_the_one_the_robot_is_at(demo_world):
    parking = {p.id: pose for p, pose in demo_world.parking_positions("oven")}
    robot = FakeRobot()
    robot.base_pose = lambda: parking["oven_front"]
    s = make(NavigateTo, demo_world, robot, inputs={"target": "oven", "parking": "another"})
    assert tick(s) == S.RUNNING
    goal = robot.calls[0][1]
    # the nearest of the others (left and right are as near: either), never the front
    assert any(abs(goal.x - parking[k].x) < 1e-9 and abs(goal.y - parking[k].y) < 1e-9
               for k in ("oven_left", "oven_right"))
    assert "oven_" in s.describe() and "front" not in s.describe()
    # an object with a single parking position, and the robot on it: fail, saying why
    robot = FakeRobot()
    only = demo_world.parking_positions("oven")[:1]
    demo_world.parking_positions = lambda node: only
    robot.base_pose = lambda: only[0][1]
    s = make(NavigateTo, demo_world, robot, inputs={"target": "oven", "parking": "another"})
    assert tick(s) == S.FAILURE
    assert "no other parking position" in s.feedback_message


def test_other_parkings_lists_the_places_to_look_from_nearest_first(demo_world):
    parking = {p.id: pose for p, pose in demo_world.parking_positions("oven")}
    robot = FakeRobot()
    robot.base_pose = lambda: parking["oven_left"]
    s = make(OtherParkings, demo_world, robot, inputs={"target": "oven"},
             outputs={"places": "/places"})
    assert tick(s) == S.SUCCESS
    # every one but the one the robot is at, nearest first (the front, then the far side)
    assert bb("/places") == ["oven_front", "oven_right"]
    # a node the map does not have: fail, naming it
    s = make(OtherParkings, demo_world, robot, inputs={"target": "no_such_thing"},
             outputs={"places": "/places"})
    assert tick(s) == S.FAILURE
    assert "no_such_thing" in s.feedback_message
    only = demo_world.parking_positions("oven")[:1]
    demo_world.parking_positions = lambda node: only
    robot.base_pose = lambda: only[0][1]
    s = make(OtherParkings, demo_world, robot, inputs={"target": "oven"},
             outputs={"places": "/places"})
    assert tick(s) == S.FAILURE
    assert "no other parking position" in s.feedback_message


def test_navigate_to_the_nearest_parking_position_comes_back_within_reach(demo_world):
    parking = {p.id: pose for p, pose in demo_world.parking_positions("oven")}
    robot = FakeRobot()
    right = parking["oven_right"]
    # a view 40 cm behind the right parking position: back to it, not to the default one
    robot.base_pose = lambda: type(right).planar(right.x - 0.4 * math.cos(right.yaw),
                                                 right.y - 0.4 * math.sin(right.yaw), right.yaw)
    s = make(NavigateTo, demo_world, robot, inputs={"target": "oven", "parking": "nearest"})
    assert tick(s) == S.RUNNING
    goal = robot.calls[0][1]
    assert (goal.x, goal.y) == pytest.approx((right.x, right.y))
    assert "oven_right" in s.describe()


def test_navigate_to_the_parking_position_nearest_an_object_not_the_robot(demo_world):
    # Found from one end of a long piece of furniture, the object lies at the other: back
    # within reach means the parking position nearest the object, not the one the robot is at.
    places = demo_world.parking_positions("oven")
    assert len(places) >= 2
    (_, here), (far_id, far) = places[0], places[1]
    robot = FakeRobot()
    robot.base_pose = lambda: here
    seen = {"x": far.x + 0.3 * math.cos(far.yaw), "y": far.y + 0.3 * math.sin(far.yaw), "z": 0.9}
    s = make(NavigateTo, demo_world, robot,
             inputs={"target": "oven", "parking": "nearest", "near": seen})
    assert tick(s) == S.RUNNING
    goal = robot.calls[0][1]
    assert (goal.x, goal.y) == pytest.approx((far.x, far.y))
    assert far_id.id in s.describe()
    # without ``near``: the one the robot is at
    robot2 = FakeRobot()
    robot2.base_pose = lambda: here
    s = make(NavigateTo, demo_world, robot2, inputs={"target": "oven", "parking": "nearest"})
    assert tick(s) == S.RUNNING
    assert (robot2.calls[0][1].x, robot2.calls[0][1].y) == pytest.approx((here.x, here.y))


def test_navigate_to_the_knobs_stands_straight_in_front_of_the_panel_facing_it(demo_world):
    knobs = [demo_world.T_world(k.id) for k in demo_world.knobs("oven")]
    centre = sum(T[:3, 3] for T in knobs) / len(knobs)
    axis = knobs[0][:3, 2]
    robot = FakeRobot()
    s = make(NavigateTo, demo_world, robot,
             inputs={"target": "oven", "parking": "knobs", "distance": 1.1})
    assert tick(s) == S.RUNNING
    goal = robot.calls[0][1]
    # 1.1 m out along the knobs' axis, looking back at them
    assert (goal.x, goal.y) == pytest.approx((centre[0] + 1.1 * axis[0], centre[1] + 1.1 * axis[1]))
    assert (math.cos(goal.yaw), math.sin(goal.yaw)) == pytest.approx((-axis[0], -axis[1]), abs=1e-9)
    for bad in (0.1, 5.0):
        s = make(NavigateTo, demo_world, FakeRobot(),
                 inputs={"target": "oven", "parking": "knobs", "distance": bad})
        assert tick(s) == S.FAILURE
        assert "the knobs are viewed from 0.3 to 3 m" in s.feedback_message


def test_open_door_writes_its_new_state_and_failure_keeps_the_map(demo_world):
    robot = FakeRobot()
    robot.next = ScriptedAction(ticks=0)
    s = make(OpenArticulated, demo_world, robot,
             inputs={"part": {"part": "cupboard_door_left", "handle": "cupboard_handle_left"}})
    assert tick(s) == S.SUCCESS
    assert demo_world.get("cupboard_door_left").joint.state == pytest.approx(math.radians(90))
    robot.next = ScriptedAction(ticks=0, ok=False, reason="the door is locked")
    s = make(OpenArticulated, demo_world, robot, inputs={"part": "fridge_door"})
    assert tick(s) == S.FAILURE and "locked" in s.feedback_message
    assert demo_world.get("fridge_door").joint.state == 0.0


def test_a_halted_action_reports_halting_until_the_robot_has_stopped(demo_world):
    class Braking(ScriptedAction):
        def cancel(self):
            self.braking = 2

        def status(self):
            if getattr(self, "braking", None) is not None:
                if self.braking == 0:
                    return "cancelled"
                self.braking -= 1
                return "running"
            return "running"

    robot = FakeRobot()
    robot.next = Braking()
    s = make(NavigateTo, demo_world, robot, inputs={"target": "oven"})
    assert tick(s) == S.RUNNING
    s.stop(S.INVALID)
    assert s.is_halting() is True
    polls = 0
    while s.is_halting() and polls < 10:
        polls += 1
    assert polls < 10 and robot.next.status() == "cancelled"
