"""ICP variants for registering an observed view to a rendered reference (RAMCIP 4.2.3.4).

The reference cloud is what the camera should see: the model rendered at the believed pose from
the current camera, with the renderer's exact normals. The observed cloud (the *source*) is
moved onto it (the *target*), so every result is ``T_target_source``, a correction in the
frame both clouds are given in (the world frame, in practice).

Three variants, one result type:

- ``register_6dof``: open3d's legacy point-to-plane ICP (measured fastest on our scenes, see
  docs/registration.md), coarse-to-fine gates, a Tukey kernel only in the last stage.
- ``register_planar``: x, y and yaw only (furniture and the robot move on the floor).
- ``register_joint``: one joint coordinate, a rotation about a hinge or a translation along a
  slide, clamped to the joint's limits.

The robust kernel is applied only once the clouds are roughly aligned: with a kernel scaled to
the sensor noise from the start, the points that should pull the model across a 10 cm error all
look like outliers, and a hidden inner CAD surface parallel to the visible one wins instead.

Every result carries ``fitness`` (fraction of source points with a correspondence within the
final gate), ``residual`` (RMS point-to-plane distance of those, metres) and ``converged``; a
registration with too little overlap raises ``RegistrationFailed`` (a PerceptionError).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from hearth.perception.errors import PerceptionError

reg = o3d.pipelines.registration

_controller = None


def single_threaded_blas(fn):
    """Run ``fn`` with OpenBLAS on one thread. Our matrix products are tall and thin
    (N x 3 @ 3 x 3): OpenBLAS splits them over threads that spin, and on a 2-core machine
    shared with other work that made two doors with handles 2x slower and the handle step 8x
    slower (measured: 274 ms vs 35 ms)."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        global _controller
        if _controller is None:
            from threadpoolctl import ThreadpoolController
            _controller = ThreadpoolController()
        with _controller.limit(limits=1, user_api="blas"):
            return fn(*args, **kwargs)
    return wrapper


@dataclass(frozen=True)
class ICPConfig:
    """Parameters of one registration. Lengths in metres.

    ``gates``: correspondence distance per stage, coarse to fine; the kernel (Tukey, scale
    ``robust_scale``) is used in the last stage only. ``voxel``: source downsampling (0: none).
    ``min_fitness`` / ``min_points``: below either, the registration fails (too little overlap).
    """
    voxel: float = 0.02
    gates: tuple[float, ...] = (0.10, 0.04, 0.015)
    iterations: tuple[int, ...] = (10, 8, 8)
    robust_scale: float = 0.01
    min_fitness: float = 0.3
    #: Fraction of the reference (target) points with a source point within the final gate.
    min_coverage: float = 0.0
    min_points: int = 60
    #: Weight of a point-to-point term added to the point-to-plane one in the planar and joint
    #: solvers: it keeps a direction that flat faces leave free (along a cupboard front)
    #: anchored at the silhouette instead of drifting.
    point_weight: float = 0.0
    #: An iteration moving less than this (metres; radians times 1 m) counts as converged.
    tolerance: float = 1e-5


@dataclass
class ICPResult:
    """``T``: 4x4 ``T_target_source``. ``inliers``: indices of source points with a
    correspondence in the last stage. ``information``: J^T J / n of the final stage, in the
    variant's parameters (6x6, 3x3 for x, y, yaw, or 1x1); small eigenvalues mean a direction
    the data barely constrains."""
    T: np.ndarray
    fitness: float
    residual: float
    converged: bool
    iterations: int
    inliers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    information: Optional[np.ndarray] = None
    value: Optional[float] = None   # the joint coordinate, for register_joint
    coverage: float = 1.0           # fraction of the reference explained by the source

    def summary(self) -> dict:
        return dict(fitness=round(self.fitness, 4), residual_mm=round(self.residual * 1000, 3),
                    converged=self.converged, iterations=self.iterations)


class RegistrationFailed(PerceptionError):
    """Too little overlap (or too few points) to trust a registration; ``result`` holds what
    was found anyway (None when nothing ran)."""

    def __init__(self, message: str, result: Optional[ICPResult] = None, node: str | None = None):
        super().__init__(message, node=node)
        self.result = result


# -- clouds --------------------------------------------------------------------------------

