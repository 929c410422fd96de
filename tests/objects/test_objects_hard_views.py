"""Small objects where the fetch suite missed them (issue 43), each detected from the pose
that sees it best while looking at its surface as the search does: standing at the back of
an open drawer, lying on a shelf at the head's height (its top out of sight), on a shelf
above the head (seen from below); and the suite never puts an object where it runs into its
furniture."""
from __future__ import annotations

import math

import numpy as np

from hearth.executive.scenarios import Case, make_case_scenario, place_on, resolve_world
from hearth.perception.objects import detect_objects
from hearth.robot.clock import SimClock
from hearth.robot.scenario import visible_pixels
from hearth.robot.simulated import SimulatedRobot
from hearth.skills.objects import capture
from hearth.worldmodel.containers import search_states
from hearth.worldmodel.geometry import object_meshes, small_object_meshes
from hearth.worldmodel.pose import Pose

#: A generated home with a book standing in the bottom drawer of a chest of drawers.
DRAWER_HOME, BOOK = "home:304", "crimson_book"


def _view(truth, belief, object_id, aim):
    """Open what the search opens, stand where the object is seen best, look at ``aim``
    and capture (truth and belief agree: no localisation error)."""
    for part, value in search_states(truth, object_id).items():
        truth.set_joint_state(part, value)
        belief.set_joint_state(part, value)
    n, (x, y, yaw) = visible_pixels(truth, object_id)
    assert n >= 200
    robot = SimulatedRobot(truth, clock=SimClock(), start_pose=Pose.planar(x, y, yaw), seed=1)
    robot.look_at(aim)
    return capture(robot)


def _detected(world_spec, object_id, seed, hide=""):
    """The scenario's truth and belief, and the detection of the object on its surface from
    the pose that sees it best, the head aimed at the surface's middle (the search does not
    know where on the surface the object stands)."""
    world = resolve_world(world_spec)
    sc, _, target = make_case_scenario(Case("fetch_object", seed, True, world=world_spec,
                                            target=object_id, hide=hide), world)
    truth, belief = sc.truth, sc.belief
    z = truth.T_world(target)[2, 3]
    level = min(truth.surfaces_of(truth.parent(target).id),
                key=lambda s: abs(s.T_world_surface[2, 3] - z))
    depth, color, K, T_wc = _view(truth, belief, target,
                                  level.T_world_surface[:3, 3] + (0, 0, 0.05))
    det = detect_objects(belief, depth, color, K, T_wc, candidates=[target], surface=level.name)
    return truth, target, det, T_wc


def _accepted_where_it_is(truth, target, det, within):
    found = [h for h in det.accepted if h.object_id == target]
    assert found, [(round(h.confidence, 2), h.position.round(3).tolist())
                   for h in det.hypotheses[:3]]
    assert np.linalg.norm(found[0].position - truth.T_world(target)[:3, 3]) < within


def test_a_book_standing_at_the_back_of_an_open_drawer_is_detected_where_it_is():
    truth, target, det, _ = _detected(DRAWER_HOME, BOOK, 1, hide="stay")
    assert truth.get(target).part, "the book is in a drawer"
    # the drawer's floor, not another face under it
    assert abs(-det.plane[3] - truth.T_world(target)[2, 3]) < 0.006
    # within the arm's grasp tolerance (8 cm); seen from above along its covers the fit
    # can settle a few centimetres off
    _accepted_where_it_is(truth, target, det, 0.05)


def test_a_book_lying_on_a_shelf_at_the_heads_height_is_found_from_its_edges():
    """Generated home 306, seed 300: a brown book on a 1.26 m shelf, the head at 1.30 m:
    only its spine and one side are in view (before: fitted 5 cm off at 0.15)."""
    truth, target, det, T_wc = _detected("home:306", "brown_book", 300)
    assert abs(T_wc[2, 3] - truth.T_world(target)[2, 3]) < 0.06, "seen from its own height"
    # within the grasp tolerance: along the face in view the fit can slide (6 cm here with
    # the head aimed at the shelf's middle; 3 mm aimed at the book)
    _accepted_where_it_is(truth, target, det, 0.08)


def test_a_bowl_on_a_shelf_above_the_head_stands_at_the_shelfs_height_not_its_underside():
    """Generated home 302, seed 301: a blue bowl on a 1.39 m shelf, the head at 1.31 m
    sees the board's lower face (before: the plane 1.4 cm low, the bowl refused at 0.14)."""
    truth, target, det, T_wc = _detected("home:302", "blue_bowl", 301)
    assert truth.T_world(target)[2, 3] > T_wc[2, 3], "above the head"
    assert det.plane is None
    _accepted_where_it_is(truth, target, det, 0.02)
    found = next(h for h in det.accepted if h.object_id == target)
    assert abs(found.position[2] - truth.T_world(target)[2, 3]) < 0.003


def _inside_box(points, mesh, shrink=0.001):
    v = np.asarray(mesh.vertices)
    lo, hi = v.min(0) + shrink, v.max(0) - shrink
    return np.all((points > lo) & (points < hi), axis=1)


def test_an_object_is_never_put_in_the_foot_of_a_pedestal_table():
    """The 'under' surface of a generated pedestal table lies on its foot: a spot there
    is refused (the object stays where it was), never one sunk in the foot."""
    world = resolve_world("home:303").copy()
    table = world.get("dining_table_1")
    foot = min(object_meshes(world, table, children=False),
               key=lambda lm: np.asarray(lm.mesh.vertices)[:, 2].max()).mesh
    assert np.asarray(foot.vertices)[:, 2].max() < 0.05, "the table stands on a low foot"
    under = next(s.id for s in table.surfaces if s.relation == "under")
    before = world.parent("grey_remote").id, world.get("grey_remote").pose
    for seed in range(5):
        if place_on(world, "grey_remote", table.id, np.random.default_rng(seed), level=under):
            pts = np.vstack([np.asarray(lm.mesh.sample_points_uniformly(500).points)
                             for lm in small_object_meshes(world, world.get("grey_remote"))])
            assert not _inside_box(pts, foot).any()
            assert math.isclose(world.T_world("grey_remote")[2, 3], 0.0, abs_tol=1e-6)
        else:
            assert (world.parent("grey_remote").id, world.get("grey_remote").pose) == before


def test_the_book_at_the_back_of_the_drawer_is_fetched():
    """The fetch mission on the same home: the search opens the drawer, looks in from the
    parking position and from a next best view, and finds the book (before: "no crimson
    book at the 14 places searched", its covers' lost returns counted against it)."""
    from hearth.executive.scenarios import run_case
    r = run_case(Case("fetch_object", 307, True, learned=False, warmup=20, world=DRAWER_HOME,
                      target=BOOK, hide="stay"))
    assert r.outcome == "succeeded", r.reason
    assert r.where == "drawer" and not r.wrong_success
    assert "drawer" in r.said[-1]
