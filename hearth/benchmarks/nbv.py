"""Next best view on seeded scenes whose first view is ambiguous or occluded.

Each scene is a cluttered kitchen table (see benchmarks/objects.py) with an occluder box put
close in front of a target object (one of the four on the table) as seen from the first camera
and one or two more around it at other angles;
only scenes where the first view does not recognise the target (hidden more than 50 %, or no
accepted hypothesis of it within 3 cm) are kept. The belief map knows roughly where the objects
are (truth plus 1.5 cm noise) but not the clutter. The planner gets the first view, the target's
hypotheses from the first detection (else the map's pose) and the objects competing for the
same place; the robot then looks from the best view (rendered with robot.sim's Kinect noise)
and detects again.

``recognised_within_two_views``: the target accepted within 3 cm in the first or the second
view. ``occlusion_avoided``: the target at most 10 % hidden in the second view (the occlusion
measured by rendering the target alone); ``occlusion_below_half`` the same at 50 %.
``random_view_*``: the same for a random collision-free candidate (a baseline).
``plan_failures``: scenes where no collision-free view was found (counted as failures).
``plan_ms_median``: wall time of plan_next_best_view (machine shared; see load average).
Reference (McGreavy et al.): recognised within two views in 82.5 % of trials, occlusion
avoided in 85 %, given as ratios (ours / theirs).
"""
from __future__ import annotations

import math
import os
import statistics
import time

import numpy as np

from hearth.benchmarks.objects import (OBJECTS, TABLE, box_object, cluttered_scene, demo_world,
                                observe, visible_fractions)
from perception.camera import Intrinsics

REFERENCE = dict(recognised_within_two_views=0.825, occlusion_avoided=0.85)
MATCH_M = 0.03


def add_arguments(parser) -> None:
    pass


def occluded_scene(rng, base):
    """(truth, T_world_camera, target): a cluttered table, a box right in front of the target
    as the first camera sees it and one or two more boxes around it (so that many other views
    are blocked too)."""
    truth, T_wc, _ = cluttered_scene(rng, n_clutter=(0, 3), occlude=False, base=base)
    target = OBJECTS[int(rng.integers(len(OBJECTS)))]
    Tt = truth.T_world(TABLE)
    p = truth.T_world(target)[:3, 3]
    placed = []
    for o in truth.get(TABLE).children:
        if o.id != target:
            q = truth.T_world(o.id)[:2, 3] - Tt[:2, 3]
            placed.append((q[0], q[1], 0.07))
    v = (T_wc[:3, 3] - p)[:2]
    front = math.atan2(v[1], v[0])
    angles = [front] + [front + rng.choice([-1, 1]) * rng.uniform(0.6, 2.6)
                        for _ in range(int(rng.integers(1, 3)))]
    for i, a in enumerate(angles):
        d = np.array([math.cos(a), math.sin(a)])
        side = np.array([-d[1], d[0]])
        for _ in range(30):
            q = p[:2] + d * rng.uniform(0.12, 0.18) + side * rng.uniform(-0.04, 0.04)
            local = q - Tt[:2, 3]
            if i == 0 or (abs(local[0]) < 0.58 and abs(local[1]) < 0.38 and all(
                    math.hypot(local[0] - x, local[1] - y) > r + 0.05 for x, y, r in placed)):
                break
        else:
            continue
        placed.append((local[0], local[1], 0.07))
        size = (0.03, rng.uniform(0.10, 0.16), rng.uniform(0.12, 0.20))
        truth.add_small_object(box_object(f"occluder_{i}", size, rng.uniform(0.1, 0.9, 3),
                                          local[0], local[1], a), TABLE)
    return truth, T_wc, target


def believed(base, truth, rng):
    """The belief: the objects near their true places (1.5 cm noise), no clutter."""
    from worldmodel.pose import Pose
    belief = base.copy()
    for oid in OBJECTS:
        p = truth.get(oid).pose
        belief.move_object(oid, TABLE, Pose(p.x + rng.normal(0, 0.015), p.y + rng.normal(0, 0.015),
                                            p.z, 0, 0, p.yaw))
    return belief


def recognised(det, truth, oid) -> bool:
    return any(h.object_id == oid and
               np.linalg.norm(h.position[:2] - truth.T_world(oid)[:2, 3]) < MATCH_M
               for h in det.accepted)


