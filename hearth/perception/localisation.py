"""Refining the robot's base pose on landmark objects (RAMCIP 4.2.3.4, 6.3.3.1).

The landmarks are the map's fixed large objects in the camera's field of view. Their expected
view is rendered at the believed camera pose (what the camera would see with perfect
localisation), the observed view is registered to it with ICP restricted to x, y and yaw, and
the resulting correction moves the believed base pose.

Starting errors can be large (15 cm and 8 degrees: 8 degrees moves a landmark 2 m away by
28 cm), beyond any ICP's basin, so a coarse grid over x, y and yaw around the base is scored
first against the depth image (``DepthAgreement``: model points agreeing with the observed
depth minus those the camera sees through), then ICP refines from the best cell.

Pure: the map, the depth image and poses in, a correction out; nothing is applied here (the
RefineLocalisation skill applies it through the robot adapter).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from hearth.perception.errors import PerceptionError
from hearth.perception.registration import (
    DepthAgreement, ICPConfig, ICPResult, RegistrationFailed, crop_box, observed_view,
    planar_params, register_planar, render_reference, single_threaded_blas,
)
from hearth.worldmodel.frames import planar_T, planar_about, room_at
from hearth.worldmodel.geometry import object_meshes, room_visuals, visual_mesh, LabelledMesh


@dataclass(frozen=True)
class LocalisationConfig:
    """``max_xy`` / ``max_yaw_deg``: the largest believed-pose error searched; ``grid_xy`` /
    ``grid_yaw_deg``: the coarse grid; ``min_weakest``: the smallest eigenvalue of the
    normalised information matrix (x, y in metres, yaw in metres at the cloud's radius) for the
    fix to count as well constrained; ``use_walls``: add the rooms' walls as landmarks."""
    icp: ICPConfig = ICPConfig(gates=(0.05, 0.02, 0.01), iterations=(10, 8, 8),
                               min_fitness=0.05, min_coverage=0.3)
    max_xy: float = 0.18
    max_yaw_deg: float = 9.0
    grid_xy: float = 0.06
    grid_yaw_deg: float = 2.0
    coarse_points: int = 600
    reference_scale: float = 0.25
    stride: int = 2
    max_range: float = 4.5
    margin: float = 0.25
    min_weakest: float = 0.005
    use_walls: bool = False
    #: A second basin of the coarse grid scoring at least this share of the best one is
    #: refined too; when it converges elsewhere (``distinct_m``, ``distinct_deg``) and fits
    #: about as well (``ambiguous_fit``), the view does not tell the two apart: not trusted.
    second_basin: float = 0.9
    distinct_m: float = 0.03
    distinct_deg: float = 1.5
    ambiguous_fit: float = 0.97
    #: ICP starts from the best cells of this many distinct basins of the coarse grid.
    starts: int = 3
    #: The fix must be pinned down: moved by ``probe_m`` or turned by ``probe_deg`` about the
    #: landmarks' centre, the depth agreement drops by at least ``min_sharpness`` (a share).
    probe_m: float = 0.02
    probe_deg: float = 2.0
    min_sharpness: float = 0.0
    #: A trusted fix is ``loose`` when, moved by any of ``ring_radii`` in any of 8
    #: directions (no turn), its depth agreement drops by less than ``min_ring_drop`` (a
    #: share), compared on the model points that fall on a reading at every probe: a long
    #: flat front slides along itself (a worktop fix 9.6 cm off and a bookshelf fix 8 cm off
    #: were trusted; docs/registration.md, "Loose fixes" and "Never a wrong corrected"). It is
    #: still the best pose the view gives (the skill applies it) but not one to say
    #: "corrected" on.
    ring_radii: tuple = (0.03, 0.06, 0.09, 0.12)
    min_ring_drop: float = 0.05
    #: Two views of the same base pose must agree: a fix is contradicted when it departs
    #: from an earlier view's estimate by more than ``max_contradiction_m`` along a direction
    #: that view pins down (an eigenvector of its information matrix with an eigenvalue of at
    #: least ``min_weakest``; ``contradiction``): twice the 2 cm a fix may be off, so that two
    #: estimates further apart cannot both be right (docs/registration.md, "Never a wrong
    #: corrected").
    max_contradiction_m: float = 0.04
    #: The corrected pose must explain at least this share of what the believed pose explains
    #: (depth agreement of the landmarks' points).
    min_improvement: float = 0.98
    #: Below this many points of the landmarks' fixed bodies, their doors and drawers (in the
    #: map's states) are registered against too.
    min_body_points: int = 300
    #: The final check: ICP restarted from the polished fix at the finest gate, for up to
    #: ``settle_iterations``, must converge within ``settle_m`` / ``settle_deg`` of it (the
    #: point-to-plane fit and the image score agree on the pose).
    settle_iterations: int = 30
    settle_m: float = 0.012
    settle_deg: float = 0.3


@dataclass
class LocalisationFix:
    """``correction``: 4x4 ``T_corrected_believed`` in the world frame (apply as
    ``correction @ T_world_base``); ``T_world_base``: the corrected base pose; ``dx``, ``dy``
    (m) and ``dyaw`` (rad): how far the base moves; ``ok``: the fix is trustworthy (enough
    overlap, converged, every direction constrained); ``quality``: the figures behind it, with
    ``loose`` (trusted, but a pose ``ring_m`` away explains the view nearly as well: applied,
    not reported as corrected; ``LocalisationConfig.min_ring_drop``)."""
    landmarks: list[str]
    correction: np.ndarray
    T_world_base: np.ndarray
    dx: float
    dy: float
    dyaw: float
    ok: bool
    quality: dict = field(default_factory=dict)
    icp: Optional[ICPResult] = None
    timings_ms: dict = field(default_factory=dict)
    #: What this view says about the base pose, for checking it against another view's
    #: (``contradiction``); None when the registration is no estimate at all (outside the
    #: searched range, ambiguous, or explaining the view worse than the believed pose).
    evidence: Optional[dict] = None
    #: The views registered (``LocalisationView``; one for ``refine_localisation``), as
    #: believed when the fix was made.
    views: list = field(default_factory=list)

    @property
    def loose(self) -> bool:
        """Trusted, but not pinned down within ``LocalisationConfig.ring_radii``."""
        return bool(self.quality.get("loose", False))


def visible_landmarks(world, K, T_world_camera: np.ndarray, max_range: float = 4.5) -> list[str]:
    """Ids of the map's fixed large objects whose bounds fall in the camera's view."""
    fixed = {o.id for o in world.landmarks()}
    # Only the room the camera is in: the renderer of the expected view has no walls.
    room = room_at(world, T_world_camera[0, 3], T_world_camera[1, 3])
    if room is not None:
        fixed = {i for i in fixed if world.room_of(i).id == room.id}
    seen = world.in_frustum(T_world_camera, K, max_range=max_range,
                            kinds=("LargeObject", "LargeArticulatedObject"))
    return [i for i in seen if i in fixed]


@dataclass(frozen=True, eq=False)
class LocalisationView:
    """One depth image taken for a fix and the poses the robot believed when it took it
    (``T_world_camera``, ``T_world_base``, 4x4), with the landmarks it was registered on.
    A fix keeps its view (``LocalisationFix.view``) so that a later fix from the same base
    pose can register every view together (``refine_localisation_views``)."""
    depth: np.ndarray
    K: object
    T_world_camera: np.ndarray
    T_world_base: np.ndarray
    landmarks: tuple

    def __repr__(self) -> str:       # it travels on the blackboard and into logs: no pixels
        return f"<view of {', '.join(self.landmarks)}>"

    def believed_at(self, T_world_base: np.ndarray) -> "LocalisationView":
        """The same image as if taken while the robot believed it stood at ``T_world_base``
        (the base has not moved; only the belief has, by a correction applied in between):
        the camera keeps its pose relative to the base."""
        T_new = np.asarray(T_world_base, dtype=float)
        if np.array_equal(T_new, self.T_world_base):
            return self
        move = T_new @ np.linalg.inv(self.T_world_base)
        return replace(self, T_world_camera=move @ self.T_world_camera, T_world_base=T_new)


class _Agreement:
    """``DepthAgreement`` over several views of one base pose: a correction's score is the
    sum of its scores in every view (each view's model points against its own image)."""

    def __init__(self, parts: list):
        self.parts = parts

    def __call__(self, Cs) -> np.ndarray:
        return sum(a(Cs) for a in self.parts)

    def against(self, C, Cs) -> tuple[np.ndarray, np.ndarray]:
        pairs = [a.against(C, Cs) for a in self.parts]
        return sum(p[0] for p in pairs), sum(p[1] for p in pairs)


class _Reference:
    """The landmarks' expected points of one or more views (a ``View`` each, world frame),
    with the views they belong to: ICP registers against all of them at once, the depth
    agreement scores each against its own image."""

    def __init__(self, parts: list, views: list):
        self.parts, self.views = parts, views
        self.points = np.concatenate([p.points for p in parts])
        self.normals = np.concatenate([p.normals for p in parts])

    def __len__(self) -> int:
        return len(self.points)

    def select(self, node_ids) -> "_Reference":
        return _Reference([p.select(node_ids) for p in self.parts], self.views)

    def agreement(self, max_points: int = 3000) -> _Agreement:
        return _Agreement([DepthAgreement(p.points, v.depth, v.K, v.T_world_camera,
                                          max_points=max_points)
                           for p, v in zip(self.parts, self.views) if len(p)])


@single_threaded_blas
def refine_localisation(world, depth: np.ndarray, K, T_world_camera: np.ndarray,
                        T_world_base: np.ndarray, cfg: LocalisationConfig = LocalisationConfig(),
                        landmarks: Optional[list[str]] = None) -> LocalisationFix:
    """The base-pose correction from one depth image taken at the believed ``T_world_camera``
    (the camera as the robot believes it is; ``T_world_base`` likewise, 4x4).

    Raises PerceptionError when no landmark is in view, RegistrationFailed when the view
    does not overlap the landmarks enough.
    """
    ids = landmarks if landmarks is not None else visible_landmarks(world, K, T_world_camera,
                                                                    cfg.max_range)
    if not ids:
        raise PerceptionError("no landmark in view")
    view = LocalisationView(depth, K, np.asarray(T_world_camera, dtype=float),
                            np.asarray(T_world_base, dtype=float), tuple(ids))
    return refine_localisation_views(world, [view], cfg)


@single_threaded_blas
def refine_localisation_views(world, views: list, cfg: LocalisationConfig = LocalisationConfig()
                              ) -> LocalisationFix:
    """The base-pose correction from one or more views (``LocalisationView``) taken from one
    base pose, the robot only turning its head between them, registered together: one
    planar correction moves every view's observed points onto its landmarks, and every
    check of the fix (convergence, the information matrix, the searched range, a second
    basin, the ring) reads all views at once. Two flat fronts that each leave a direction
    free (a cabinet, then a worktop at right angles to it) pin the pose down together.
    The correction is about the belief of the last view (``views[-1].T_world_base``); a
    correction applied between views is undone in the earlier ones
    (``LocalisationView.believed_at``).

    Raises RegistrationFailed when the views do not overlap their landmarks enough.
    """
    t0 = time.perf_counter()
    T_world_base = np.asarray(views[-1].T_world_base, dtype=float)
    views = [v.believed_at(T_world_base) for v in views]
    ids = list(dict.fromkeys(i for v in views for i in v.landmarks))
    refs = []
    for v in views:
        meshes = []
        for oid in v.landmarks:
            meshes += object_meshes(world, world.get(oid), children=False)
        if cfg.use_walls:
            for room in world.rooms:
                for vis in room_visuals(room, world):
                    if vis.name == "wall":
                        meshes.append(LabelledMesh(room.id, room.id,
                                                   visual_mesh(vis).transform(room.pose.matrix()),
                                                   tuple(vis.color), vis.material, vis.name))
        refs.append(render_reference(meshes, v.K, v.T_world_camera, scale=cfg.reference_scale,
                                     max_range=cfg.max_range))
    ref = _Reference(refs, views)
    # Doors, drawers and knobs may not be where the map has them (a door left ajar): the
    # whole objects are rendered (so a closed door hides what it hides) but only the fixed
    # bodies (and walls) are registered against, unless they show too little (a fridge seen
    # from the front is all door); ``quality["parts_used"]`` says so.
    bodies = ref.select(list(ids) + [r.id for r in world.rooms])
    parts_used = len(bodies) < cfg.min_body_points
    if len(ref) < cfg.icp.min_points:
        raise RegistrationFailed(f"the landmarks {ids} would cover only {len(ref)} points")
    t1 = time.perf_counter()
    srcs = []
    for v, r in zip(views, refs):
        obs = observed_view(v.depth, v.K, v.T_world_camera, cfg.stride)
        if len(r):
            lo, hi = r.points.min(0), r.points.max(0)
            srcs.append(obs.points[crop_box(obs.points, lo, hi, cfg.margin)])
    src = np.concatenate(srcs)
    t2 = time.perf_counter()
    base = T_world_base[:3, 3]
    try:
        res, T0, alt = _register(bodies if not parts_used else ref, src, base, cfg)
    except RegistrationFailed:
        if parts_used:
            raise
        parts_used = True
        res, T0, alt = _register(ref, src, base, cfg)
    used = ref if parts_used else bodies
    agree = used.agreement()
    if not parts_used and len(ref) > len(bodies) + cfg.icp.min_points:
        # Doors and drawers in view: where the fit on the bodies alone explains the view
        # worse than the believed pose (ICP pulled onto an open door beside a carcass side),
        # register on everything as the map has it, and keep that when the bodies agree
        # with it better.
        s_res, s_none = agree(np.stack([res.T, np.eye(4)]))
        if s_res < cfg.min_improvement * s_none:
            try:
                res2, _, alt2 = _register(ref, src, base, cfg)
            except RegistrationFailed:
                res2 = None
            if res2 is not None and agree(res2.T[None])[0] > s_res:
                res, alt, parts_used = res2, alt2, True
    # Converged, not merely a small residual (a stopped ICP with a small residual sat 4.5 cm
    # off on a cupboard front in a generated home): ICP restarted from the polished fix
    # settles next to it. The result's flag says so from here on.
    res.converged, settle_m, settle_deg = _settles(res.T, src, ref if parts_used else bodies,
                                                   base, cfg)
    t4 = time.perf_counter()
    C = res.T
    T_new = C @ T_world_base
    dyaw = math.atan2(C[1, 0], C[0, 0])
    dx, dy = (T_new[:3, 3] - base)[:2]
    weakest = float(np.linalg.eigvalsh(_scaled(res.information, ref.points))[0]) \
        if res.information is not None else 0.0
    # A correction beyond what was searched is ICP wandering off, not a fix; and a fix must
    # explain the view better than the believed pose does (ICP can be pulled away by what the
    # landmarks' fixed bodies do not model: open doors, things on shelves).
    inside = math.hypot(dx, dy) <= math.hypot(cfg.max_xy, cfg.max_xy) + 0.03 and \
        abs(math.degrees(dyaw)) <= cfg.max_yaw_deg + 1.0
    s_fix, s_believed = agree(np.stack([C, np.eye(4)]))
    better = float(s_fix) >= cfg.min_improvement * float(s_believed)
    sharp = _sharpness(C, agree, used.points.mean(axis=0), cfg)
    parts_through = _parts_through(ref, bodies, C) if not parts_used else 0.0
    ok = bool(res.converged) and weakest >= cfg.min_weakest \
        and inside and alt is None and better and sharp >= cfg.min_sharpness
    ring, ring_m = _ring_drop(C, agree, used.points.mean(axis=0), cfg,
                              _weakest_direction(res.information, used.points))
    doubts = [what for bad, what in (
        (not res.converged, "the registration did not converge"),
        (weakest < cfg.min_weakest, f"the view constrains one direction too little "
                                    f"(weakest {weakest:.3f} < {cfg.min_weakest})"),
        (not inside, "the correction lies outside the searched range"),
        (alt is not None, "another pose explains the view as well"),
        (not better, "it explains the view no better than the believed pose"),
        (sharp < cfg.min_sharpness, "a nearby pose explains the view as well"))
        if bad]
    evidence = None
    if inside and alt is None and better and res.information is not None:
        evidence = fix_evidence(ids, T_new, (ref if parts_used else bodies).points,
                                res.information)
    quality = dict(fitness=round(res.fitness, 4), coverage=round(res.coverage, 4),
                   residual_mm=round(res.residual * 1000, 3), converged=res.converged,
                   weakest=round(weakest, 4), landmarks=len(ids), points=len(src),
                   ambiguous=alt is not None, within_search=inside,
                   agreement=int(s_fix), agreement_believed=int(s_believed),
                   sharpness=round(sharp, 4), ring_drop=round(ring, 4), ring_m=ring_m,
                   parts_through=round(parts_through, 4),
                   loose=bool(ok and ring < cfg.min_ring_drop),
                   parts_used=parts_used, doubts=doubts,
                   settle_mm=round(1000 * settle_m, 2) if math.isfinite(settle_m) else None,
                   settle_deg=round(settle_deg, 3) if math.isfinite(settle_deg) else None,
                   views=len(views))
    return LocalisationFix(ids, C, T_new, float(dx), float(dy), float(dyaw), ok, quality, res,
                           {"reference": 1000 * (t1 - t0), "observed": 1000 * (t2 - t1),
                            "registration": 1000 * (t4 - t2)}, evidence, views)


def fix_evidence(landmarks, T_world_base: np.ndarray, target_points: np.ndarray,
                 information: np.ndarray) -> dict:
    """A view's estimate of the base pose in plain numbers (it travels on the blackboard):
    ``pose`` (x, y [m], yaw [rad], world), ``centre`` (x, y) the registration's centre of
    rotation (the target points' mean, as ``register_planar`` turns about it), ``radius`` (m,
    their spread) and ``information`` (3x3 nested lists, J^T J / n over x, y and radius * yaw:
    metres in every direction, as ``weakest`` reads it)."""
    pts = np.asarray(target_points, dtype=float)
    c, radius = _spread(pts)
    T = np.asarray(T_world_base, dtype=float)
    return dict(landmarks=list(landmarks),
                pose=[float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0])],
                centre=[float(c[0]), float(c[1])], radius=radius,
                information=_scaled(np.asarray(information, dtype=float), pts).tolist())


