"""The named missions' logic, with perception and the robot replaced by scripted stand-ins
(hearth.executive.testing) and the map skills real: fast, and what a user would see (outcome,
reason, what was said, what changed in the map)."""
from __future__ import annotations

import math

import py_trees
import pytest

from missions_helpers import MISSIONS, mission_skills
from hearth.executive.executive import Executive
from hearth.executive.testing import Script, Substitution
from hearth.robot.clock import SimClock
from hearth.worldmodel import load_world
from hearth.worldmodel.nodes import Knob
from hearth.worldmodel.pose import Pose

S = py_trees.common.Status


class Done:
    """A robot action that finished at once."""
    def __init__(self, ok=True, reason=""):
        self._ok, self.reason, self.progress = ok, reason, 1.0

    def status(self):
        return "succeeded" if self._ok else "failed"

    def cancel(self):
        pass


class FakeRobot:
    """Speech, a base pose and knobs with a truth (a stuck knob does not move)."""
    def __init__(self, knobs=None, stuck=(), unreadable=()):
        self.said: list[str] = []
        self.truth_knobs = dict(knobs or {})
        self.stuck = set(stuck)
        #: per knob reading, in order: the knobs that reading cannot read
        self.unreadable = [set(u) for u in unreadable]
        self.reads: list = []   # the knobs each reading was asked for (None: all)

    def say(self, text):
        self.said.append(text)

    def base_pose(self):
        return Pose.planar(0.0, -1.5, 0.0)

    def look_at(self, point):
        return Done()

    def turn_knob(self, knob_id, angle):
        if knob_id not in self.stuck:
            self.truth_knobs[knob_id] = angle
        return Done()


def _read_knobs_class(real):
    """ReadKnobs reading the fake robot's truth into the map (its real ports)."""
    class FakeReadKnobs(real):
        def update(self):
            oid, only = self.input("object"), self.input("knobs")
            blind = self.robot.unreadable.pop(0) if self.robot.unreadable else set()
            self.robot.reads.append(only)
            states, unknown = {}, []
            for k in self.world.knobs(oid):
                if only and k.id not in only:
                    continue
                if k.id in blind:
                    unknown.append(k.id)
                    continue
                angle = self.robot.truth_knobs.get(k.id, k.angle)
                state = min(k.states, key=lambda s: abs(s.angle - angle)).name
                self.world.set_knob_state(k.id, state, source="ReadKnobs")
                states[k.id] = state
            self.set_output("states", states)
            self.set_output("unknown", unknown)
            return S.SUCCESS if states else S.FAILURE
    # (A module outside hearth/skills/ keeps it out of hearth.skills.base.registry() in later tests.)
    return FakeReadKnobs


def on_top_of(world, node_id, dx=0.0):
    """A world pose on top of a table (for scripted detections)."""
    lo, hi = world.bounds_world(node_id)
    c = (lo + hi) / 2
    return {"x": float(c[0] + dx), "y": float(c[1]), "z": float(hi[2] + 0.05), "yaw": 0.0}


def run(mission, world, scripts, robot=None, skills=None, **params):
    sub = Substitution(scripts, default=None)
    ex = Executive(world=world, robot=robot or FakeRobot(), clock=SimClock(), tick_hz=10,
                   runs_dir=None, skills=skills or mission_skills(), make_skill=sub,
                   background=False)
    handle = ex.submit(str(MISSIONS / mission), **params)
    ex.run_until_idle(20_000)
    return handle.result, sub


ROBOT_SCRIPTS = [Script("NavigateTo", duration=2.0), Script("Grasp", duration=1.0),
                 Script("HandOver", duration=1.0), Script("OpenArticulated", duration=1.0),
                 Script("CloseArticulated", duration=1.0),
                 Script("RegisterArticulated"), Script("RefineLocalisation")]


@pytest.fixture
def world(demo_world_path):
    return load_world(demo_world_path)