def voxel_downsample(points: np.ndarray, voxel: float, normals: Optional[np.ndarray] = None):
    """Points (and normals) reduced to one per ``voxel`` cube (open3d; averages a voxel)."""
    if voxel <= 0 or len(points) == 0:
        return points, normals
    pc = to_o3d(points, normals)
    pc = pc.voxel_down_sample(voxel)
    pts = np.asarray(pc.points)
    if normals is None:
        return pts, None
    n = np.asarray(pc.normals)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return pts, n


def to_o3d(points: np.ndarray, normals: Optional[np.ndarray] = None) -> o3d.geometry.PointCloud:
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    if normals is not None:
        pc.normals = o3d.utility.Vector3dVector(np.asarray(normals, dtype=np.float64))
    return pc


def transform(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ T[:3, :3].T + T[:3, 3]


def _check_overlap(result: ICPResult, n_source: int, cfg: ICPConfig, what: str) -> ICPResult:
    n_in = len(result.inliers)
    if n_in < cfg.min_points or result.fitness < cfg.min_fitness:
        raise RegistrationFailed(
            f"{what}: too little overlap (fitness {result.fitness:.2f}, {n_in} of {n_source} "
            f"points matched; need {cfg.min_fitness:.2f} and {cfg.min_points})", result)
    if result.coverage < cfg.min_coverage:
        raise RegistrationFailed(
            f"{what}: too little overlap (only {result.coverage:.0%} of the expected view "
            f"matched; need {cfg.min_coverage:.0%})", result)
    return result


def _coverage(target: np.ndarray, moved_source: np.ndarray, gate: float) -> float:
    if len(target) == 0 or len(moved_source) == 0:
        return 0.0
    d, _ = cKDTree(moved_source).query(target, k=1, distance_upper_bound=gate, workers=1)
    return float(np.mean(np.isfinite(d)))


def _require(points: np.ndarray, n: int, what: str) -> None:
    if len(points) < n:
        raise RegistrationFailed(f"{what}: only {len(points)} points (need {n})")


def _tukey_weights(r: np.ndarray, k: float) -> np.ndarray:
    u = np.clip(np.abs(r) / k, 0.0, 1.0)
    return (1.0 - u * u) ** 2


# -- 6-DoF: open3d ---------------------------------------------------------------------------

@single_threaded_blas
def register_6dof(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray,
                  T_init: Optional[np.ndarray] = None, cfg: ICPConfig = ICPConfig()) -> ICPResult:
    """Full rigid registration of ``source`` (N, 3) onto ``target`` (M, 3) with its unit
    normals, point-to-plane; returns ``T_target_source``."""
    T = np.eye(4) if T_init is None else np.asarray(T_init, dtype=float).copy()
    src, _ = voxel_downsample(np.asarray(source, dtype=float), cfg.voxel)
    _require(src, cfg.min_points, "6-DoF ICP")
    _require(target, cfg.min_points, "6-DoF ICP reference")
    src_pc, tgt_pc = to_o3d(src), to_o3d(target, target_normals)
    total = 0
    last = len(cfg.gates) - 1
    for stage, (gate, iters) in enumerate(zip(cfg.gates, cfg.iterations)):
        est = (reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=cfg.robust_scale))
               if stage == last and cfg.robust_scale > 0
               else reg.TransformationEstimationPointToPlane())
        res = reg.registration_icp(src_pc, tgt_pc, gate, T, est,
                                   reg.ICPConvergenceCriteria(1e-7, 1e-7, iters))
        T = np.asarray(res.transformation)
        total += iters
    # One more iteration tells whether the last stage had settled.
    res2 = reg.registration_icp(src_pc, tgt_pc, cfg.gates[-1], T, est,
                                reg.ICPConvergenceCriteria(1e-9, 1e-9, 1))
    T2 = np.asarray(res2.transformation)
    step = np.linalg.norm(T2[:3, 3] - T[:3, 3]) + np.linalg.norm(T2[:3, :3] - T[:3, :3])
    corr = np.asarray(res.correspondence_set)
    inliers = corr[:, 0].astype(np.int64) if len(corr) else np.zeros(0, dtype=np.int64)
    info, residual = None, float("inf")
    if len(corr):
        p = transform(T, src[corr[:, 0]])
        n = np.asarray(target_normals)[corr[:, 1]]
        J = np.hstack([np.cross(p, n), n])
        info = J.T @ J / len(J)
        # point-to-plane, like the other variants (open3d's inlier_rmse is point-to-point)
        r = np.einsum("ij,ij->i", p - np.asarray(target)[corr[:, 1]], n)
        residual = float(np.sqrt(np.mean(r ** 2)))
    out = ICPResult(T=T, fitness=float(res.fitness), residual=residual,
                    converged=bool(step < cfg.tolerance * 10), iterations=total, inliers=inliers,
                    information=info,
                    coverage=(_coverage(np.asarray(target), transform(T, src), 2 * cfg.gates[-1])
                              if cfg.min_coverage else 1.0))
    return _check_overlap(out, len(src), cfg, "6-DoF ICP")


