"""Small-object detection and verification on rendered views of the demo home's kitchen table.

open3d's plane RANSAC is not deterministic even with a seed: assertions are tolerances."""
from __future__ import annotations


import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from hearth.benchmarks._worlds import places
from hearth.benchmarks.objects import box_object, cluttered_scene, observe, visible_fractions
from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.errors import PerceptionError
from hearth.perception.objects import color_agreement, detect_objects, model_library
from hearth.worldmodel.pose import Pose

K = Intrinsics.kinect()
#: The small objects on the demo home's kitchen table.
OBJECTS = ("red_cup", "bowl", "sugar", "blue_cup")


def _south_view(world):
    T = world.T_world("kitchen_table")
    return look_at(T[:3, 3] + (0.0, -1.3, 1.3), T[:3, 3] + (0.0, 0.0, 0.75))


@pytest.fixture(scope="module")
def table_view():
    from hearth.benchmarks._worlds import load
    world = load("demo")
    T_wc = _south_view(world)
    depth, color, _ = observe(world, T_wc, np.random.default_rng(1), K)
    return world, T_wc, depth, color, detect_objects(world, depth, color, K, T_wc)


def test_support_plane_is_found_at_the_table_top(table_view):
    *_, det = table_view
    assert det.surface == "kitchen_table/top"
    assert abs(-det.plane[3] - 0.75) < 0.006
    assert det.plane[2] > 0.99


def test_every_object_on_the_table_is_detected_within_a_centimetre(table_view):
    world, *_, det = table_view
    found = {h.object_id: h for h in det.accepted}
    assert set(OBJECTS) <= set(found)
    for oid in OBJECTS:
        err = np.linalg.norm(found[oid].position - world.T_world(oid)[:3, 3])
        assert err < 0.01, (oid, err)
        assert found[oid].confidence > 0.6


def test_objects_not_on_the_table_are_not_reported(table_view):
    *_, det = table_view
    assert {h.object_id for h in det.accepted} <= set(OBJECTS)


def test_blue_cup_is_told_apart_from_red_cup(table_view):
    world, *_, det = table_view
    blue = world.T_world("blue_cup")[:2, 3]
    at_blue = [h for h in det.hypotheses if np.linalg.norm(h.position[:2] - blue) < 0.03]
    best = max(at_blue, key=lambda h: h.confidence)
    assert best.object_id == "blue_cup"
    red_there = [h for h in at_blue if h.object_id == "red_cup"]
    assert all(h.confidence < 0.2 for h in red_there)


def test_swapped_cups_are_reported_where_they_really_are(demo_world):
    truth = demo_world.copy()
    pr, pb = truth.get("red_cup").pose, truth.get("blue_cup").pose
    truth.move_object("red_cup", "kitchen_table", pb)
    truth.move_object("blue_cup", "kitchen_table", pr)
    T_wc = _south_view(truth)
    depth, color, _ = observe(truth, T_wc, np.random.default_rng(2), K)
    det = detect_objects(demo_world, depth, color, K, T_wc)  # the belief still has them swapped
    found = {h.object_id: h.position for h in det.accepted}
    assert np.linalg.norm(found["red_cup"][:2] - truth.T_world("red_cup")[:2, 3]) < 0.02
    assert np.linalg.norm(found["blue_cup"][:2] - truth.T_world("blue_cup")[:2, 3]) < 0.02


def test_an_unknown_box_is_not_taken_for_a_map_object(demo_world):
    truth = demo_world.copy()
    truth.remove_small_object("sugar")
    # A box of another size in a yellowish colour near where the sugar jar stood.
    truth.add_small_object(box_object("clutter", (0.12, 0.05, 0.2), (0.9, 0.75, 0.3),
                                      Pose(0.35, -0.2, 0.75, 0, 0, 0.3)), "kitchen_table")
    T_wc = _south_view(truth)
    depth, color, _ = observe(truth, T_wc, np.random.default_rng(3), K)
    det = detect_objects(demo_world, depth, color, K, T_wc)
    box = truth.T_world("clutter")[:2, 3]
    assert not [h for h in det.accepted if np.linalg.norm(h.position[:2] - box) < 0.08]