def contradiction(earlier: dict, later: dict, min_weakest: float) -> float:
    """How far (m) ``later``'s estimate of the base pose departs from ``earlier``'s along the
    directions ``earlier``'s view pins down (``fix_evidence`` dicts of the same base pose,
    the robot not having driven between them). The difference is taken as a planar move
    about ``earlier``'s centre, (dx, dy, radius * dyaw), and projected onto each eigenvector
    of ``earlier``'s information matrix whose eigenvalue is at least ``min_weakest``: a
    direction the view leaves free (along a flat front) carries no evidence, as in the
    degeneracy analysis of Zhang, Kaess and Singh (ICRA 2016). 0 when it pins down none."""
    D = planar_T(*later["pose"]) @ np.linalg.inv(planar_T(*earlier["pose"]))
    c = np.array([*earlier["centre"], 0.0, 1.0])
    moved = (D @ c)[:2] - c[:2]
    d = np.array([moved[0], moved[1], earlier["radius"] * math.atan2(D[1, 0], D[0, 0])])
    values, vectors = np.linalg.eigh(np.asarray(earlier["information"], dtype=float))
    pinned = values >= min_weakest
    if not pinned.any():
        return 0.0
    return float(np.max(np.abs(vectors[:, pinned].T @ d)))


def _register(ref, src, base, cfg):
    """Coarse grid about the base (the believed-pose error is a rotation about the robot),
    then planar ICP from the best cells of up to ``cfg.starts`` distinct basins; the result
    that explains the depth image best (``DepthAgreement``) wins, polished by a small local
    search on that score. Returns (result, its start, a distinct result that fits about as
    well, or None: an ambiguous view)."""
    coarse = ref.agreement(max_points=cfg.coarse_points)
    # Grids centred on no correction (the believed pose itself is a candidate): an odd
    # number of cells, e.g. yaw -8..8 in steps of 2 rather than -9..9, which misses 0.
    nx, na = int(cfg.max_xy / cfg.grid_xy + 1e-9), int(cfg.max_yaw_deg / cfg.grid_yaw_deg + 1e-9)
    xs = cfg.grid_xy * np.arange(-nx, nx + 1)
    yaws = np.radians(cfg.grid_yaw_deg * np.arange(-na, na + 1))
    cands = np.stack([planar_about(x, y, a, base) for a in yaws for x in xs for y in xs])
    scores = coarse(cands)
    order = np.argsort(-scores)
    starts = [order[0]]
    for i in order[1:]:
        if len(starts) >= cfg.starts or scores[i] < cfg.second_basin * scores[order[0]]:
            break
        if all(_distinct(cands[i], cands[k], base, 2 * cfg.grid_xy * 0.99,
                         2 * cfg.grid_yaw_deg * 0.99) for k in starts):
            starts.append(i)      # not a neighbour of a start: another basin
    fine = ref.agreement()
    results = []
    for k, i in enumerate(starts):
        try:
            r = register_planar(src, ref.points, ref.normals, T_init=cands[i], cfg=cfg.icp,
                                scorer=fine, search_range=0.06, search_step=0.005)
        except RegistrationFailed:
            if k == 0:
                raise
            continue
        results.append((float(fine(r.T[None])[0]), r, cands[i]))
    results.sort(key=lambda t: -t[0])
    best_score, res, T0 = results[0]
    res.T, best_score = _polish(res.T, fine, best_score, base)
    alt = None
    for sc, r, _ in results[1:]:
        if _distinct(r.T, res.T, base, cfg.distinct_m, cfg.distinct_deg) and \
                sc >= cfg.ambiguous_fit * best_score:
            alt = r
            break
    return res, T0, alt