def test_fetch_finds_the_moved_cup_and_says_where_it_was(world):
    robot = FakeRobot()
    seen = on_top_of(world, "side_table")
    result, sub = run("fetch_object.yaml", world, ROBOT_SCRIPTS + [
        Script("DetectObject", outcomes=["failure", "success"], outputs={"pose": seen}),
        Script("PlanNextBestView", outcomes=["failure"]),
        Script("ProposeSearchPositions", outcomes=["failure"])], robot=robot, object="blue cup")
    assert result.outcome == "succeeded", result.reason
    assert world.parent("blue_cup").id == "side_table"
    assert "the blue cup was on the side table in the kitchen" in robot.said
    stats = world.search_stats("blue_cup")
    assert stats["kitchen_table"].found == 0 and stats["side_table"].found == 1


def test_fetch_learns_to_start_where_the_cup_turned_up(world):
    seen = on_top_of(world, "side_table")
    for _ in range(3):
        world.record_search("blue_cup", "kitchen_table", False)
        world.record_search("blue_cup", "side_table", True)
    result, sub = run("fetch_object.yaml", world, ROBOT_SCRIPTS + [
        Script("DetectObject", outputs={"pose": seen})], object="blue cup")
    assert result.outcome == "succeeded", result.reason
    drive = next(n for p, n in sub.made.items()
                 if p.endswith("/known_places/search_known_places/for_each/sequence/search_at/sequence/drive/NavigateTo"))
    assert drive.seen_inputs[0]["target"]["place"] == "side_table"


def test_fetch_of_an_absent_object_says_how_many_places_were_searched(world):
    robot = FakeRobot()
    result, _ = run("fetch_object.yaml", world, ROBOT_SCRIPTS + [
        Script("DetectObject", outcomes=["failure"]),
        Script("PlanNextBestView", outcomes=["failure"]),
        Script("ProposeSearchPositions", outcomes=["failure"])],
        robot=robot, object="blue cup", max_places=3)
    assert result.outcome == "failed"
    assert "no blue cup at the 3 places searched" in result.reason
    assert any("no blue cup at the 3 places searched" in s for s in robot.said)


def test_fetch_falls_back_to_proposed_search_positions(world):
    seen = on_top_of(world, "bathroom_counter")
    c = world.T_world("bathroom_counter")[:3, 3]
    proposed = {"positions": [{"x": float(c[0]), "y": float(c[1]) + 0.8, "yaw": -1.57}],
                "tables": [{"x": float(c[0]), "y": float(c[1]), "height": 0.9}]}
    result, sub = run("fetch_object.yaml", world, ROBOT_SCRIPTS + [
        Script("*/new_places/*/DetectObject", outputs={"pose": seen}),
        Script("DetectObject", outcomes=["failure"]),
        Script("PlanNextBestView", outcomes=["failure"]),
        Script("ProposeSearchPositions", outputs=proposed)],
        object="blue cup", max_places=2)
    assert result.outcome == "succeeded", result.reason
    assert world.parent("blue_cup").id == "bathroom_counter"


def test_a_door_that_does_not_open_is_named_in_the_reason(world):
    result, _ = run("fetch_object.yaml", world, [
        Script("OpenArticulated", outcomes=["failure"]),
        Script("DetectObject", outcomes=["failure"]),
        Script("PlanNextBestView", outcomes=["failure"]),
        Script("ProposeSearchPositions", outcomes=["failure"])] + ROBOT_SCRIPTS,
        object="glass jar", max_places=1)
    assert result.outcome == "failed"
    assert "no clear jar at the 1 place searched" in result.reason
    assert "the left cupboard door did not open" in result.reason


def _closed_doors(sub):
    # ClosedParts gives {part, handle} items
    return [i["part"]["part"] for p, n in sub.made.items() if p.endswith("/close_door")
            for i in n.seen_inputs]


