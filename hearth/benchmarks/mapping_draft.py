"""The semantic draft of a home scored against its truth (issue 47, stages 2 and 3).

For each generated home (``--homes N`` from ``--seed S``, or ``--world W``): its fused map
FROM TRUE POSES (hearth/mapping/true_pose_map.py, cached), the draft
(hearth/perception/semantic_map.py, the classifier of hearth/mapping/classify.py trained on
other generated homes), the draft
world (hearth/worldmodel/draft.py), and ``score_draft(draft_world, true_world)``:

- rooms: each true room's best outline IoU with a drafted room (``room_iou_mean``), counts;
- large objects: drafted and true objects matched one to one by centre (within 0.5 m,
  nearest first); per type precision, recall, F1 (a match of the wrong type counts against
  both types); ``large_object_macro_f1`` over the types in the truth; ``appliance_f1``
  (oven, cooker, hob, fridge, exact type); ``centre_err_cm_median`` (the centre of the
  closed box: body and closed fronts, without handles and knobs), ``yaw_err_deg_median``
  (the front's direction; a rectangular table modulo 180 degrees; round tables and chairs
  left out), ``size_err_cm_median``;
- parts: each true handle of a matched object to the nearest drafted handle within 8 cm
  (``handles_found``, ``handle_err_mm_median``); its part: door vs drawer
  (``part_kind_accuracy``) and, for side-hinged doors, the hinge side
  (``hinge_side_accuracy``: the hinge on the same side of the handle);
- knobs found (within 4 cm) and their position error; parking positions: the share of
  drafted objects with one;
- ``build_s_median``: the draft stages per home (the fusion is the metric map's and is
  reported as ``fuse_s_median``, 0 when cached).

The JSON says ``"poses": "true"``: these figures are NOT the tour's; the metric map from a
tour replaces the true-pose fusion in ``hearth map build``.
"""
from __future__ import annotations

import math
import statistics
import time
from typing import Optional

import numpy as np

APPLIANCE_TYPES = ("oven", "cooker", "hob", "fridge")


def add_arguments(parser) -> None:
    parser.add_argument("--homes", type=int, default=None,
                        help="generated homes from --seed (default 3; 1 with --quick)")
    parser.add_argument("--world", action="append", default=None,
                        help="a world file to draft (repeatable; its true-pose map is fused)")
    parser.add_argument("--verbose", action="store_true", help="one line per home on stderr")


# -- scoring ------------------------------------------------------------------------------------

def _room_polygons(world):
    from hearth.worldmodel.frames import room_corners
    return [room_corners(r) for r in world.rooms if r.bounds is not None]


def _iou(a: np.ndarray, b: np.ndarray, cell: float = 0.01) -> float:
    import cv2
    lo = np.minimum(a.min(0), b.min(0)) - 0.05
    hi = np.maximum(a.max(0), b.max(0)) + 0.05
    shape = tuple((np.ceil((hi - lo) / cell)).astype(int)[::-1] + 1)
    ma, mb = np.zeros(shape, np.uint8), np.zeros(shape, np.uint8)
    cv2.fillPoly(ma, [np.round((a - lo) / cell).astype(np.int32)], 1)
    cv2.fillPoly(mb, [np.round((b - lo) / cell).astype(np.int32)], 1)
    union = np.count_nonzero(ma | mb)
    return float(np.count_nonzero(ma & mb) / union) if union else 0.0


def _yaw_err(a: float, b: float, sym: int) -> float:
    period = 2 * math.pi / sym
    d = math.remainder(a - b, period)
    return abs(math.degrees(d))