def _settles(T: np.ndarray, src, ref, base: np.ndarray, cfg) -> tuple[bool, float, float]:
    """Whether ICP restarted from ``T`` at the finest gate converges near ``T`` (the
    converged flag of the first ICP speaks of the pose before polishing, and with few
    iterations per stage a good fit often stops just short of the tolerance)."""
    icp = replace(cfg.icp, gates=(cfg.icp.gates[-1],), iterations=(cfg.settle_iterations,))
    try:
        r = register_planar(src, ref.points, ref.normals, T_init=T, cfg=icp)
    except RegistrationFailed:
        return False, math.inf, math.inf
    D = r.T @ np.linalg.inv(T)
    moved = float(np.hypot(*((D @ np.append(base[:3], 1.0))[:2] - base[:2])))
    turned = abs(math.degrees(math.atan2(D[1, 0], D[0, 0])))
    return bool(r.converged) and moved <= cfg.settle_m and turned <= cfg.settle_deg, \
        moved, turned


def _polish(T: np.ndarray, score, best: float, base: np.ndarray, step_m: float = 0.01,
            step_deg: float = 0.5, rounds: int = 12) -> tuple[np.ndarray, float]:
    """Hill-climb the depth agreement from ``T`` in x, y and yaw about the base (steps
    halving from 1 cm / 0.5 deg): ICP minimises point-to-plane distances over gated
    correspondences, which a flat face can satisfy with a wrong turn and shift; the image
    score sees the face's edges. Written here: a six-neighbour pattern search over three
    parameters needs no optimiser library."""
    for _ in range(rounds):
        moves = [planar_about(dx, dy, da, base) @ T for dx, dy, da in
                 ((step_m, 0, 0), (-step_m, 0, 0), (0, step_m, 0), (0, -step_m, 0),
                  (0, 0, math.radians(step_deg)), (0, 0, -math.radians(step_deg)))]
        s = score(np.stack(moves))
        k = int(np.argmax(s))
        if s[k] > best:
            T, best = moves[k], float(s[k])
        else:
            step_m, step_deg = step_m / 2, step_deg / 2
            if step_m < 0.001:
                break
    return T, best