def test_doors_opened_at_a_place_without_the_object_are_closed_again(world):
    result, sub = run("fetch_object.yaml", world, ROBOT_SCRIPTS + [
        Script("DetectObject", outcomes=["failure"]),
        Script("PlanNextBestView", outcomes=["failure"]),
        Script("ProposeSearchPositions", outcomes=["failure"])],
        object="glass jar", max_places=1)
    assert result.outcome == "failed"
    assert sorted(_closed_doors(sub)) == ["cupboard_door_left", "cupboard_door_right"]


def test_doors_stay_open_where_the_object_is_found(world):
    jar = world.T_world("glass_jar")[:3, 3]
    seen = {"x": float(jar[0]), "y": float(jar[1]), "z": float(jar[2]), "yaw": 0.0}
    result, sub = run("fetch_object.yaml", world, ROBOT_SCRIPTS + [
        Script("DetectObject", outputs={"pose": seen})], object="glass jar")
    assert result.outcome == "succeeded", result.reason
    assert _closed_doors(sub) == []


def test_an_ambiguous_object_asks_which_one(world):
    result, _ = run("fetch_object.yaml", world, ROBOT_SCRIPTS, object="cup")
    assert result.outcome == "failed"
    assert "which cup do you mean" in result.reason


def test_a_failed_grasp_says_where_the_object_is(world):
    seen = on_top_of(world, "kitchen_table")
    result, _ = run("fetch_object.yaml", world, [Script("Grasp", outcomes=["failure"])]
                    + ROBOT_SCRIPTS + [Script("DetectObject", outputs={"pose": seen})],
                    object="blue cup")
    assert result.outcome == "failed"
    assert "I found the blue cup but could not pick it up" in result.reason
    assert "kitchen table" in result.reason


def test_search_object_tells_where_the_object_is(world):
    robot = FakeRobot()
    seen = on_top_of(world, "kitchen_table")
    result, _ = run("search_object.yaml", world, ROBOT_SCRIPTS + [
        Script("DetectObject", outputs={"pose": seen})], robot=robot, object="red cup")
    assert result.outcome == "succeeded", result.reason
    assert robot.said[-1] == "the red cup is on the kitchen table in the kitchen"


def _oven_skills():
    skills = mission_skills()
    skills["ReadKnobs"] = _read_knobs_class(skills["ReadKnobs"])
    return skills


#: The free poses KnobViews chooses (its ranking is tests/knobs/test_knob_views.py's): two,
#: facing the oven's knobs from the room.
VIEW_PLACES = [dict(x=0.6, y=-1.2, yaw=1.2, look_at=[0.9, -0.4, 0.85], expected_read=0.9),
               dict(x=1.3, y=-1.1, yaw=1.9, look_at=[0.9, -0.4, 0.85], expected_read=0.7)]


def _turn_off_oven(world, robot):
    return run("turn_off_oven.yaml", world,
               ROBOT_SCRIPTS + [Script("KnobViews", outputs={"places": VIEW_PLACES,
                                                            "count": len(VIEW_PLACES)})],
               robot=robot, skills=_oven_skills())


def _assert_turned_off(result, world, robot, knob_id, off_state):
    """The mission succeeded: ``knob_id`` is at ``off_state`` in the map and at angle 0 in
    truth, and the robot said it turned one knob off."""
    assert result.outcome == "succeeded", result.reason
    assert world.get(knob_id).state == off_state
    assert robot.truth_knobs[knob_id] == pytest.approx(0.0)
    assert robot.said[-1] == "I turned off 1 knob of the oven; it is off now."


def _knob_angle(world, knob_id, state):
    k = world.get(knob_id)
    assert isinstance(k, Knob)
    return k.state_angle(state)


def test_turn_off_oven_turns_off_the_knob_that_is_on(world):
    on_state = [s.name for s in world.get("oven_knob_2").states if s.name != "off"][0]
    robot = FakeRobot(knobs={"oven_knob_2": _knob_angle(world, "oven_knob_2", on_state)})
    if "TurnKnob" not in {k for k, v in mission_skills().items() if v.__module__ == "hearth.skills.knobs"}:
        pytest.skip("TurnKnob not landed")
    result, _ = _turn_off_oven(world, robot)
    _assert_turned_off(result, world, robot, "oven_knob_2", "off")