def score_draft(draft_world, true_world) -> dict:
    """The draft against the truth (see the module docstring): a dict of figures and the
    lists they are medians of."""
    from hearth.mapping.truth import truth_objects
    truth = truth_objects(true_world)
    draft = truth_objects(draft_world, drafted=True)
    # rooms
    tp, dp = _room_polygons(true_world), _room_polygons(draft_world)
    room_iou = [max((_iou(t, d) for d in dp), default=0.0) for t in tp]
    # objects: nearest centres first, one to one, within 0.5 m
    pairs = sorted(((float(np.linalg.norm(t.centre - d.centre)), i, j)
                    for i, t in enumerate(truth) for j, d in enumerate(draft)))
    used_t, used_d, matches = set(), set(), []
    for dist, i, j in pairs:
        if dist > 0.5 or i in used_t or j in used_d:
            continue
        used_t.add(i)
        used_d.add(j)
        matches.append((truth[i], draft[j], dist))
    types = sorted({t.type for t in truth} | {d.type for d in draft})
    counts = {k: dict(tp=0, fp=0, fn=0) for k in types}
    for t, d, _ in matches:
        if t.type == d.type:
            counts[t.type]["tp"] += 1
        else:
            counts[t.type]["fn"] += 1
            counts[d.type]["fp"] += 1
    for i, t in enumerate(truth):
        if i not in used_t:
            counts[t.type]["fn"] += 1
    for j, d in enumerate(draft):
        if j not in used_d:
            counts[d.type]["fp"] += 1
    centre = [100 * dist for _, _, dist in matches]
    yaw = [_yaw_err(d.yaw, t.yaw, t.symmetry) for t, d, _ in matches
           if t.symmetry and t.yaw is not None and d.yaw is not None and t.type == d.type]
    size = [100 * float(np.mean(np.abs(np.sort(t.size) - np.sort(d.size)))) for t, d, _ in matches]
    handle_err, found, kind_ok, hinge_ok, n_handles = [], 0, [], [], 0
    knob_err, n_knobs = [], 0
    for t, d, _ in matches:
        n_handles += len(t.handles)
        n_knobs += len(t.knobs)
        for hp, kind, sign in t.handles:
            best = min(d.handles, key=lambda h: np.linalg.norm(h[0] - hp), default=None)
            if best is None or np.linalg.norm(best[0] - hp) > 0.08:
                continue
            found += 1
            handle_err.append(1000 * float(np.linalg.norm(best[0] - hp)))
            kind_ok.append(best[1] == kind)
            if sign:
                hinge_ok.append(best[2] == sign)
        for kp in t.knobs:
            best = min(d.knobs, key=lambda k: np.linalg.norm(k - kp), default=None)
            if best is not None and np.linalg.norm(best - kp) < 0.04:
                knob_err.append(1000 * float(np.linalg.norm(best - kp)))
    return dict(rooms_true=len(tp), rooms_drafted=len(dp), room_iou=room_iou, counts=counts,
                centre_cm=centre, yaw_deg=yaw, size_cm=size, handle_mm=handle_err,
                handles_true=n_handles, handles_found=found, part_kind_ok=kind_ok,
                hinge_ok=hinge_ok, knobs_true=n_knobs, knob_mm=knob_err,
                objects_true=len(truth), objects_drafted=len(draft),
                parked=sum(1 for r in draft_world.rooms for o in r.objects if o.parking))


def _f1(c: dict) -> tuple[float, float, float]:
    p = c["tp"] / (c["tp"] + c["fp"]) if c["tp"] + c["fp"] else 0.0
    r = c["tp"] / (c["tp"] + c["fn"]) if c["tp"] + c["fn"] else 0.0
    return p, r, (2 * p * r / (p + r) if p + r else 0.0)


def _median(xs) -> Optional[float]:
    return round(float(statistics.median(xs)), 3) if xs else None