def _sharpness(C: np.ndarray, agree, centre: np.ndarray, cfg) -> float:
    """How much the depth agreement drops when the fix is moved by ``probe_m`` along x or y,
    or turned by ``probe_deg`` about the landmarks' centre, in the worst of those six
    directions (a share of the agreement at the fix). Near zero or below: the image does not
    pin that direction down (a flat front seen square on turns about its centre freely), and
    ICP's information matrix, built from gated correspondences, can miss it."""
    a = math.radians(cfg.probe_deg)
    return _worst_drop(C, agree, centre, ((cfg.probe_m, 0, 0), (-cfg.probe_m, 0, 0),
                                          (0, cfg.probe_m, 0), (0, -cfg.probe_m, 0),
                                          (0, 0, a), (0, 0, -a)))


def _weakest_direction(information, pts: np.ndarray):
    """The least constrained planar move (dx, dy [m], dyaw [rad]) of unit length at the
    landmarks' radius, from ICP's information matrix about the points' centre (the direction
    a flat front slides along); None without one."""
    if information is None or not np.any(information):
        return None
    radius = max(_spread(pts)[1], 1e-6)
    _, vectors = np.linalg.eigh(_scaled(np.asarray(information, dtype=float), pts))
    v = vectors[:, 0]
    return np.array([v[0], v[1], v[2] / radius])