def test_turn_off_oven_with_every_knob_off_says_so(world):
    robot = FakeRobot()
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    assert robot.said[-1] == "Every knob of the oven was already off."


def test_a_stuck_knob_ends_with_cannot(world):
    on_state = [s.name for s in world.get("oven_knob_3").states if s.name != "off"][0]
    robot = FakeRobot(knobs={"oven_knob_3": _knob_angle(world, "oven_knob_3", on_state)},
                      stuck={"oven_knob_3"})
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "failed"
    assert "I cannot turn off oven knob 3 of the oven: it did not move" in result.reason


def _on(world, knob_id):
    on_state = [s.name for s in world.get(knob_id).states if s.name != "off"][0]
    return _knob_angle(world, knob_id, on_state)


def _made(sub, suffix):
    return next(node for path, node in sub.made.items() if path.endswith(suffix))


def _other_parkings(world, robot, node="oven"):
    """The parking positions of ``node`` other than the robot's, nearest first (what
    OtherParkings lists)."""
    here = robot.base_pose()
    found = sorted((math.hypot(pose.x - here.x, pose.y - here.y), p.id)
                   for p, pose in world.parking_positions(node))
    return [pid for d, pid in found if d > 0.15]


def test_a_knob_unread_from_the_first_place_is_read_from_another_and_turned_off(world):
    # the map says off (stale); the knob is on and the first view cannot read it
    robot = FakeRobot(knobs={"oven_knob_4": _on(world, "oven_knob_4")},
                      unreadable=[{"oven_knob_4"}])
    result, sub = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    # the nearest other parking position
    assert _made(sub, "drive_aside").seen_inputs[-1]["parking"] == _other_parkings(world, robot)[0]
    assert robot.reads[:2] == [None, ["oven_knob_4"]]   # all, then the unread one again
    assert robot.truth_knobs["oven_knob_4"] == pytest.approx(0.0)
    assert robot.said[-1] == "I turned off 1 knob of the oven; it is off now."


def test_no_knob_read_from_the_first_place_reads_them_all_from_another(world):
    every = {k.id for k in world.knobs("oven")}
    robot = FakeRobot(knobs={"oven_knob_1": _on(world, "oven_knob_1")}, unreadable=[every])
    result, sub = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    assert _made(sub, "drive_aside_for_all").seen_inputs[-1]["parking"] == "another"
    assert robot.reads[:2] == [None, None]
    assert robot.said[-1] == "I turned off 1 knob of the oven; it is off now."


def test_a_knob_unread_from_every_parking_position_is_read_from_the_best_free_pose(world):
    others = _other_parkings(world, FakeRobot())
    assert len(others) >= 2
    robot = FakeRobot(knobs={"oven_knob_4": _on(world, "oven_knob_4")},
                      unreadable=[{"oven_knob_4"}] * (1 + len(others)))
    result, sub = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    # every other parking position in turn, nearest first, then the best free pose, facing
    # the point KnobViews aims at
    assert [i["parking"] for i in _made(sub, "drive_aside").seen_inputs] == others
    assert _made(sub, "free_views").seen_inputs[-1]["knobs"] == ["oven_knob_4"]
    assert [i["target"] for i in _made(sub, "drive_to_view").seen_inputs] == VIEW_PLACES[:1]
    assert robot.reads[:2 + len(others)] == [None] + [["oven_knob_4"]] * (1 + len(others))
    assert robot.truth_knobs["oven_knob_4"] == pytest.approx(0.0)
    assert robot.said[-1] == "I turned off 1 knob of the oven; it is off now."


