"""Objects learned from views (hearth/perception/object_learning.py) against the models they were
rendered from.

``hearth bench learning --json [--homes N] [--seed S] [--world W ...] [--scenarios K]
[--jobs J]`` (``--jobs``: worlds learned in J worker processes at once).
Worlds as the other perception benches (hearth/benchmarks/_worlds.py; by default 3
generated homes, no demo home). In each world, for every kind of small object it holds
(``type``), up to ``--scenarios`` objects (default 2; 1 with ``--quick``) standing on a
surface open above: the simulated head camera looks at the object from bases around it, on
each of 16 bearings the nearest of 0.6-1.3 m that stands on free floor of its room (clear
of furniture by the robot's radius) and sees at least 40 % of it; at most 8 views spread
around it, rendered
with the simulated Kinect's noise. Each view's believed camera pose is the true one moved
by a localisation error of its own (1 cm and 0.5 degree sigma): the views must be
registered to each other. The learned model is compared with the true one:

- ``chamfer_mm``: symmetric chamfer distance (the median of both ways' nearest-neighbour
  distances, mm) between the learned mesh's surface and the true model's (base left out:
  no camera sees it), after aligning the learned model to the truth by ICP (the shape's
  error, not where it was put; ``placement_mm``: the alignment's translation);
- ``completeness``: share of the true surface within 5 mm of the learned one (an object's
  back against a wall is never seen);
- ``size_err_mm``: the largest error of the learned size (the footprint box's long and
  short side and the height, as the model reports them) against the truth's, measured from
  its surface;
- ``colour_right``: the learned dominant colour names the object's colour (the nearest of
  the generator's colour words, judged on hue and, for greys, brightness);
- ``learn_s``: wall time of segmentation, registration, fusion and meshing (rendering not
  included).

Pooled medians at the top (``chamfer_mm_median``, ``size_err_mm_median``,
``completeness_median``, ``learn_s_median``, ``colour_right_rate``), ``per_kind``,
``per_world`` and ``per_object`` (each object's chamfer, size error, learned and true size:
long side, short side, height, mm). Targets (issue 42): chamfer median <= 3 mm for objects >= 5 cm
(``chamfer_mm_median_5cm``), size error <= 5 mm.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from hearth.benchmarks import _worlds
from hearth.benchmarks._worlds import summary_stats

RINGS = (0.6, 0.75, 0.9, 1.1, 1.3)
ANGLES = 16
MAX_VIEWS = 8
LOC_SIGMA_M = 0.01
LOC_SIGMA_DEG = 0.5


def add_arguments(parser) -> None:
    _worlds.add_arguments(parser, homes=3)


def colour_name(rgb) -> str:
    """The nearest of the generator's colour words (hearth.perception.object_learning.colour_name)."""
    from hearth.perception.object_learning import colour_name as name
    from hearth.worldmodel.homegen_palette import COLOURS
    return name(rgb, COLOURS)


def views_of(truth, oid, K, rng):
    """(true T_world_camera, believed T_world_camera) of up to MAX_VIEWS views around the
    object (hearth.perception.object_learning.views_around, as the learn_object mission plans
    them), each kept when it sees at least 40 % of the object, spread round it."""
    from hearth.perception.object_learning import spread, views_around
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import scene_meshes, small_object_meshes
    room = truth.room_of(oid)
    c = truth.T_world(oid)[:3, 3]
    h = _worlds.extent(truth, oid)[1]
    Kq = K.scaled(0.25)
    scene = Scene(scene_meshes(truth, room_ids=[room.id]))
    alone = Scene(small_object_meshes(truth, truth.get(oid)))
    good = []
    for x, y, yaw in views_around(truth, c, room.id, radii=RINGS, bearings=ANGLES):
        T = _worlds.head_camera((x, y, yaw), c + (0, 0, h / 2))
        n_alone = int((alone.render(Kq, T).labels >= 0).sum())
        if n_alone >= 4 and scene.render(Kq, T).mask([oid]).sum() >= 0.4 * n_alone:
            good.append((x, y, T))
    out = []
    for x, y, T in spread(good, MAX_VIEWS, c):
        err = np.eye(4)
        yaw = math.radians(rng.normal(0, LOC_SIGMA_DEG))
        cz, sz = math.cos(yaw), math.sin(yaw)
        err[:2, :2] = [[cz, -sz], [sz, cz]]          # turned about the robot, not the origin
        err[:2, 3] = np.array([x, y]) - err[:2, :2] @ [x, y] + rng.normal(0, LOC_SIGMA_M, 2)
        out.append((T, err @ T))
    return out


