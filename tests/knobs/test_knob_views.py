"""Choosing where to read a knob again (hearth.perception.knob_views, KnobViews): poses on free
floor ranked by what the reader's own validation views of that knob gave at that size in pixels
and angle off its axis; a knob too small to read from where the robot stands is read from the
pose chosen; a knob no free pose reads is said so with numbers."""
from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import py_trees
import pytest

from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.knob_views import (KnobViewConfig, occluded, rank_views, readability, ring,
                                          view_of)
from hearth.perception.knobs import knob_priors, view_level
from hearth.robot.clock import SimClock
from hearth.robot.simulated import SimulatedRobot
from hearth.skills.knob_views import KnobViews
from hearth.skills.knobs import ReadKnobs
from tests.knobs.test_knobs_skills import make

S = py_trees.common.Status
K = Intrinsics.kinect()
pytestmark = pytest.mark.usefixtures("clean_blackboard")


def _camera_at(x, y, yaw, point):
    return look_at([x, y, 1.3], point)


def _table(knob_id, given_from_px):
    """Validation views of one knob over sizes and angles, given from ``given_from_px`` up."""
    rows = [(math.log(r), a, float(r >= given_from_px), view_level(r, a))
            for r in np.linspace(6, 24, 19) for a in range(0, 61, 5)]
    return {knob_id: np.asarray(rows)}


def test_a_pose_where_the_knob_looks_bigger_ranks_first_when_only_big_views_were_read(demo_world):
    priors = knob_priors(demo_world, "oven")
    p = priors[0]
    face = p.T_world_face()[:3, 3]
    normal = p.T_world_knob[:3, 2][:2]
    poses = ring(face[:2], normal, (0.6, 1.0, 2.4), (0,))
    ranked, best = rank_views(priors, [p.knob_id], poses, _camera_at, K, _table(p.knob_id, 14.0))
    sizes = {round(math.hypot(r.x - face[0], r.y - face[1]), 1): r.views[0].radius_px for r in ranked}
    assert ranked and math.hypot(ranked[0].x - face[0], ranked[0].y - face[1]) < 1.5, sizes
    assert ranked[0].views[0].radius_px >= 14.0 and ranked[0].score > 0.5
    # from 1.0 and 2.4 m the knob is smaller than any view of it that was read
    assert all(r.score < 0.5 * ranked[0].score for r in ranked[1:]), sizes
    assert ranked[-1].views[0].radius_px < 6 and ranked[-1].score < 0.1, sizes
    # facing the knob, the head aimed at it
    assert abs(math.remainder(ranked[0].yaw - math.atan2(-normal[1], -normal[0]), 2 * math.pi)) < 1e-6
    assert best[p.knob_id].p_read == pytest.approx(ranked[0].score)
    # from where a view as good as the best was just had, no pose is a better view
    again, _ = rank_views(priors, [p.knob_id], poses, _camera_at, K, _table(p.knob_id, 14.0),
                          beat=ranked[0].score)
    assert again == []
    fewer, _ = rank_views(priors, [p.knob_id], poses, _camera_at, K, _table(p.knob_id, 14.0),
                          beat=ranked[-1].score)
    assert [r.score for r in fewer] == [r.score for r in ranked if r.score > round(ranked[-1].score, 3)]


def test_a_view_smaller_than_the_reader_reads_or_through_another_object_scores_nothing(demo_world):
    p = knob_priors(demo_world, "oven")[0]
    face = p.T_world_face()[:3, 3]
    eye = face + 1.0 * p.T_world_knob[:3, 2] + [0, 0, 0.4]
    v = view_of(p, look_at(eye, face), K)
    table = _table(p.knob_id, 0.0)
    assert v.in_image and readability(table, v) > 0.9
    assert readability(table, v, KnobViewConfig(min_radius_px=v.radius_px + 1)) == 0.0
    mid = (eye + face) / 2
    assert occluded(eye, face, [(mid - 0.05, mid + 0.05)])
    assert not occluded(eye, face, [(mid + 0.5, mid + 0.6)])