def test_a_knob_unread_from_every_parking_position_and_free_pose_is_read_from_straight_in_front(world):
    others = _other_parkings(world, FakeRobot())
    before = 1 + len(others) + len(VIEW_PLACES)
    robot = FakeRobot(knobs={"oven_knob_4": _on(world, "oven_knob_4")},
                      unreadable=[{"oven_knob_4"}] * before)
    result, sub = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    # the other parking positions, the free poses in turn, then straight in front
    assert [i["target"] for i in _made(sub, "drive_to_view").seen_inputs] == VIEW_PLACES
    assert _made(sub, "drive_straight").seen_inputs[-1]["parking"] == "knobs"
    assert _made(sub, "drive_straight").seen_inputs[-1]["distance"] == 1.0
    assert robot.reads[:1 + before] == [None] + [["oven_knob_4"]] * before
    assert robot.truth_knobs["oven_knob_4"] == pytest.approx(0.0)
    assert robot.said[-1] == "I turned off 1 knob of the oven; it is off now."


def test_a_knob_unread_from_every_place_is_never_taken_for_off(world):
    # unread from the parking position, the others, the free poses and every view straight in front
    others = _other_parkings(world, FakeRobot())
    views = len(others) + len(VIEW_PLACES) + 3   # other parking positions, free poses, three straight
    robot = FakeRobot(knobs={"oven_knob_4": _on(world, "oven_knob_4")},
                      unreadable=[{"oven_knob_4"}] * (1 + views))
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "failed"
    assert robot.reads == [None] + [["oven_knob_4"]] * views   # all, then every other view
    assert robot.said[-1] == ("I could not read the oven knob 4 of the oven, so I cannot tell "
                              "whether it is off; please check it")
    assert robot.truth_knobs["oven_knob_4"] != pytest.approx(0.0)   # not touched
    assert "Every knob" not in " ".join(robot.said)


def test_a_turned_knob_unread_from_here_is_read_back_from_the_other_places(world):
    # read fine first; after the turn the reading here cannot see it, the next place can
    robot = FakeRobot(knobs={"oven_knob_2": _on(world, "oven_knob_2")},
                      unreadable=[set(), {"oven_knob_2"}, {"oven_knob_2"}])
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    # all, all after the turn, then knob 2 from another parking position and straight in front
    assert robot.reads == [None, None, ["oven_knob_2"], ["oven_knob_2"]]
    assert robot.said[-1] == "I turned off 1 knob of the oven; it is off now."


def test_a_turned_knob_that_cannot_be_read_back_is_not_reported_off(world):
    # read fine first; after the turn no place can see it: here, every other parking
    # position, the free poses and the three views straight in front
    views = len(_other_parkings(world, FakeRobot())) + len(VIEW_PLACES) + 3
    robot = FakeRobot(knobs={"oven_knob_2": _on(world, "oven_knob_2")},
                      unreadable=[set()] + [{"oven_knob_2"}] * (1 + views))
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "failed"
    assert robot.reads == [None, None] + [["oven_knob_2"]] * views
    assert "I turned oven knob 2 of the oven but could not read it back; please check it" in result.reason
    assert not any("it is off now" in x for x in robot.said)


class _SpringBack(FakeRobot):
    """Turning knob 2 turns knob 1 back on; from its ``stuck_after``-th turn on, knob 1 no
    longer moves."""
    def __init__(self, world, stuck_after=None):
        super().__init__(knobs={"oven_knob_1": _on(world, "oven_knob_1"),
                                "oven_knob_2": _on(world, "oven_knob_2")})
        self.world, self.stuck_after, self.knob_1_turns = world, stuck_after, 0

    def turn_knob(self, knob_id, angle):
        if knob_id == "oven_knob_1":
            self.knob_1_turns += 1
            if self.stuck_after is not None and self.knob_1_turns >= self.stuck_after:
                self.stuck.add("oven_knob_1")
        done = super().turn_knob(knob_id, angle)
        if knob_id == "oven_knob_2":
            self.truth_knobs["oven_knob_1"] = _on(self.world, "oven_knob_1")
        return done