def _surface(world, oid, T_world_object=None, spacing=0.002):
    from hearth.perception.objects import model_from_world
    m = model_from_world(world, oid, spacing)
    T = world.T_world(oid) if T_world_object is None else T_world_object
    return m.points @ T[:3, :3].T + T[:3, 3]


def _dims(points_world, support):
    from hearth.perception.object_learning import object_frame
    T = object_frame(points_world, support)
    Ti = np.linalg.inv(T)
    p = points_world @ Ti[:3, :3].T + Ti[:3, 3]
    e = p.max(axis=0) - p.min(axis=0)
    return np.array([max(e[0], e[1]), min(e[0], e[1]), p[:, 2].max()])


def align(truth, oid, model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, learned surface points in the world, the true surface's points): ``A`` (4x4,
    world) moves the learned model onto the true one by ICP: what is left is the shape's
    error, not where the views put it."""
    import open3d as o3d
    true_pts = _surface(truth, oid)
    learned = []
    o3d.utility.random.seed(0)
    for V, F, _ in model.meshes:
        m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))
        n = max(200, int(m.get_surface_area() / 0.002 ** 2))
        learned.append(np.asarray(m.sample_points_uniformly(n).points))
    L = np.vstack(learned) if learned else model.points
    L = L[L[:, 2] > 0.003]                              # the base: no camera saw it
    T = model.T_world_object
    Lw = L @ T[:3, :3].T + T[:3, 3]
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(Lw))
    dst = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(true_pts))
    reg = o3d.pipelines.registration.registration_icp(
        src, dst, 0.02, np.eye(4), o3d.pipelines.registration.TransformationEstimationPointToPoint())
    return np.asarray(reg.transformation), Lw, true_pts


def score(truth, oid, model) -> dict:
    """The learned ``model`` against the true object ``oid`` (see the module docstring)."""
    from scipy.spatial import cKDTree
    A, Lw, true_pts = align(truth, oid, model)
    La = Lw @ A[:3, :3].T + A[:3, 3]
    d1, _ = cKDTree(true_pts).query(La)
    d2, _ = cKDTree(La).query(true_pts)
    support = float(truth.T_world(oid)[2, 3])
    dims = _dims(true_pts, support)
    size_err = np.abs(np.asarray(model.size) - dims).max()
    obj = truth.get(oid)
    colour = (obj.color or "").split()[0] if obj.color else None
    got = colour_name(model.colours[0][0]) if model.colours else None
    return dict(chamfer_mm=round(1000 * float(np.median(np.concatenate([d1, d2]))), 2),
                completeness=round(float((d2 < 0.005).mean()), 3),
                size_err_mm=round(1000 * float(size_err), 1),
                size_mm=[round(1000 * float(x), 1) for x in model.size],
                true_size_mm=[round(1000 * float(x), 1) for x in dims],
                placement_mm=round(1000 * float(np.linalg.norm(La.mean(axis=0) - Lw.mean(axis=0))), 1),
                colour=colour, colour_learned=got,
                colour_right=None if colour is None else got == colour,
                at_least_5cm=bool(max(dims[0], dims[2]) >= 0.05),
                views=model.views_used)


def on_top(truth, oid, tops) -> bool:
    """Whether the object stands on one of the surfaces open above (``tops``)."""
    c = truth.T_world(oid)[:3, 3]
    for p in tops:
        u, v = p.local_xy(c[:2])[0]
        if abs(u) < p.size[0] / 2 and abs(v) < p.size[1] / 2 and abs(c[2] - p.height) < 0.03:
            return True
    return False


def learn_one(truth, oid, K, rng):
    """(model, seconds): learn ``oid`` from views around it where it stands in ``truth``
    (views_of, then hearth.perception.object_learning.learn_object with the objects the map
    knows around it, as LearnObject's belief does). PerceptionError when it cannot: fewer than
    two views, or the pipeline's own reasons."""
    from hearth.benchmarks._worlds import observe
    from hearth.perception.errors import PerceptionError
    from hearth.perception.object_learning import learn_object
    from hearth.worldmodel.learned import support_colour
    views = views_of(truth, oid, K, rng)
    if len(views) < 2:
        raise PerceptionError("fewer than two views see it")
    frames = []
    for T_true, T_believed in views:
        depth, color, _ = observe(truth, T_true, rng, K)
        frames.append((depth, color, K, T_believed))
    c = truth.T_world(oid)[:3, 3]
    known = [tuple(truth.bounds_world(o.id)) for o in truth.small_objects()
             if o.id != oid and np.hypot(*(truth.T_world(o.id)[:2, 3] - c[:2])) < 0.5]
    t0 = time.perf_counter()
    model = learn_object(frames, float(c[2]), c[:2], known=known,
                         reference_rgb=support_colour(truth, truth.parent(oid).id, c))
    return model, time.perf_counter() - t0


def run_world(spec: str, per_kind: int, seed: int) -> tuple[list[dict], str]:
    from hearth.perception.camera import Intrinsics
    from hearth.perception.errors import PerceptionError
    truth = _worlds.load(spec)
    K = Intrinsics.kinect()
    tops = [p for p in _worlds.places(truth) if p.kind == "top"]
    by_kind: dict[str, list[str]] = {}
    for o in truth.small_objects():
        if on_top(truth, o.id, tops):
            by_kind.setdefault(o.type, []).append(o.id)
    out = []
    for kind in sorted(by_kind):
        for j, oid in enumerate(sorted(by_kind[kind])[:per_kind]):
            rng = np.random.default_rng([seed, len(out), j])
            rec = dict(world=spec, kind=kind, object=oid)
            try:
                model, seconds = learn_one(truth, oid, K, rng)
            except PerceptionError as err:
                rec.update(failure=str(err))
                out.append(rec)
                continue
            rec["views_given"] = model.views_given
            rec["learn_s"] = round(seconds, 2)
            rec.update(score(truth, oid, model), failure=None)
            out.append(rec)
    return out, "" if out else "no small object on a surface open above"


def summarise(records: list[dict]) -> dict:
    ok = [r for r in records if not r.get("failure")]
    big = [r for r in ok if r["at_least_5cm"]]
    colour = [r for r in ok if r["colour_right"] is not None]
    out = dict(objects=len(records), learned=len(ok),
               failures=[f"{r['object']}: {r['failure']}" for r in records if r.get("failure")],
               chamfer_mm_median=summary_stats([r["chamfer_mm"] for r in ok], 2),
               chamfer_mm_median_5cm=summary_stats([r["chamfer_mm"] for r in big], 2),
               size_err_mm_median=summary_stats([r["size_err_mm"] for r in ok], 1),
               completeness_median=summary_stats([r["completeness"] for r in ok], 3),
               placement_mm_median=summary_stats([r["placement_mm"] for r in ok], 1),
               learn_s_median=summary_stats([r["learn_s"] for r in ok], 2),
               colour_right_rate=round(sum(r["colour_right"] for r in colour) / len(colour), 3)
               if colour else None)
    return out


def run(args) -> dict:
    specs = _worlds.world_specs(args, homes=3)
    n = args.scenarios or (1 if args.quick else 2)
    records: list[dict] = []
    jobs = max(1, int(getattr(args, "jobs", None) or 1))
    done = {}
    if jobs > 1 and len(specs) > 1:       # worlds in worker processes, pooled as one run
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(min(jobs, len(specs))) as pool:
            futures = [pool.submit(run_world, spec, n, args.seed + i) for i, spec in enumerate(specs)]
            done = {i: f.result() for i, f in enumerate(futures)}

    def one(i, spec):
        recs, why = done[i] if i in done else run_world(spec, n, args.seed + i)
        records.extend(recs)
        return recs, why or None
    out = _worlds.run_worlds("learning", specs, one, summarise)
    out["per_kind"] = {k: summarise([r for r in records if r["kind"] == k])
                       for k in sorted({r["kind"] for r in records})}
    out["per_object"] = [{k: r.get(k) for k in ("world", "object", "kind", "chamfer_mm",
                                                 "size_err_mm", "size_mm", "true_size_mm",
                                                 "failure")} for r in records]
    out["targets"] = dict(chamfer_mm_median_5cm=3.0, size_err_mm_median=5.0)
    return out


# -- learned models in place of drawn ones (hearth bench objects / missions --learned-models) --

#: Bump when what a model set is made of changes (cached sets are then made again).
MODEL_SET_RECIPE = 1


def stagings(truth, oid):
    """Worlds to learn ``oid`` in, best first: as it stands, when on a surface open above;
    then moved to the middle of each surface open above that it fits on, the other small
    objects of that furniture taken away (a person clears a space to show the robot a
    thing). Objects on shelves and inside cupboards are learned this way."""
    from hearth.benchmarks._worlds import fitting_objects
    tops = [p for p in _worlds.places(truth) if p.kind == "top"]
    if on_top(truth, oid, tops):
        yield truth
    for p in tops:
        if oid not in fitting_objects(truth, p):
            continue
        w = truth.copy()
        for o in list(w.children_of(p.object_id)):
            if getattr(o, "kind", "") == "SmallObject" and o.id != oid:
                w.remove_small_object(o.id)
        w.move_object(oid, p.object_id, p.to_parent(0.0, 0.0, 0.0), p.relation)
        yield w


def learn_model_set(spec: str, seed: int, directory, progress=None) -> dict:
    """Learn every small object of world ``spec`` from views (``stagings``: the first that
    works) and write the model set (hearth.worldmodel.learned.write_model_set) under
    ``directory``. Each learned mesh is put in its object's frame after aligning it to the
    true model (``align``): a learned object stands in the map where the views put it
    (within the robot's localisation error, which ``placement_mm`` measures), and the
    benches that use the set compare recognising the shapes and colours, not that offset.
    Returns the manifest."""
    from hearth.perception.camera import Intrinsics
    from hearth.perception.errors import PerceptionError
    from hearth.worldmodel.learned import read_model_set, write_model_set
    truth = _worlds.load(spec)
    K = Intrinsics.kinect()
    models, failed, scores = {}, {}, {}
    for i, o in enumerate(sorted(truth.small_objects(), key=lambda o: o.id)):
        why = "no surface open above that it fits on"
        for staged in stagings(truth, o.id):
            rng = np.random.default_rng([seed, i])
            try:
                model, _ = learn_one(staged, o.id, K, rng)
            except PerceptionError as err:
                why = str(err)
                continue
            A = align(staged, o.id, model)[0]
            T = np.linalg.inv(staged.T_world(o.id)) @ A @ model.T_world_object
            models[o.id] = [(V, F, rgb, T) for V, F, rgb in model.meshes]
            scores[o.id] = score(staged, o.id, model)
            break
        else:
            failed[o.id] = why
        if progress:
            progress(f"{spec}: {o.id} " + (f"learned ({scores[o.id]['chamfer_mm']} mm chamfer)"
                                           if o.id in models else f"not learned: {failed[o.id]}"))
    write_model_set(directory, models, failed,
                    info=dict(world=spec, seed=seed, recipe=MODEL_SET_RECIPE, scores=scores))
    return read_model_set(directory)


def model_set_dir(spec: str, seed: int = 0) -> Path:
    """Where the model set of world ``spec`` is cached (``$HEARTH_HOME_DIR``'s sibling
    ``learned/``), keyed by the world file's and the learning code's contents."""
    import hashlib
    import inspect

    from hearth.executive.scenarios import home_cache_dir, world_path
    from hearth.perception import object_learning, registration
    h = hashlib.sha256()
    h.update(Path(world_path(spec)).read_bytes())
    for mod in (object_learning, registration):
        h.update(inspect.getsource(mod).encode())
    h.update(f"{MODEL_SET_RECIPE}:{seed}".encode())
    name = "".join(c if c.isalnum() else "_" for c in spec)[-40:]
    return home_cache_dir().parent / "learned" / f"{name}-{h.hexdigest()[:12]}"


def model_set_for(spec: str, seed: int = 0, progress=None) -> Path:
    """The model set of world ``spec`` (learned on first use, then cached)."""
    from hearth.worldmodel.learned import MODEL_SET_FILE
    d = model_set_dir(spec, seed)
    if not (d / MODEL_SET_FILE).exists():
        learn_model_set(spec, seed, d, progress)
    return d