def _ring_drop(C: np.ndarray, agree, centre: np.ndarray, cfg,
               weakest=None) -> tuple[float, float]:
    """How much the depth agreement drops when the fix is moved by each of
    ``cfg.ring_radii`` in 8 directions (45 degrees apart, no turn), and along the least
    constrained direction of the information matrix (``weakest``, turn included) from the
    first radius to the last in 1 cm steps, in the worst of them, as a share of the
    agreement at the fix, and how far that worst probe moves the centre (m). Each probe and
    the fix are scored on the same model points, those on a reading at both: the reference is
    rendered at the believed pose, so at the right correction a front cut by the image's
    edge pushes points off the image that a wrong slide along it keeps on the front (home 5's
    worktop: 9.6 cm along it, the truth scored 4 % under the fix on all points)."""
    moves = [(r * math.cos(a), r * math.sin(a), 0.0) for r in cfg.ring_radii
             for a in np.arange(8) * (math.pi / 4)]
    if weakest is not None:
        steps = np.arange(cfg.ring_radii[0], cfg.ring_radii[-1] + 1e-9, 0.01)
        moves += [tuple(k * weakest) for k in np.concatenate([steps, -steps])]
    probes = [planar_about(dx, dy, da, centre) @ C for dx, dy, da in moves]
    at_fix, at_probe = agree.against(C, np.stack(probes))
    shares = np.where(at_fix > 0, at_probe / np.maximum(at_fix, 1), 1.0)
    k = int(np.argmax(shares))
    return float(1.0 - shares[k]), round(float(math.hypot(*moves[k][:2])), 3)