def test_partly_occluded_objects_are_still_found(demo_world):
    rng = np.random.default_rng(11)
    table = next(p for p in places(demo_world) if p.name == "kitchen_table/top")
    found = total = 0
    for _ in range(3):
        sc = cluttered_scene(rng, table, demo_world, n_objects=(4, 4), objects=OBJECTS)
        truth, T_wc = sc.truth, sc.T_world_camera
        depth, color, r = observe(truth, T_wc, rng, K)
        vis = visible_fractions(truth, r, T_wc, K, sc.ids)
        det = detect_objects(demo_world, depth, color, K, T_wc)
        acc = {h.object_id: h.position for h in det.accepted}
        for oid, v in vis.items():
            if v >= 0.5:
                total += 1
                found += oid in acc and np.linalg.norm(
                    acc[oid][:2] - truth.T_world(oid)[:2, 3]) < 0.03
    assert total >= 8
    assert found / total >= 0.85


def test_hypotheses_claiming_the_same_points_are_penalised(table_view):
    world, T_wc, depth, color, _ = table_view
    # Without colour, the red and blue cup models explain the same cup equally well.
    det = detect_objects(world, depth, None, K, T_wc, candidates=["red_cup", "blue_cup"])
    red = world.T_world("red_cup")[:2, 3]
    there = sorted((h for h in det.hypotheses if np.linalg.norm(h.position[:2] - red) < 0.03),
                   key=lambda h: -h.confidence)
    assert len(there) >= 2
    # the weaker is penalised: for the points the stronger claimed, or, when its object is
    # already placed where it stands (the other cup's own place), as a second place of it
    # (a placed object claims no second place's points)
    second = there[1]
    elsewhere = [h for h in det.hypotheses if h.object_id == second.object_id
                 and np.linalg.norm(h.position[:2] - red) >= 0.03
                 and h.confidence > second.confidence]
    assert second.conflict > 0.5 or elsewhere
    assert second.confidence < 0.5 * there[0].confidence


def test_no_surface_in_view_is_an_error(demo_world):
    T_wc = look_at((0.5, 0.5, 1.3), (-3.0, -3.0, 1.3))  # into the kitchen's corner
    depth = np.zeros((K.height, K.width))
    with pytest.raises(PerceptionError):
        detect_objects(demo_world, depth, None, K, T_wc)


def test_cup_models_carry_their_colour_and_are_not_symmetric(demo_world):
    lib = model_library(demo_world, ["red_cup", "blue_cup", "bowl"])
    assert not lib["red_cup"].symmetric and lib["bowl"].symmetric
    assert np.median(lib["red_cup"].hsv[:, 0]) < 0.05 or np.median(lib["red_cup"].hsv[:, 0]) > 0.95
    assert 0.55 < np.median(lib["blue_cup"].hsv[:, 0]) < 0.7
    assert lib["red_cup"].points[:, 2].min() > -1e-6


hsv = st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1))


@given(hsv, hsv)
@settings(max_examples=60, deadline=None)
def test_colour_agreement_is_symmetric_and_wraps_hue(a, b):
    A, B = np.array([a]), np.array([b])
    assert color_agreement(A, B)[0] == color_agreement(B, A)[0]
    assert color_agreement(A, A)[0] == 1.0
    near_wrap = np.array([[0.99, 0.8, 0.5]]), np.array([[0.01, 0.8, 0.5]])
    assert color_agreement(*near_wrap)[0] == 1.0


def test_bench_counts_an_object_of_the_room_found_where_it_stands_as_no_false_positive(demo_world):
    """The objects benchmark: a small object outside the scene that the view also shows (on
    other furniture of the room) is neither required nor a false positive when it is found
    where it stands; found elsewhere it is still a false positive."""
    from types import SimpleNamespace

    from hearth.benchmarks.objects import score
    oid = demo_world.small_objects()[0].id
    where = demo_world.T_world(oid)[:3, 3]
    found = SimpleNamespace(accepted=[SimpleNamespace(object_id=oid, position=where.copy())])
    assert score(found, demo_world, {}, bystanders=frozenset({oid}))[:3] == (0, 0, 0)
    assert score(found, demo_world, {})[:3] == (0, 1, 0)
    off = SimpleNamespace(accepted=[SimpleNamespace(object_id=oid, position=where + [0.2, 0, 0])])
    assert score(off, demo_world, {}, bystanders=frozenset({oid}))[:3] == (0, 1, 0)


