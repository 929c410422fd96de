"""Registration: localisation refinement, large objects, doors, drawers and handles.

A failure is a task that raised, a part left unknown (``*_unknown_rate``, e.g. a drawer
hidden below an open one) or a result outside twice the target (``*_wrong_rate``: door
> 3 deg, drawer > 10 mm, handle > 10 mm or > 2 deg, localisation > 2 cm or > 1 deg, large
object > 10 mm or > 1 deg). ``*_ms_median`` is wall time; ``*_cpu_ms_median`` is this
process's CPU time (all threads), steadier on a machine shared with other jobs;
``load_average_1min`` says how shared it was.

Seeded simulated scenes of the demo home (data/demo_home/world.xml): the truth is rendered
with Kinect-class depth noise from a camera in front of the objects, the belief is the map.
Targets (DESIGN.md): localisation within 1 cm and 0.5 deg from start errors up to 15 cm and
8 deg; large object <= 60 ms; two doors with handles <= 300 ms; door angle <= 1 deg; drawer
<= 5 mm; handle <= 5 mm and <= 1 deg. The RAMCIP reference figures (2016 laptop) are given
as ratios (ours / theirs: below 1 is faster or better).
"""
from __future__ import annotations

import math
import os
import statistics
import time

import numpy as np

from perception.camera import Intrinsics, look_at
from hearth import demo_world_path
from worldmodel.frames import planar_T as planar

DEMO_WORLD = demo_world_path()

#: A camera on the robot's head: 1.35 m up, 10 cm ahead of the base centre, looking down
#: at a point 2 m ahead at 0.4 m height.
T_BASE_CAMERA = look_at((0.1, 0.0, 1.35), (2.0, 0.0, 0.4))

#: RAMCIP D3.1 section 6.3: ~700 ms per large object, ~4.2 s for a cupboard with two doors
#: and handles, handle error ~1 cm and ~1 deg, localisation improved by ~3 cm and ~2 deg.
REFERENCE = dict(large_object_ms=700.0, articulated_two_doors_ms=4200.0, handle_pos_err_mm=10.0,
                 handle_rot_err_deg=1.0)


# -- simulated observations ---------------------------------------------------------------------