def test_a_knob_that_reads_on_again_after_the_others_are_turned_is_turned_off_once_more(world):
    """Knob 1 is turned off and read off; turning knob 2 turns it back on: at the end it reads
    on, is turned off once more and read back off, and the oven is reported off."""
    robot = _SpringBack(world)
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "succeeded", result.reason
    assert robot.knob_1_turns == 2
    assert robot.said[-1] == "I turned off 2 knobs of the oven; it is off now."


def test_a_knob_that_still_reads_on_after_turning_it_once_more_is_named(world):
    """The same, but the second turn of knob 1 does not move it: the mission does not report
    the oven off, and names the knob in a sentence."""
    robot = _SpringBack(world, stuck_after=2)
    result, _ = _turn_off_oven(world, robot)
    assert result.outcome == "failed"
    assert robot.said[-1] == ("I read the oven knob 1 of the oven on again after turning off its "
                              "knobs; please check it")
    assert not any("it is off now" in x for x in robot.said)


def test_refine_localisation_reports_the_correction(world):
    robot = FakeRobot()
    result, _ = run("refine_localisation.yaml", world, [
        Script("RefineLocalisation", outputs={"correction": {"dx": 0.06, "dy": 0.08, "dyaw": 0.0}})]
        + ROBOT_SCRIPTS, robot=robot, at="cupboard")
    assert result.outcome == "succeeded", result.reason
    assert robot.said[-1] == "My position was off by 10.0 cm and 0.0 degrees; corrected."


def test_refine_localisation_without_a_fix_says_to_try_elsewhere(world):
    result, sub = run("refine_localisation.yaml", world, [
        Script("RefineLocalisation", outcomes=["failure"], outputs={"quality": {"fitness": 0.1}}),
        Script("LookAtLandmark")] + ROBOT_SCRIPTS)
    assert result.outcome == "failed"
    assert "I could not correct my position here" in result.reason
    assert sub.made["/refine_localisation/fix/localise_here/on_landmarks/RefineLocalisation"].activations == 1
    assert sub.made["/refine_localisation/fix/localise_here/on_landmarks/other_landmarks/sequence/refine_on_another"].activations == 3


def test_a_missed_grasp_is_retried_after_relocalising_and_looking_again(world):
    seen = on_top_of(world, "kitchen_table")
    result, sub = run("fetch_object.yaml", world, [
        Script("/fetch_object/find_and_pick_up/find_and_pick/sequence/pick_up/Grasp", outcomes=["failure"]),
        Script("LookAtLandmark"), Script("DetectObject", outputs={"pose": seen})]
        + ROBOT_SCRIPTS, object="blue cup")
    assert result.outcome == "succeeded", result.reason
    assert sub.made["/fetch_object/find_and_pick_up/find_and_pick/sequence/pick_up/relocalise_and_grasp/grasp_again_or_where_seen/"
                    "sequence/grasp_again"].activations == 1


PICK_UP = "/fetch_object/find_and_pick_up/find_and_pick/sequence/pick_up"


def test_a_grasp_that_comes_back_empty_searches_the_other_places(world):
    # A false detection on the kitchen table: every grasp there closes on nothing (the robot
    # says so); the search goes on at the places not searched yet and the grasp there holds.
    robot = FakeRobot()
    seen = on_top_of(world, "kitchen_table")
    result, sub = run("fetch_object.yaml", world, [
        Script(f"{PICK_UP}/Grasp", outcomes=["failure", "success"], outputs={"empty": True}),
        Script(f"{PICK_UP}/relocalise_and_grasp/*", outcomes=["failure"], outputs={"empty": True}),
        Script("LookAtLandmark"), Script("DetectObject", outputs={"pose": seen})]
        + ROBOT_SCRIPTS, robot=robot, object="blue cup")
    assert result.outcome == "succeeded", result.reason
    assert "the blue cup was not where I saw it" in robot.said
    searched = [p["place"] for p in result.outputs["searched"]]
    assert searched[0] == "kitchen_table" and len(searched) == 2 and "kitchen_table" not in searched[1:]