# -- the ICP skeleton: associate, linearise, solve, converged ---------------------------------
#
# The planar and 1-DoF solvers (and objects.planar_icp) are written by hand because open3d's
# ICP estimates all six degrees of freedom and cannot be restricted to a subspace (x, y, yaw;
# or one joint coordinate); projecting its 6-DoF step afterwards is not the constrained
# optimum. Each loop reads like KISS-ICP's ``AlignPointsToMap``: associate the moved points
# with their nearest neighbours within the stage's gate, linearise the residuals in the
# variant's parameters (the textbook linearised point-to-plane step, Low 2004, with only the
# wanted columns in the Jacobian), solve the damped normal equations (iteratively reweighted
# with a Tukey kernel in the last stage), apply the step, stop when it is small. The pieces
# below are shared; a variant only brings its parameterisation (Jacobian and update).

def stages(cfg: ICPConfig):
    """(gate, iterations, robust) per stage, coarse to fine; the kernel in the last only."""
    last = len(cfg.gates) - 1
    for stage, (gate, iterations) in enumerate(zip(cfg.gates, cfg.iterations)):
        yield gate, iterations, stage == last and cfg.robust_scale > 0


def associate(tree: cKDTree, points: np.ndarray, gate: float):
    """Nearest neighbours of ``points`` among the tree's within ``gate``: (indices into
    ``points``, indices into the tree's points, distances)."""
    d, j = tree.query(points, k=1, distance_upper_bound=gate, workers=1)
    ok = np.isfinite(d)
    return np.nonzero(ok)[0], j[ok], d[ok]