def hypotheses_for(det, belief, target):
    """The target's hypotheses from a detection, competitors at the same place, else the map."""
    from perception.nbv import ObjectHypothesis, from_map
    p = belief.T_world(target)[:2, 3]
    hs = [ObjectHypothesis(h.object_id, h.T_world_object, max(h.confidence, 0.05))
          for h in det.hypotheses if np.linalg.norm(h.position[:2] - p) < 0.06]
    if not any(h.object_id == target for h in hs):
        hs = from_map(belief, target) + hs
    return hs[:4]


def _median(xs, nd=1):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return round(statistics.median(xs), nd) if xs else None


def run(args) -> dict:
    from perception.nbv import plan_next_best_view
    from perception.errors import PerceptionError
    from perception.objects import detect_objects
    n = args.scenarios or (8 if args.quick else 60)
    rng = np.random.default_rng(args.seed)
    base = demo_world()
    K = Intrinsics.kinect()
    rec2 = avoided = below_half = rnd_avoided = rnd_below = 0
    vis1s, vis2s, ms, cpu, tried, occluded_first = [], [], [], [], 0, 0
    plan_failures: list[str] = []
    while len(ms) < n and tried < 20 * n:
        tried += 1
        truth, T1, target = occluded_scene(rng, base)
        belief = believed(base, truth, rng)
        depth, color, r = observe(truth, T1, rng, K)
        vis1 = visible_fractions(truth, r, T1, K, [target])[target]
        try:
            det1 = detect_objects(belief, depth, color, K, T1)
        except PerceptionError:
            continue  # the first camera missed the table altogether: not an NBV scene
        if vis1 >= 0.5 and recognised(det1, truth, target):
            continue  # the first view is neither ambiguous nor occluded
        occluded_first += vis1 < 0.5
        hs = hypotheses_for(det1, belief, target)
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            views = plan_next_best_view(belief, hs, depth, K, T1, current_base=T1[:2, 3])
        except PerceptionError as err:  # no free view: a failed scene
            ms.append((time.perf_counter() - t0) * 1000)
            cpu.append((time.process_time() - c0) * 1000)
            plan_failures.append(f"{target}: {err}")
            continue
        ms.append((time.perf_counter() - t0) * 1000)
        cpu.append((time.process_time() - c0) * 1000)
        T2 = views[0].T_world_camera
        d2, c2, r2 = observe(truth, T2, rng, K)
        vis2 = visible_fractions(truth, r2, T2, K, [target])[target]
        try:
            det2 = detect_objects(belief, d2, c2, K, T2)
            seen2 = recognised(det2, truth, target)
        except PerceptionError:  # e.g. no surface in view: not recognised
            seen2 = False
        rec2 += recognised(det1, truth, target) or seen2
        avoided += vis2 >= 0.9
        below_half += vis2 >= 0.5
        vis1s.append(vis1)
        vis2s.append(vis2)
        Tr = views[int(rng.integers(len(views)))].T_world_camera
        _, _, rr = observe(truth, Tr, rng, K)
        visr = visible_fractions(truth, rr, Tr, K, [target])[target]
        rnd_avoided += visr >= 0.9
        rnd_below += visr >= 0.5
    m = len(ms)
    rw2 = round(rec2 / m, 4) if m else None
    oa = round(avoided / m, 4) if m else None
    try:
        load = round(os.getloadavg()[0], 2)
    except OSError:  # pragma: no cover
        load = None
    return dict(
        scenes=m, scenes_tried=tried, seed=args.seed, first_view_occluded=occluded_first,
        plan_failures=len(plan_failures),
        recognised_within_two_views=rw2, occlusion_avoided=oa,
        occlusion_below_half=round(below_half / m, 4) if m else None,
        random_view_occlusion_avoided=round(rnd_avoided / m, 4) if m else None,
        random_view_occlusion_below_half=round(rnd_below / m, 4) if m else None,
        target_visible_first_view_median=_median(vis1s, 3),
        target_visible_second_view_median=_median(vis2s, 3),
        plan_ms_median=_median(ms), plan_ms_p90=round(float(np.percentile(ms, 90)), 1) if ms else None,
        plan_cpu_ms_median=_median(cpu), load_average_1min=load,
        targets=dict(recognised_within_two_views=0.95, occlusion_avoided=0.95),
        reference=REFERENCE,
        ratio_recognised_to_reference=round(rw2 / REFERENCE["recognised_within_two_views"], 3)
        if rw2 is not None else None,
        ratio_occlusion_avoided_to_reference=round(oa / REFERENCE["occlusion_avoided"], 3)
        if oa is not None else None,
    )