def test_a_grasp_that_fails_otherwise_ends_the_mission_saying_where_the_object_is(world):
    # the gripper did not come back empty (the object is there, the arm cannot take it):
    # no second search, and the sentence says where it is
    robot = FakeRobot()
    seen = on_top_of(world, "kitchen_table")
    result, sub = run("fetch_object.yaml", world, [
        Script("Grasp", outcomes=["failure"], outputs={"empty": False}),
        Script("LookAtLandmark"), Script("DetectObject", outputs={"pose": seen})]
        + ROBOT_SCRIPTS, robot=robot, object="blue cup")
    assert result.outcome == "failed"
    assert result.reason.endswith("I found the blue cup but could not pick it up; the blue cup "
                                  "was on the kitchen table in the kitchen")
    assert [p["place"] for p in result.outputs["searched"]] == ["kitchen_table"]


def test_a_grasp_out_of_reach_comes_back_within_reach_and_grasps_where_it_was_seen(world):
    # Found from a view further than the arm reaches; from the parking position the object
    # is not seen again: the robot grasps it where the far view saw it.
    seen = on_top_of(world, "kitchen_table")
    result, sub = run("fetch_object.yaml", world, [
        Script("/fetch_object/find_and_pick_up/find_and_pick/sequence/pick_up/Grasp", outcomes=["failure"]),
        Script("*/detect_again", outcomes=["failure"]),
        Script("LookAtLandmark"), Script("DetectObject", outputs={"pose": seen})]
        + ROBOT_SCRIPTS, object="blue cup")
    assert result.outcome == "succeeded", result.reason
    base = "/fetch_object/find_and_pick_up/find_and_pick/sequence/pick_up/relocalise_and_grasp"
    back = sub.made[f"{base}/come_closer/sequence/back_within_reach"]
    assert back.activations == 1
    assert back.seen_inputs[0] == {"target": "kitchen_table", "parking": "nearest",
                                   "near": seen, "distance": None}
    assert sub.made[f"{base}/grasp_again_or_where_seen/grasp_where_seen"].activations == 1
    assert sub.made[f"{base}/grasp_again_or_where_seen/grasp_where_seen"].seen_inputs[0]["pose"] \
        == seen


def test_a_knob_whose_off_state_is_not_called_off_is_turned_to_its_own_off(world):
    # A thermostat-style knob: states 0..3, off is "0", turning the other way.
    from hearth.worldmodel.nodes import KnobState
    k = world.get("oven_knob_1")
    k.states = [KnobState("0", 0.0), KnobState("1", 0.8), KnobState("2", 1.6), KnobState("3", 2.4)]
    k.off_state, k.state, k.angle = "0", "0", 0.0
    robot = FakeRobot(knobs={"oven_knob_1": 1.6})
    result, _ = _turn_off_oven(world, robot)
    _assert_turned_off(result, world, robot, "oven_knob_1", "0")


def test_turn_off_oven_falls_back_to_other_landmarks_when_the_fix_on_the_oven_is_not_trusted(world):
    robot = FakeRobot(knobs={"oven_knob_2": _on(world, "oven_knob_2")})
    result, sub = run("turn_off_oven.yaml", world, [
        Script("/turn_off_oven/localise/localise_here/on_landmarks/RefineLocalisation",
               outcomes=["failure"]),
        Script("LookAtLandmark"),
        Script("RefineLocalisation", outputs={"correction": {"dx": 0.1, "dy": 0.0, "dyaw": 0.0}}),
    ] + ROBOT_SCRIPTS, robot=robot, skills=_oven_skills())
    assert result.outcome == "succeeded", result.reason
    assert _made(sub, "other_landmarks/sequence/refine_on_another").activations == 1