def test_a_model_mostly_hidden_behind_furniture_of_its_colour_is_not_accepted():
    """Generated home 5 (generator version 8, kept in tests/assets): a blue bottle that the
    map puts in a slate-blue cupboard (hue within
    the colour test's 25 degrees, saturation just over its 0.25) has been moved elsewhere. Seen
    with the door open and the believed camera 3 cm or 2 degrees off, the cupboard's own side
    and door edges, unexplained by its model, fit the bottle's model placed mostly behind them:
    hypotheses of 0.45-0.52 confidence with 9-22 % of the model in sight, the rest hidden by
    the cupboard. None may be accepted."""
    import math
    from pathlib import Path
    from hearth.perception.objects import DetectionConfig
    from hearth.worldmodel.io import load_world
    belief = load_world(Path(__file__).resolve().parents[1] / "assets" / "generated_home5_v8" / "world.xml")
    truth = belief.copy()
    truth.move_object("blue_bottle", "bedside_1", Pose(0.13, 0.1, 0.551 - truth.T_world(
        "bedside_1")[2, 3]), "on")
    for m in (belief, truth):
        m.set_joint_state("cupboard_1_door", math.pi / 2, source="test")
    surface = next(s for s in belief.get("cupboard_1").surfaces if s.id == "inside_bottom")
    target = (belief.T_world("cupboard_1") @ surface.pose.matrix())[:3, 3]
    ungated = DetectionConfig(min_visible_fraction=0.0)
    wrong, would_pass = [], 0
    for pid, pose in belief.parking_positions("cupboard_1"):
        if not pid.id.endswith(("_left", "_right")):
            continue
        T_true = look_at(np.array([pose.x, pose.y, 1.3]), target)
        for seed in (0, 1):
            depth, color, _ = observe(truth, T_true, np.random.default_rng(seed), K)
            for dx, dy, deg in ((0, 0.03, 0), (0, -0.03, 0), (0, 0, 2), (0, 0, -2)):
                a = math.radians(deg)           # turned about the camera's own position
                T_believed = T_true.copy()
                T_believed[:3, :3] = np.array([[math.cos(a), -math.sin(a), 0],
                                               [math.sin(a), math.cos(a), 0],
                                               [0, 0, 1]]) @ T_true[:3, :3]
                T_believed[:2, 3] += dx, dy
                det = detect_objects(belief, depth, color, K, T_believed,
                                     surface="cupboard_1/inside_bottom")
                for h in det.accepted:
                    # an object reported in the cupboard that is not in it (the believed
                    # camera's error moves those that are by a few centimetres)
                    there = truth.T_world(h.object_id)[:3, 3]
                    if np.linalg.norm(h.position - there) > 0.15:
                        wrong.append((pid.id, seed, (dx, dy, deg), h.object_id, h.visible_fraction))
                # The same hypotheses without the visibility gate: some pass the confidence gate.
                would_pass += sum(1 for h in det.hypotheses
                                  if h.confidence >= ungated.accept_confidence and h.conflict < 0.5
                                  and h.mostly_hidden_by_furniture(det.min_visible_fraction)
                                  and h.object_id in ("blue_bottle", "navy_bottle"))
    assert not wrong, wrong
    assert would_pass >= 1      # what the gate is for, seen in this home


def _cylinder(oid, radius, height, color, pose):
    from hearth.worldmodel.nodes import Model, SmallObject, Visual
    vis = Visual("cylinder", Pose(0, 0, height / 2), radius=radius, length=height,
                 color=tuple(color), name="body")
    return SmallObject(oid, "clutter", pose, model=Model(visuals=[vis]))


def test_a_taller_lookalike_is_not_taken_for_the_cup(demo_world):
    # The red cup is not in the home; where it stood, a red tin of its radius and no handle,
    # 2.5 cm taller (the handle can hide behind a cup's body, its height cannot).
    truth = demo_world.copy()
    pose = truth.get("red_cup").pose
    truth.remove_small_object("red_cup")
    truth.add_small_object(_cylinder("tin", 0.04, 0.125, (0.8, 0.1, 0.1), pose), "kitchen_table")
    T = truth.T_world("kitchen_table")
    # from a head 1.1 m up, so that the tin's top shows little and its side much
    T_wc = look_at(T[:3, 3] + (0.0, -1.2, 1.1), T[:3, 3] + (0.0, 0.0, 0.75))
    at = truth.T_world("tin")[:2, 3]
    for seed in (4, 5):
        depth, color, _ = observe(truth, T_wc, np.random.default_rng(seed), K)
        det = detect_objects(demo_world, depth, color, K, T_wc)
        there = [h for h in det.hypotheses if h.object_id == "red_cup"
                 and np.linalg.norm(h.position[:2] - at) < 0.03]
        assert there and max(h.taller for h in there) > 0.1
        assert not [h for h in det.accepted if np.linalg.norm(h.position[:2] - at) < 0.03]
        # the other objects on the table are found as before
        assert {"bowl", "sugar", "blue_cup"} <= {h.object_id for h in det.accepted}