def _parts_through(ref, bodies, C: np.ndarray) -> float:
    """The share of the landmarks' doors and drawers (rendered as the map has them, not
    registered against) that the camera sees through at the fix ``C``, of those on a
    reading; 0 when no part is in view. A figure, not a gate: a fix on a carcass frame alone
    sat 3.3 cm off in depth with its closed doors seen through at 97 % (home 314), but a
    right fix saw through 84 % of doors open in the truth (home 7): docs/registration.md."""
    through = valid = 0
    for part, body_part, v in zip(ref.parts, bodies.parts, ref.views):
        body = {body_part.nodes[i] for i in np.unique(body_part.labels)}
        keep = ~np.array([n in body for n in part.nodes] + [True], dtype=bool)[part.labels]
        if keep.sum() < 30:
            continue
        t, n = DepthAgreement(part.points[keep], v.depth, v.K, v.T_world_camera).seen_through(C)
        through, valid = through + t, valid + n
    return through / valid if valid >= 30 else 0.0


def _worst_drop(C: np.ndarray, agree, centre: np.ndarray, moves) -> float:
    """1 - the best depth agreement of the fix ``C`` moved by each of ``moves`` ((dx, dy,
    dyaw) about ``centre``) over the agreement at ``C`` (0 where that is not positive)."""
    probes = [planar_about(dx, dy, da, centre) @ C for dx, dy, da in moves]
    s = agree(np.stack([C] + probes))
    if s[0] <= 0:
        return 0.0
    return float(1.0 - np.max(s[1:]) / s[0])