def _robot(world, pose, look):
    robot = SimulatedRobot(world.copy(), clock=SimClock(), start_pose=pose, seed=0)
    robot.look_at(np.asarray(look, dtype=float))
    return robot


def test_a_knob_too_small_to_read_from_the_parking_position_is_read_from_the_pose_chosen(demo_world, reader):
    world = demo_world
    parking = world.parking_positions("oven")[0][1]
    priors = knob_priors(world, "oven")
    aim = np.mean([p.T_world_face()[:3, 3] for p in priors], axis=0)
    robot = _robot(world, parking, aim)
    f = robot.capture()
    seen = [r.evidence.get("radius_px", 0.0)
            for r in reader.read(f.color, f.intrinsics, f.T_world_camera, priors, depth=f.depth)]
    # a reader that needs each knob 15 % bigger than the parking position shows them
    strict = reader.with_config(replace(reader.config, min_radius_px=1.15 * max(seen)))
    read = make(ReadKnobs, world, robot, strict, {"object": "oven"}, {"unknown": "/unknown"})
    read.tick_once()
    assert read.status == S.FAILURE and "too small in the image" in read.feedback_message
    unread = py_trees.blackboard.Blackboard.get("/unknown")
    assert len(unread) == len(priors)

    views = make(KnobViews, world, robot, strict, {"object": "oven", "knobs": unread},
                 {"places": "/places"})
    views.tick_once()
    assert views.status == S.SUCCESS, views.feedback_message
    places = py_trees.blackboard.Blackboard.get("/places")
    best = places[0]
    assert math.hypot(best["x"] - parking.x, best["y"] - parking.y) >= 0.3   # another place
    there = _robot(world, (best["x"], best["y"], best["yaw"]), best["look_at"])
    again = make(ReadKnobs, world, there, strict, {"object": "oven", "knobs": unread},
                 {"states": "/states", "unknown": "/unknown"})
    again.tick_once()
    assert again.status == S.SUCCESS, again.feedback_message
    states = py_trees.blackboard.Blackboard.get("/states")
    assert states and all(world.get(k).state == v for k, v in states.items())


def test_a_knob_no_free_pose_reads_is_said_with_its_size_in_pixels(demo_world, reader):
    world = demo_world
    never = copy.copy(reader)
    never.validation_ = {"depth": [dict(r, right=False) for r in reader.validation_["depth"]]}
    robot = _robot(world, world.parking_positions("oven")[0][1], [0, 0, 0])
    views = make(KnobViews, world, robot, never, {"object": "oven", "knobs": ["oven_knob_2"]},
                 {"places": "/places"})
    views.tick_once()
    assert views.status == S.FAILURE
    assert "none reads its unread knobs" in views.feedback_message
    assert "oven_knob_2: no free pose reads it (at best" in views.feedback_message
    assert "px radius" in views.feedback_message


def test_free_poses_are_on_the_floor_of_a_room_and_clear_of_furniture(demo_world):
    from hearth.skills.knob_views import BEARINGS, DISTANCES
    from hearth.worldmodel.viewing import floor_clear
    world = demo_world
    boxes = {o.id: world.bounds_world(o.id) for o in world.large_objects()}
    free = floor_clear(world, 0.3, boxes)
    for lo, hi in boxes.values():                   # nobody parks inside a cupboard
        assert not free(*((np.asarray(lo) + np.asarray(hi)) / 2)[:2])
    parking = world.parking_positions("oven")[0][1]
    assert free(parking.x, parking.y)               # where the robot is sent to read them
    priors = knob_priors(world, "oven")
    face = np.mean([p.T_world_face()[:3, 3] for p in priors], axis=0)
    normal = priors[0].T_world_knob[:3, 2][:2]
    behind = ring(face[:2], -normal, (1.0,), (0,))[0]     # through the oven, into the wall
    assert not free(behind[0], behind[1])
    kept = [c for c in ring(face[:2], normal, DISTANCES, BEARINGS) if free(c[0], c[1])]
    assert kept and all(math.hypot(c[0] - face[0], c[1] - face[1]) >= 0.4 - 1e-9 for c in kept)