def test_a_lookalike_without_the_lid_colour_is_not_taken_for_the_jar(demo_world):
    # The map's sugar jar has a blue lid; a yellow box of the jar's size whose top is yellow
    # too agrees in colour on most of its points, but on none of the lid's.
    from hearth.worldmodel.nodes import Visual
    belief = demo_world.copy()
    body = belief.get("sugar").model.visuals[0]
    body.size, body.pose = (0.08, 0.08, 0.10), Pose(0, 0, 0.05)
    belief.get("sugar").model.visuals.append(
        Visual("box", Pose(0, 0, 0.11), size=(0.08, 0.08, 0.02), color=(0.1, 0.2, 0.8), name="lid"))
    T_wc = _south_view(belief)
    at = belief.T_world("sugar")[:2, 3]
    for truth, accepted in ((belief, True), (demo_world, False)):
        depth, color, _ = observe(truth, T_wc, np.random.default_rng(6), K)
        det = detect_objects(belief, depth, color, K, T_wc)
        found = [h for h in det.accepted if h.object_id == "sugar"
                 and np.linalg.norm(h.position[:2] - at) < 0.03]
        assert bool(found) is accepted, [(h.object_id, h.confidence, h.worst_part_color)
                                         for h in det.hypotheses if h.object_id == "sugar"]
        if not accepted:
            there = [h for h in det.hypotheses if h.object_id == "sugar"
                     and np.linalg.norm(h.position[:2] - at) < 0.03]
            assert there and max(h.worst_part_color for h in there) < 0.5


def test_of_two_cups_alike_in_hue_the_one_the_map_puts_here_is_found(demo_world):
    # A navy and a blue cup of one shape differ in brightness only, which the colour test
    # leaves out (shading changes it): on the same points they tie, and the map decides.
    import copy
    truth = demo_world
    T_wc = _south_view(truth)
    depth, color, _ = observe(truth, T_wc, np.random.default_rng(7), K)
    at = truth.T_world("blue_cup")[:2, 3]
    far = demo_world.get("glass_jar").pose
    for here in ("blue_cup", "navy_cup"):
        belief = demo_world.copy()
        navy = copy.deepcopy(belief.get("blue_cup"))
        navy.id, navy.color = "navy_cup", "navy"
        for v in navy.model.visuals:
            v.color = (0.08, 0.12, 0.45)
        belief.add_small_object(navy, "kitchen_table")
        away = "navy_cup" if here == "blue_cup" else "blue_cup"
        belief.move_object(here, "kitchen_table", truth.get("blue_cup").pose)
        belief.move_object(away, "cupboard", far)
        det = detect_objects(belief, depth, color, K, T_wc)
        found = [h.object_id for h in det.accepted if np.linalg.norm(h.position[:2] - at) < 0.03]
        assert found == [here], (here, [(h.object_id, round(h.confidence, 3))
                                        for h in det.hypotheses
                                        if np.linalg.norm(h.position[:2] - at) < 0.03])


def test_an_object_found_where_it_stands_leaves_its_lookalike_beside_it_alone(demo_world):
    # The blue cup stands where the map has it; beside it, where the red cup stood, a navy cup
    # of the same shape that the map has in the cupboard. The blue cup fits both places alike
    # and the map prefers it at both; placed at its own, it takes nothing of the other.
    import copy
    belief = demo_world.copy()
    navy = copy.deepcopy(belief.get("blue_cup"))
    navy.id, navy.color = "navy_cup", "navy"
    for v in navy.model.visuals:
        v.color = (0.08, 0.12, 0.45)
    navy.pose = demo_world.get("glass_jar").pose
    belief.add_small_object(navy, "cupboard")
    truth = demo_world.copy()
    there = copy.deepcopy(navy)
    there.pose = truth.get("red_cup").pose
    truth.remove_small_object("red_cup")
    truth.add_small_object(there, "kitchen_table")
    T_wc = _south_view(truth)
    depth, color, _ = observe(truth, T_wc, np.random.default_rng(8), K)
    det = detect_objects(belief, depth, color, K, T_wc, candidates=["blue_cup", "navy_cup"])
    for oid in ("blue_cup", "navy_cup"):
        at = truth.T_world(oid)[:2, 3]
        assert [h.object_id for h in det.accepted
                if np.linalg.norm(h.position[:2] - at) < 0.03] == [oid]