def summarise(scores: list[dict]) -> dict:
    """Figures over several homes' ``score_draft`` results."""
    counts: dict = {}
    for s in scores:
        for k, c in s["counts"].items():
            acc = counts.setdefault(k, dict(tp=0, fp=0, fn=0))
            for f in acc:
                acc[f] += c[f]
    per_type = {}
    for k, c in sorted(counts.items()):
        p, r, f = _f1(c)
        per_type[k] = dict(precision=round(p, 3), recall=round(r, 3), f1=round(f, 3),
                           true=c["tp"] + c["fn"], **c)
    true_types = [k for k, c in counts.items() if c["tp"] + c["fn"] > 0]
    app = dict(tp=0, fp=0, fn=0)
    for k in APPLIANCE_TYPES:
        for f in app:
            app[f] += counts.get(k, {}).get(f, 0)
    flat = lambda key: [x for s in scores for x in s[key]]
    kinds, hinges = flat("part_kind_ok"), flat("hinge_ok")
    handles_true = sum(s["handles_true"] for s in scores)
    knobs_true = sum(s["knobs_true"] for s in scores)
    objs = sum(s["objects_drafted"] for s in scores)
    return dict(
        large_object_macro_f1=round(float(np.mean([per_type[k]["f1"] for k in true_types])), 3)
        if true_types else None,
        appliance_f1=round(_f1(app)[2], 3),
        hinge_side_accuracy=round(float(np.mean(hinges)), 3) if hinges else None,
        part_kind_accuracy=round(float(np.mean(kinds)), 3) if kinds else None,
        centre_err_cm_median=_median(flat("centre_cm")),
        yaw_err_deg_median=_median(flat("yaw_deg")),
        size_err_cm_median=_median(flat("size_cm")),
        handle_err_mm_median=_median(flat("handle_mm")),
        handles_found=round(sum(s["handles_found"] for s in scores) / handles_true, 3)
        if handles_true else None,
        knobs_found=round(len(flat("knob_mm")) / knobs_true, 3) if knobs_true else None,
        knob_err_mm_median=_median(flat("knob_mm")),
        room_iou_mean=round(float(np.mean(flat("room_iou"))), 3) if flat("room_iou") else None,
        rooms_found=f"{sum(s['rooms_drafted'] for s in scores)}/{sum(s['rooms_true'] for s in scores)}",
        parking_share=round(sum(s["parked"] for s in scores) / objs, 3) if objs else None,
        per_type=per_type)


# -- the benchmark ------------------------------------------------------------------------------

def run(args) -> dict:
    import sys
    from hearth.mapping.classify import TRAIN_SEEDS, classifier, label
    from hearth.perception.semantic_map import draft_geometry
    from hearth.worldmodel.draft import draft_world
    from hearth.worldmodel.homegen import HomeConfig
    from hearth.worldmodel.world import World
    from hearth.mapping.true_pose_map import cached_fused, fused_from_true_poses
    verbose = getattr(args, "verbose", False)
    say = (lambda m: print(f"mapping_draft: {m}", file=sys.stderr, flush=True)) if verbose else None
    clf = classifier(progress=say)
    cases = []
    if getattr(args, "world", None):
        from hearth.worldmodel.io import load_world
        for w in args.world:
            cases.append((w, lambda w=w: _fuse_world(load_world(w), fused_from_true_poses)))
    else:
        n = args.homes or (1 if args.quick else 3)
        for seed in range(args.seed, args.seed + n):
            cases.append((f"home-{seed}", lambda seed=seed: cached_fused(seed, HomeConfig())))
    scores, per_world, build_s, fuse_s = [], {}, [], []
    for name, get in cases:
        t0 = time.perf_counter()
        world, pcd = get()
        fuse_s.append(time.perf_counter() - t0)
        P, N, C = np.asarray(pcd.points), np.asarray(pcd.normals), np.asarray(pcd.colors)
        t0 = time.perf_counter()
        d = label(draft_geometry(P, N), P, N, C, clf)
        result = draft_world(d, home_id="draft")
        build_s.append(time.perf_counter() - t0)
        s = score_draft(World(result.apartment), world)
        scores.append(s)
        one = summarise([s])
        one.pop("per_type")
        one.update(build_s=round(build_s[-1], 2), unlabelled=len(result.unlabelled),
                   objects=f"{s['objects_drafted']} drafted / {s['objects_true']} true")
        per_world[name] = one
        if say:
            say(f"{name}: macro F1 {one['large_object_macro_f1']}, rooms IoU "
                f"{one['room_iou_mean']}, centre {one['centre_err_cm_median']} cm, "
                f"{build_s[-1]:.1f} s")
    out = summarise(scores)
    out.update(poses="true", homes=len(cases), build_s_median=_median(build_s),
               fuse_s_median=_median(fuse_s), per_world=per_world,
               training_seeds=f"{TRAIN_SEEDS[0]}-{TRAIN_SEEDS[-1]}")
    return out


def _fuse_world(world, fuse):
    pcd, _ = fuse(world)
    return world, pcd