def _distinct(A: np.ndarray, B: np.ndarray, base: np.ndarray, metres: float, degrees: float) -> bool:
    """Whether two corrections move the base to places further apart than ``metres`` or
    turn it differently by more than ``degrees``."""
    pa, pb = A[:3, :3] @ base + A[:3, 3], B[:3, :3] @ base + B[:3, 3]
    dyaw = math.degrees(abs(math.remainder(math.atan2(A[1, 0], A[0, 0])
                                           - math.atan2(B[1, 0], B[0, 0]), 2 * math.pi)))
    return float(np.linalg.norm((pa - pb)[:2])) > metres or dyaw > degrees


def _spread(pts: np.ndarray) -> tuple[np.ndarray, float]:
    """The points' mean and their RMS distance from it across the floor (m)."""
    c = pts.mean(axis=0)
    return c, float(np.sqrt(np.mean(np.sum((pts[:, :2] - c[:2]) ** 2, axis=1))))


def _scaled(info: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The information matrix over x, y, yaw [rad] as over x, y and yaw times the points'
    spread (metres in every direction)."""
    radius = _spread(pts)[1]
    S = np.diag([1.0, 1.0, 1.0 / max(radius, 1e-6)])
    return S @ info @ S


__all__ = ["LocalisationConfig", "LocalisationFix", "LocalisationView", "refine_localisation",
           "refine_localisation_views", "visible_landmarks",
           "planar_params", "fix_evidence", "contradiction"]