def axial_noise(depth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Kinect-class axial noise, sigma = 1.2 mm + 1.9 mm * (z - 0.4 m)^2 (Nguyen et al. 2012)."""
    d = depth.astype(np.float64).copy()
    ok = d > 0
    sigma = 0.0012 + 0.0019 * (d[ok] - 0.4) ** 2
    d[ok] += rng.standard_normal(ok.sum()) * sigma
    return d


def simulate_depth(truth, K: Intrinsics, T_world_camera: np.ndarray, rng: np.random.Generator,
                   states: dict | None = None, scene=None) -> np.ndarray:
    """A noisy depth image (metres) of the truth world: the ray caster, then the simulated
    robot's Kinect noise model (``robot.noise.add_kinect_noise``) when it is there, else
    ``axial_noise``. ``scene``: a prebuilt perception.render.Scene of the truth."""
    from perception.render import Scene
    from worldmodel.geometry import scene_meshes
    scene = scene or Scene(scene_meshes(truth, states=states))
    rendering = scene.render(K, T_world_camera)
    noise = _kinect_noise()
    if noise is not None:
        out = noise(rendering, rng)
        return np.asarray(getattr(out, "depth", out), dtype=np.float64)
    return axial_noise(rendering.depth, rng)


def _kinect_noise():
    try:
        from hearth.robot.noise import add_kinect_noise  # type: ignore
        return add_kinect_noise
    except ImportError:
        return None


def camera_in_front(world, object_id: str, rng: np.random.Generator,
                    distance=(1.3, 1.8), lateral: float = 0.35, height: float = 1.4,
                    look_height: float = 0.5) -> np.ndarray:
    """``T_world_camera`` for a camera in front of an object (which faces its local +x)."""
    To = world.T_world(object_id)
    eye = (To @ np.array([rng.uniform(*distance), rng.uniform(-lateral, lateral), 0, 1]))[:3]
    eye[2] = To[2, 3] + height
    target = (To @ np.array([0.15, 0, 0, 1]))[:3]
    target[2] = To[2, 3] + look_height
    return look_at(eye, target)


def _median(xs):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return round(statistics.median(xs), 4) if xs else None


def _rate(bad, n):
    return round(bad / n, 4) if n else None


# -- the figures ------------------------------------------------------------------------------

def bench_localisation(world, n: int, rng) -> dict:
    from perception.localisation import refine_localisation
    from perception.render import Scene
    from worldmodel.geometry import scene_meshes
    K = Intrinsics.kinect()
    scene = Scene(scene_meshes(world))
    cm, deg, ms, bad, ok = [], [], [], 0, 0
    objects = ["cupboard", "drawer_unit", "fridge", "oven"]
    for i in range(n):
        To = world.T_world(objects[i % len(objects)])
        p = To @ np.array([rng.uniform(1.3, 2.2), rng.uniform(-0.5, 0.5), 0, 1])
        yaw = math.atan2(To[1, 3] - p[1], To[0, 3] - p[0]) + math.radians(rng.uniform(-10, 10))
        T_true = planar(p[0], p[1], yaw)
        depth = simulate_depth(world, K, T_true @ T_BASE_CAMERA, rng, scene=scene)
        r, th = rng.uniform(0, 0.15), rng.uniform(0, 2 * math.pi)
        T_bel = planar(p[0] + r * math.cos(th), p[1] + r * math.sin(th),
                       yaw + math.radians(rng.uniform(-8, 8)))
        t0 = time.perf_counter()
        try:
            fix = refine_localisation(world, depth, K, T_bel @ T_BASE_CAMERA, T_bel)
        except Exception:  # noqa: BLE001 - a failure is a figure here
            bad += 1
            continue
        ms.append(1000 * (time.perf_counter() - t0))
        E = np.linalg.inv(T_true) @ fix.T_world_base
        cm.append(100 * math.hypot(E[0, 3], E[1, 3]))
        deg.append(abs(math.degrees(math.atan2(E[1, 0], E[0, 0]))))
        ok += fix.ok
        if cm[-1] > 2.0 or deg[-1] > 1.0:
            bad += 1
    return dict(loc_residual_cm_median=_median(cm), loc_residual_deg_median=_median(deg),
                loc_residual_cm_p90=round(float(np.percentile(cm, 90)), 4) if cm else None,
                loc_ms_median=_median(ms), loc_failure_rate=_rate(bad, n),
                loc_quality_ok_rate=_rate(ok, n), loc_scenes=n)


def bench_large_object(world, n: int, rng) -> dict:
    """The object stands up to 5 cm / 4 deg from where the map has it (as in the issue's trial)."""
    from perception.articulated import register_base
    K = Intrinsics.kinect()
    objects = ["cupboard", "drawer_unit", "fridge", "oven"]
    ms, cpu, mm, deg, bad = [], [], [], [], 0
    for i in range(n):
        oid = objects[i % len(objects)]
        truth = world.copy()
        obj = truth.get(oid)
        Tm = world.T_world(oid)
        r, th = rng.uniform(0, 0.05), rng.uniform(0, 2 * math.pi)
        D = planar(r * math.cos(th), r * math.sin(th), math.radians(rng.uniform(-4, 4)))
        c = Tm[:3, 3]
        D = planar(*c[:2], 0) @ D @ planar(*(-c[:2]), 0)
        from worldmodel.pose import Pose
        T_true = D @ Tm
        T_parent = truth.T_world(truth.parent(oid).id)
        truth.set_pose(oid, Pose.from_matrix(np.linalg.inv(T_parent) @ T_true))
        Tc = camera_in_front(world, oid, rng)
        depth = simulate_depth(truth, K, Tc, rng)
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            reg = register_base(world, oid, depth, K, Tc, include_parts=True)
        except Exception:  # noqa: BLE001
            bad += 1
            continue
        ms.append(1000 * (time.perf_counter() - t0))
        cpu.append(1000 * (time.process_time() - c0))
        E = np.linalg.inv(T_true) @ reg.T_world_object
        mm.append(1000 * np.linalg.norm(E[:3, 3]))
        deg.append(abs(math.degrees(math.atan2(E[1, 0], E[0, 0]))))
        if mm[-1] > 10 or deg[-1] > 1.0:
            bad += 1
        del obj
    return dict(large_object_ms_median=_median(ms), large_object_cpu_ms_median=_median(cpu),
                large_object_err_mm_median=_median(mm),
                large_object_err_deg_median=_median(deg), large_object_failure_rate=_rate(bad, n),
                large_object_scenes=n)


def _articulated_scene(world, oid, rng, states, max_offset=(0.02, 1.0)):
    """Truth: the object moved a little from where the map has it and its parts at
    ``states``; the map (belief) keeps its parts closed."""
    from worldmodel.pose import Pose
    truth = world.copy()
    Tm = world.T_world(oid)
    r, th = rng.uniform(0, max_offset[0]), rng.uniform(0, 2 * math.pi)
    c = Tm[:3, 3]
    D = (planar(*c[:2], 0) @ planar(r * math.cos(th), r * math.sin(th),
                                    math.radians(rng.uniform(-max_offset[1], max_offset[1])))
         @ planar(*(-c[:2]), 0))
    T_parent = truth.T_world(truth.parent(oid).id)
    truth.set_pose(oid, Pose.from_matrix(np.linalg.inv(T_parent) @ D @ Tm))
    for pid, v in states.items():
        truth.set_joint_state(pid, v)
    return truth


def bench_doors(world, n: int, rng) -> dict:
    from perception.articulated import register_articulated
    K = Intrinsics.kinect()
    objects = ["cupboard", "fridge", "bathroom_cabinet"]
    errs, unknown, bad, total = [], 0, 0, 0
    for i in range(n):
        oid = objects[i % len(objects)]
        parts = world.get(oid).parts
        states = {p.id: math.radians(rng.uniform(0, 90)) for p in parts}
        truth = _articulated_scene(world, oid, rng, states)
        look = 0.5 if oid != "bathroom_cabinet" else 0.3
        Tc = camera_in_front(world, oid, rng, look_height=look)
        depth = simulate_depth(truth, K, Tc, rng)
        try:
            reg = register_articulated(world, oid, depth, K, Tc)
        except Exception:  # noqa: BLE001
            bad += len(parts)
            total += len(parts)
            continue
        for p in parts:
            total += 1
            st = reg.parts[p.id]
            if not st.known:
                unknown += 1
                bad += 1
                continue
            errs.append(abs(st.state - math.degrees(states[p.id])))
            bad += errs[-1] > 3.0
    return dict(door_angle_err_deg_median=_median(errs),
                door_angle_err_deg_p90=round(float(np.percentile(errs, 90)), 4) if errs else None,
                door_unknown_rate=_rate(unknown, total), door_failure_rate=_rate(bad, total),
                door_wrong_rate=_rate(bad - unknown, total),
                door_scenes=n)


def bench_drawers(world, n: int, rng) -> dict:
    from perception.articulated import register_articulated
    K = Intrinsics.kinect()
    parts = world.get("drawer_unit").parts
    errs, bad, total, unknown = [], 0, 0, 0
    for i in range(n):
        states = {p.id: rng.uniform(0, p.joint.upper) for p in parts}
        truth = _articulated_scene(world, "drawer_unit", rng, states)
        Tc = camera_in_front(world, "drawer_unit", rng)
        depth = simulate_depth(truth, K, Tc, rng)
        try:
            reg = register_articulated(world, "drawer_unit", depth, K, Tc)
        except Exception:  # noqa: BLE001
            bad += len(parts)
            total += len(parts)
            continue
        for p in parts:
            total += 1
            st = reg.parts[p.id]
            if not st.known:
                bad += 1
                unknown += 1
                continue
            errs.append(1000 * abs(st.value - states[p.id]))
            bad += errs[-1] > 10
    return dict(drawer_err_mm_median=_median(errs), drawer_failure_rate=_rate(bad, total),
                drawer_unknown_rate=_rate(unknown, total),
                drawer_wrong_rate=_rate(bad - unknown, total), drawer_scenes=n)


def bench_two_doors_and_handles(world, n: int, rng) -> dict:
    """The cupboard: base, both doors (0..90 deg) and both handles, timed together."""
    from perception.articulated import register_articulated, register_handles
    from perception.handles import rotation_error_deg
    K = Intrinsics.kinect()
    parts = world.get("cupboard").parts
    ms, cpu, pos, rot, bad, total, unknown = [], [], [], [], 0, 0, 0
    for i in range(n):
        states = {p.id: math.radians(rng.uniform(0, 90)) for p in parts}
        truth = _articulated_scene(world, "cupboard", rng, states)
        Tc = camera_in_front(world, "cupboard", rng)
        depth = simulate_depth(truth, K, Tc, rng)
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            reg = register_articulated(world, "cupboard", depth, K, Tc)
            hs = register_handles(world, reg, Tc)
        except Exception:  # noqa: BLE001
            bad += 2
            total += 2
            continue
        ms.append(1000 * (time.perf_counter() - t0))
        cpu.append(1000 * (time.process_time() - c0))
        for hid, est in hs.items():
            total += 1
            if isinstance(est, Exception):
                bad += 1
                unknown += "unknown" in str(est)
                continue
            Tt = truth.T_world(hid)
            pos.append(1000 * float(np.linalg.norm(est.T_world_handle[:3, 3] - Tt[:3, 3])))
            rot.append(rotation_error_deg(est.T_world_handle, Tt))
            bad += pos[-1] > 10 or rot[-1] > 2
    return dict(articulated_two_doors_ms_median=_median(ms),
                articulated_two_doors_cpu_ms_median=_median(cpu),
                handle_pos_err_mm_median=_median(pos),
                handle_rot_err_deg_median=_median(rot),
                handle_pos_err_mm_p90=round(float(np.percentile(pos, 90)), 4) if pos else None,
                handle_failure_rate=_rate(bad, total),
                handle_unknown_rate=_rate(unknown, total),
                handle_wrong_rate=_rate(bad - unknown, total), two_door_scenes=n)


def run(args) -> dict:
    from worldmodel import load_world
    n = getattr(args, "scenarios", None) or (8 if getattr(args, "quick", False) else 50)
    seed = getattr(args, "seed", 0)
    world = load_world(DEMO_WORLD)
    out: dict = {}
    t0 = time.perf_counter()
    for k, fn in enumerate((bench_localisation, bench_large_object, bench_doors, bench_drawers,
                            bench_two_doors_and_handles)):
        out.update(fn(world, n, np.random.default_rng(seed * 1000 + k)))
    out["failure_rate"] = {k[:-len("_failure_rate")]: v for k, v in out.items()
                           if k.endswith("_failure_rate")}
    out["vs_ramcip"] = {
        "large_object_time_ratio": _ratio(out["large_object_ms_median"],
                                          REFERENCE["large_object_ms"]),
        "two_doors_time_ratio": _ratio(out["articulated_two_doors_ms_median"],
                                       REFERENCE["articulated_two_doors_ms"]),
        "handle_pos_err_ratio": _ratio(out["handle_pos_err_mm_median"],
                                       REFERENCE["handle_pos_err_mm"]),
        "handle_rot_err_ratio": _ratio(out["handle_rot_err_deg_median"],
                                       REFERENCE["handle_rot_err_deg"]),
        "reference": REFERENCE,
    }
    out["noise_model"] = ("hearth.robot.noise.add_kinect_noise" if _kinect_noise() is not None
                          else "axial gaussian 1.2 mm + 1.9 mm (z - 0.4)^2")
    out["load_average_1min"] = round(os.getloadavg()[0], 2)
    out["scenes_per_figure"] = n
    out["seed"] = seed
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    return out


def _ratio(a, b):
    return round(a / b, 4) if a is not None else None