def point_to_plane(p: np.ndarray, q: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Signed distances of points ``p`` from the planes through ``q`` with unit normals ``n``."""
    return np.einsum("ij,ij->i", p - q, n)


def kernel_weights(r: np.ndarray, robust: bool, scale: float) -> np.ndarray:
    """Tukey weights of residuals ``r`` at ``scale`` when ``robust``, else ones."""
    return _tukey_weights(r, scale) if robust else np.ones_like(r)


def normal_equations(J: np.ndarray, r: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """H = J^T W J and g = J^T W r of weighted residuals ``r`` (N,) with Jacobian ``J`` (N, k)."""
    Jw = J * w[:, None]
    return Jw.T @ J, Jw.T @ r


def solve(H: np.ndarray, g: np.ndarray, damping: float = 1e-6) -> Optional[np.ndarray]:
    """The damped Gauss-Newton step ``-(H + lambda I)^-1 g`` with lambda = ``damping`` tr(H):
    a direction nothing constrains (along one flat wall) stays put instead of running off.
    None when H is empty (no correspondence constrains anything)."""
    tr = float(np.trace(H))
    if tr < 1e-12:
        return None
    return -np.linalg.solve(H + (damping * tr + 1e-12) * np.eye(len(H)), g)


def converged(step, tolerance) -> bool:
    """Whether a step moved less than ``tolerance``: one size against one tolerance, or a
    size per quantity against a tolerance each (metres, radians), all under."""
    return bool(np.all(np.abs(np.asarray(step, dtype=float)) < tolerance))


# -- planar: x, y and yaw -----------------------------------------------------------------------

def planar_delta(x, c) -> np.ndarray:
    """The planar move of parameters ``x`` = (dx, dy, dyaw): a turn by dyaw about the vertical
    through ``c``, then a shift by (dx, dy). 4x4."""
    co, si = np.cos(x[2]), np.sin(x[2])
    D = np.eye(4)
    D[:2, :2] = [[co, -si], [si, co]]
    D[:2, 3] = c[:2] - D[:2, :2] @ c[:2] + x[:2]
    return D


def planar_plane_jacobian(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N, 3) Jacobian of point-to-plane residuals (normals ``n``) in (x, y, yaw), ``d`` the
    points' offsets from the centre of rotation: d(p)/d(yaw) = e_z x d."""
    return np.stack([n[:, 0], n[:, 1], n[:, 1] * d[:, 0] - n[:, 0] * d[:, 1]], axis=1)


def planar_point_jacobian(d: np.ndarray) -> np.ndarray:
    """(2N, 3) Jacobian of point-to-point residuals (the x residuals, then the y ones) in
    (x, y, yaw), ``d`` as in ``planar_plane_jacobian``."""
    one, zero = np.ones(len(d)), np.zeros(len(d))
    return np.concatenate([np.stack([one, zero, -d[:, 1]], axis=1),
                           np.stack([zero, one, d[:, 0]], axis=1)])


def planar_point_step(src: np.ndarray, dst: np.ndarray, turn: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The planar move (dx, dy, dyaw) about ``c``, and ``c``, that best takes points ``src``
    onto ``dst`` (both (N, 2) or (N, 3), x and y used) in the least-squares sense; without
    ``turn`` a shift only. Point-to-point residuals in x, y and yaw need no linearisation:
    the 2-D Kabsch solution is the exact minimiser, and it is what the normal equations of
    ``planar_point_jacobian`` approach as the step gets small."""
    c, cd = src[:, :2].mean(axis=0), dst[:, :2].mean(axis=0)
    H = (src[:, :2] - c).T @ (dst[:, :2] - cd)
    a = math.atan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1]) if turn else 0.0
    return np.array([cd[0] - c[0], cd[1] - c[1], a]), np.array([c[0], c[1], 0.0])


def _planar_search(T, info, c, radius, scorer, search_range, search_step):
    """The candidate along the weakest direction of ``info`` (+-``search_range`` m) the
    scorer likes best."""
    S = np.diag([1.0, 1.0, radius])       # yaw scaled to metres at the cloud's radius
    _, evecs = np.linalg.eigh(np.linalg.inv(S) @ info @ np.linalg.inv(S))
    v = evecs[:, 0]
    ks = np.arange(-search_range, search_range + 1e-9, search_step)
    cands = [planar_delta(np.array([k * v[0], k * v[1], k * v[2] / radius]), c) @ T for k in ks]
    return cands[int(np.argmax(np.asarray(scorer(cands))))]


@single_threaded_blas
def register_planar(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray,
                    T_init: Optional[np.ndarray] = None, cfg: ICPConfig = ICPConfig(),
                    tree: Optional[cKDTree] = None, scorer=None,
                    search_range: float = 0.2, search_step: float = 0.01,
                    turn: bool = True) -> ICPResult:
    """Registration restricted to a translation in x, y and a rotation about the world z axis
    (through the target's centroid, which keeps the three parameters well conditioned).
    Returns ``T_target_source``; ``information`` is 3x3 over (x, y, yaw [rad * radius]).
    Without ``turn`` the yaw is held (a shift in x, y only): for a body of revolution, whose
    surface leaves the yaw free, so that Gauss-Newton wanders along it.

    ``scorer(Ts) -> scores`` (higher is better) rates candidate transforms against the image
    (see ``DepthAgreement``). Point-to-plane leaves the direction along a flat front (a
    cupboard with closed doors) nearly free: after the first stage, the weakest direction of
    the information matrix is searched over +-``search_range`` metres with the scorer, which
    sees silhouettes and depth edges that gated correspondences cannot.
    """
    src, _ = voxel_downsample(np.asarray(source, dtype=float), cfg.voxel)
    _require(src, cfg.min_points, "planar ICP")
    target = np.asarray(target, dtype=float)
    tn = np.asarray(target_normals, dtype=float)
    _require(target, cfg.min_points, "planar ICP reference")
    tree = tree or cKDTree(target)
    T = np.eye(4) if T_init is None else np.asarray(T_init, dtype=float).copy()
    c = target.mean(axis=0)
    radius = float(np.sqrt(np.mean(np.sum((target[:, :2] - c[:2]) ** 2, axis=1))))
    total, done = 0, False
    info = np.zeros((3, 3))
    for stage, (gate, iterations, robust) in enumerate(stages(cfg)):
        for _ in range(iterations):
            total += 1
            p = transform(T, src)
            i_s, i_t, _ = associate(tree, p, gate)
            if len(i_s) < 6:
                break
            ps, q = p[i_s], target[i_t]
            r = point_to_plane(ps, q, tn[i_t])
            w = kernel_weights(r, robust, cfg.robust_scale)
            H, g = normal_equations(planar_plane_jacobian(tn[i_t], ps - c), r, w)
            info = H / max(w.sum(), 1e-9)
            if cfg.point_weight > 0:
                # point-to-point rows anchor what flat faces leave free (the silhouette)
                e = ps - q
                Hp, gp = normal_equations(planar_point_jacobian(ps - c),
                                          np.concatenate([e[:, 0], e[:, 1]]),
                                          np.tile(cfg.point_weight * w, 2))
                H, g = H + Hp, g + gp
            x = solve(H, g) if turn else solve(H[:2, :2], g[:2])
            if x is None:
                break
            x = x if turn else np.r_[x, 0.0]
            # Trust region: correspondences gated at ``gate`` say nothing about moves much
            # larger than it; a full Gauss-Newton step from a first, mostly wrong matching
            # along a weakly constrained direction jumps into another minimum.
            x *= min(1.0, 0.5 * gate / max(np.hypot(x[0], x[1]) + abs(x[2]) * radius, 1e-12))
            T = planar_delta(x, c) @ T
            if converged(np.sum(np.abs(x)), cfg.tolerance):    # metres, yaw at a 1 m lever
                done = stage == len(cfg.gates) - 1
                break
        if stage == 0 and scorer is not None and np.any(info):
            T = _planar_search(T, info, c, radius, scorer, search_range, search_step)
    moved = transform(T, src)
    i_s, i_t, _ = associate(tree, moved, cfg.gates[-1])
    r = point_to_plane(moved[i_s], target[i_t], tn[i_t])
    return _finish(T, moved, len(src), i_s, r, target, cfg, total, done, info, "planar ICP")


def _finish(T, moved, n_source, inliers, r, target, cfg, total, done, info, what, value=None):
    """The result of a constrained registration after its last step: ``moved`` the source
    points at ``T``, ``inliers`` those with a correspondence within the final gate and ``r``
    their point-to-plane residuals."""
    out = ICPResult(T=T, fitness=len(inliers) / max(n_source, 1),
                    residual=float(np.sqrt(np.mean(r ** 2))) if len(r) else float("inf"),
                    converged=done, iterations=total, inliers=inliers, information=info,
                    value=value,
                    coverage=(_coverage(target, moved, 2 * cfg.gates[-1])
                              if cfg.min_coverage and target is not None else 1.0))
    return _check_overlap(out, n_source, cfg, what)


@dataclass(frozen=True)
class JointAxis:
    """A joint in the world frame: ``T_world_joint`` places the joint frame (the part frame at
    state 0); the part moves about (revolute) or along (prismatic) the unit ``axis`` given in
    the joint frame, within [lower, upper] (radians or metres)."""
    T_world_joint: np.ndarray
    axis: tuple[float, float, float]
    type: str
    lower: float
    upper: float

    def T_world_part(self, value: float) -> np.ndarray:
        a = np.asarray(self.axis, dtype=float)
        a = a / np.linalg.norm(a)
        M = np.eye(4)
        if self.type == "revolute":
            from scipy.spatial.transform import Rotation
            M[:3, :3] = Rotation.from_rotvec(a * value).as_matrix()
        else:
            M[:3, 3] = a * value
        return self.T_world_joint @ M


def joint_jacobian(joint: "JointAxis", p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(N, 1) Jacobian of point-to-plane residuals (points ``p`` on the moving part, their
    normals ``n``, world frame) in the joint coordinate."""
    a = joint.T_world_joint[:3, :3] @ (np.asarray(joint.axis, dtype=float)
                                       / np.linalg.norm(joint.axis))
    if joint.type == "revolute":
        dp = np.cross(a, p - joint.T_world_joint[:3, 3])
    else:
        dp = np.broadcast_to(a, p.shape)
    return np.einsum("ij,ij->i", dp, n)[:, None]


@single_threaded_blas
def register_joint(model_points: np.ndarray, model_normals: np.ndarray, observed: np.ndarray,
                   joint: JointAxis, value_init: float, cfg: ICPConfig = ICPConfig(),
                   tree: Optional[cKDTree] = None, slack: float = 0.0) -> ICPResult:
    """One-coordinate registration: find the joint value at which the part's model points
    (``model_points`` / ``model_normals`` in the part frame, what the camera sees of the part)
    lie on the ``observed`` world points. The model moves, the observation stays (a KD-tree
    on it is built once); point-to-plane on the model's normals.

    ``slack`` (metres, revolute joints only): the joint's axis may also shift across the
    floor, with a Gaussian prior of that sigma on the shift. For a part whose parent could
    not be registered (its base kept where the map has it, centimetres off): a door hung
    from a hinge that is not where the map says turns to a wrong angle to put its face on
    the observed one, while with the hinge free the angle comes from the face's direction,
    which no shift changes (only the base's yaw error remains).

    Returns ``value`` (clamped to the limits) and ``T`` = ``T_world_part`` at that value (and
    the shift, when there is slack). ``inliers`` index model points.
    """
    mp = np.asarray(model_points, dtype=float)
    mn = np.asarray(model_normals, dtype=float)
    obs = np.asarray(observed, dtype=float)
    _require(mp, cfg.min_points, "joint ICP model")
    _require(obs, cfg.min_points, "joint ICP observation")
    tree = tree or cKDTree(obs)
    s = float(np.clip(value_init, joint.lower, joint.upper))
    free = slack > 0 and joint.type == "revolute"
    shift = np.zeros(3)

    def at(value):
        T = joint.T_world_part(value)
        T[:2, 3] += shift[:2]
        return T

    total, done, info = 0, False, np.zeros((1, 1))
    for stage, (gate, iterations, robust) in enumerate(stages(cfg)):
        for _ in range(iterations):
            total += 1
            T = at(s)
            p, n = transform(T, mp), mn @ T[:3, :3].T
            i_m, i_o, _ = associate(tree, p, gate)
            if len(i_m) < 3:
                break
            r = point_to_plane(p[i_m], obs[i_o], n[i_m])
            w = kernel_weights(r, robust, cfg.robust_scale)
            # the turn about the (shifted) axis: the points as they would be unshifted
            J = joint_jacobian(joint, p[i_m] - shift, n[i_m])
            if free:
                J = np.hstack([J, n[i_m][:, :2]])
            H, g = normal_equations(J, r, w)
            info = H[:1, :1] / max(w.sum(), 1e-9)
            if free:
                # the prior on the shift, on the residuals' scale: sum w r^2 + |t|^2 s_r^2 / slack^2
                prior = (cfg.robust_scale or 0.005) ** 2 / slack ** 2 * max(w.sum(), 1.0) / len(r)
                H = H + np.diag([0.0, prior, prior])
                g = g + np.array([0.0, prior * shift[0], prior * shift[1]])
            x = solve(H, g)
            if x is None:
                break
            new = float(np.clip(s + x[0], joint.lower, joint.upper))
            step, s = np.array([new - s]), new
            if free:
                before = shift[:2].copy()
                shift[:2] += x[1:]
                far = np.linalg.norm(shift[:2]) / (3 * slack)
                if far > 1:      # no further than three sigmas
                    shift[:2] /= far
                step = np.array([step[0], *(shift[:2] - before)])
            if converged(step, cfg.tolerance):
                done = stage == len(cfg.gates) - 1
                break
    T = at(s)
    # Residuals and inliers with the observation as the reference: normals of the model.
    p, n = transform(T, mp), mn @ T[:3, :3].T
    i_m, i_o, _ = associate(tree, p, cfg.gates[-1])
    r = point_to_plane(p[i_m], obs[i_o], n[i_m])
    return _finish(T, p, len(mp), i_m, r, None, cfg, total, done, info, "joint ICP", value=s)


def planar_params(T: np.ndarray) -> tuple[float, float, float]:
    """x, y (metres) and yaw (radians) of a planar transform."""
    return float(T[0, 3]), float(T[1, 3]), float(np.arctan2(T[1, 0], T[0, 0]))


def point_agreement(points_camera: np.ndarray, depth: np.ndarray, K, tau: float = 0.02
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per point of ``depth_agreement``: (scores (M, N) of +1, -1 or 0, and whether each
    point falls on a reading in the image)."""
    z = points_camera[..., 2]
    zs = np.where(z > 0.05, z, 1.0)
    H, W = depth.shape
    u = np.rint(K.fx * points_camera[..., 0] / zs + K.cx).astype(np.int64)
    v = np.rint(K.fy * points_camera[..., 1] / zs + K.cy).astype(np.int64)
    inside = (z > 0.05) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
    d = depth[np.clip(v, 0, H - 1), np.clip(u, 0, W - 1)]
    valid = inside & (d > 0)
    agree = valid & (np.abs(d - z) < tau)
    through = valid & (d > z + tau)
    return agree.astype(np.int64) - through.astype(np.int64), valid


def depth_agreement(points_camera: np.ndarray, depth: np.ndarray, K, tau: float = 0.02,
                    mask: Optional[np.ndarray] = None) -> np.ndarray:
    """How well placements of a model agree with an observed depth image (metres, 0: no
    reading): ``points_camera`` (M, N, 3) holds M placements of N model points in the camera
    frame; each scores +1 for a point whose observed depth is within ``tau`` of it and -1 for
    one the camera sees through (the observed depth is behind it by more than ``tau``); a point
    hidden behind something nearer, off the image or without a reading scores 0, as does one
    that ``mask`` (M, N) leaves out (back faces, say). Returns (M,) integer scores."""
    scores, _ = point_agreement(points_camera, depth, K, tau)
    if mask is not None:
        scores = np.where(mask, scores, 0)
    return scores.sum(axis=1)


class DepthAgreement:
    """Scores candidate corrections ``C`` (``T_target_source``: observed world -> model world)
    by ``depth_agreement`` of the model moved by ``C^-1`` into where the observation says it is.
    Vectorised over candidates; the reference should be small (a few thousand points)."""

    def __init__(self, ref_points: np.ndarray, depth: np.ndarray, K, T_world_camera: np.ndarray,
                 tau: float = 0.02, max_points: int = 3000, seed: int = 0):
        if len(ref_points) > max_points:
            idx = np.random.default_rng(seed).choice(len(ref_points), max_points, replace=False)
            ref_points = ref_points[idx]
        self.ref = np.asarray(ref_points, dtype=float)
        self.depth, self.K, self.tau = depth, K, tau
        self.T_camera_world = np.linalg.inv(T_world_camera)

    def __call__(self, Cs) -> np.ndarray:
        return depth_agreement(self.points_camera(Cs), self.depth, self.K, self.tau)

    def points_camera(self, Cs) -> np.ndarray:
        """(M, N, 3) the model points moved by each correction's inverse, camera frame."""
        A = self.T_camera_world[None] @ np.linalg.inv(np.asarray(Cs))      # (M, 4, 4)
        return np.einsum("mij,nj->mni", A[:, :3, :3], self.ref) + A[:, None, :3, 3]

    def against(self, C, Cs) -> tuple[np.ndarray, np.ndarray]:
        """The correction ``C`` against each of ``Cs`` (M, 4, 4), each pair scored on the
        model points that fall on a reading at both: (M,) scores of ``C``, (M,) of ``Cs``.
        The reference is rendered at the believed pose, so a correction that pushes points
        off the image (at the right correction, the stretch of a long front the believed
        camera saw beyond the true one's edge) loses them while a wrong slide along the
        front keeps them; compared on the same points, neither is favoured."""
        scores, valid = point_agreement(self.points_camera(np.concatenate(
            [np.asarray(C)[None], np.asarray(Cs)])), self.depth, self.K, self.tau)
        both = valid[1:] & valid[0]
        return (np.where(both, scores[0], 0).sum(axis=1),
                np.where(both, scores[1:], 0).sum(axis=1))

    def seen_through(self, C) -> tuple[int, int]:
        """(points the camera sees through, points on a reading) of the model at ``C``."""
        scores, valid = point_agreement(self.points_camera(np.asarray(C)[None]), self.depth,
                                         self.K, self.tau)
        return int((scores[0] < 0).sum()), int(valid[0].sum())


# -- views: the rendered reference and the observed cloud -----------------------------------

@dataclass
class View:
    """Points seen in one view, world frame. ``nodes[labels[i]]`` is the map node point ``i``
    belongs to (-1: unknown, for observations); ``pixels`` (N, 2) are (row, col) in the image
    the points came from; ``normals`` are unit, facing the camera (None when unknown)."""
    points: np.ndarray
    normals: Optional[np.ndarray]
    labels: np.ndarray
    nodes: list[str]
    pixels: np.ndarray

    def select(self, node_ids) -> "View":
        idx = [i for i, n in enumerate(self.nodes) if n in set(node_ids)]
        m = np.isin(self.labels, idx)
        return View(self.points[m], None if self.normals is None else self.normals[m],
                    self.labels[m], self.nodes, self.pixels[m])

    def __len__(self) -> int:
        return len(self.points)


def render_reference(meshes, K, T_world_camera: np.ndarray, scale: float = 0.25,
                     max_range: float = 6.0) -> View:
    """What the camera should see of ``meshes`` (labelled, world frame; see
    hearth.worldmodel.geometry): ray cast at ``scale`` times the camera's resolution (a quarter:
    ~1 cm spacing at 1.5 m, plenty as an ICP target and ~16x fewer rays)."""
    from hearth.perception.camera import depth_to_points
    from hearth.perception.render import Scene
    Ks = K.scaled(scale)
    r = Scene(meshes).render(Ks, T_world_camera, max_range=max_range)
    hit = r.depth > 0
    pc = depth_to_points(r.depth, Ks, mask=hit)
    rows, cols = np.nonzero(hit)
    R, t = T_world_camera[:3, :3], T_world_camera[:3, 3]
    return View(points=pc @ R.T + t, normals=r.normals_camera[hit].astype(float) @ R.T,
                labels=r.labels[hit].astype(np.int64), nodes=list(r.nodes),
                pixels=np.stack([rows, cols], axis=1))


def observed_view(depth: np.ndarray, K, T_world_camera: np.ndarray, stride: int = 2,
                  mask: Optional[np.ndarray] = None) -> View:
    """World points of a depth image (metres, 0 = no reading), every ``stride``-th pixel."""
    from hearth.perception.camera import depth_to_points
    pc = depth_to_points(depth, K, mask=mask, stride=stride)
    d = depth[::stride, ::stride]
    ok = np.isfinite(d) & (d > 0)
    if mask is not None:
        ok &= mask[::stride, ::stride]
    rows, cols = np.nonzero(ok)
    R, t = T_world_camera[:3, :3], T_world_camera[:3, 3]
    return View(points=pc @ R.T + t, normals=None, labels=np.full(len(pc), -1, dtype=np.int64),
                nodes=[], pixels=np.stack([rows * stride, cols * stride], axis=1))


def crop_box(points: np.ndarray, lo: np.ndarray, hi: np.ndarray, margin: float,
             floor_z: Optional[float] = 0.0, floor_clearance: float = 0.015) -> np.ndarray:
    """Mask of points inside the box [lo - margin, hi + margin], and above the floor."""
    lo = np.asarray(lo) - margin
    hi = np.asarray(hi) + margin
    m = np.all((points >= lo) & (points <= hi), axis=1)
    if floor_z is not None:
        m &= points[:, 2] > floor_z + floor_clearance
    return m


__all__ = ["DepthAgreement", "ICPConfig", "ICPResult", "JointAxis", "RegistrationFailed",
           "associate", "converged", "crop_box", "depth_agreement", "kernel_weights",
           "normal_equations", "observed_view", "planar_delta", "planar_params", "planar_point_step",
           "planar_plane_jacobian", "planar_point_jacobian", "point_to_plane", "register_6dof",
           "register_joint", "register_planar", "render_reference", "replace", "solve", "stages",
           "to_o3d", "transform", "View", "voxel_downsample"]
