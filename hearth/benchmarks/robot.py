"""Simulated robot: time to render one noisy 640x480 RGB-D frame (ray casting + colour +
Kinect noise) of the busiest room of the demo home and of generated homes (``--world``,
``--homes``, ``--no-demo``: ``per_world``, and ``render_640x480_ms_pooled``, the median of
the worlds' medians); on the first world: the frame's parts, scene rebuild, recording and
replay per frame, recording time per capture at the start and at the end of a 2,000-capture recording (Hearth
format and ROS 2 bag), and the noise model's measured depth std against its formula."""
from __future__ import annotations

import os
import tempfile
import time

import numpy as np


def _median_ms(fn, n: int, cpu: list | None = None) -> float:
    """Median wall time (ms) of ``fn``; ``cpu`` receives the median process CPU time (ms,
    all threads), which a busy shared machine inflates much less than wall time."""
    ts, cs = [], []
    for _ in range(n):
        c = time.process_time()
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
        cs.append(time.process_time() - c)
    if cpu is not None:
        cpu.append(round(float(np.median(cs)) * 1000.0, 2))
    return round(float(np.median(ts)) * 1000.0, 2)


def _minor_faults() -> int | None:
    """The process's minor page faults so far (fresh pages from the kernel), where known."""
    try:
        import resource
    except ImportError:                 # not on Windows
        return None
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def _busiest_room(world):
    """The room with the most large objects that have parking positions (the demo's kitchen)."""
    return max(world.rooms, key=lambda r: sum(1 for o in r.objects if getattr(o, "parking", None)))


def _kitchen_views(world):
    """Camera poses at the parking positions of the busiest room's furniture (taken from the
    map), looking at their objects; chairs are left out (their view is the table's)."""
    from hearth.robot.sim import camera_pose, pan_tilt_to
    views = []
    room = _busiest_room(world)
    for oid in [o.id for o in room.objects if getattr(o, "parking", None) and o.type != "chair"]:
        base = world.parking_positions(oid)[0][1]
        target = world.bounds_world(oid).mean(axis=0)
        views.append(camera_pose(base, *pan_tilt_to(base, target)))
    return views


def _door(world) -> tuple[str, str]:
    """(object id, part id) of the first revolute part of an articulated object with parking
    positions in the busiest room (the map's order): the door moved between captures."""
    for o in _busiest_room(world).objects:
        for part in getattr(o, "parts", None) or []:
            if o.parking and part.joint is not None and part.joint.type == "revolute":
                return o.id, part.id
    raise ValueError("the world has no articulated object with a door and a parking position")


def _plane_std(z: float, rng) -> float:
    import open3d as o3d
    from hearth.perception.camera import Intrinsics
    from hearth.perception.render import Scene
    from hearth.robot.noise import add_kinect_noise
    from hearth.worldmodel.geometry import LabelledMesh
    m = o3d.geometry.TriangleMesh.create_box(8.0, 8.0, 0.01)
    m.translate((-4.0, -4.0, z))
    r = Scene([LabelledMesh("wall", "wall", m, (0.8, 0.8, 0.8))]).render(Intrinsics.kinect(),
                                                                        np.eye(4))
    d = add_kinect_noise(r, rng).depth
    return float(np.std(d[d > 0] - z))


def _record_scaling(make_writer, frame, n: int) -> tuple[float, float]:
    """Median ms per capture of the first 100 and of the last 100 captures of an ``n``-capture
    recording. The two are timed in turns (a capture into a new recording, then one into a
    recording already ``n - 100`` long), so that a shared machine's changing load falls on
    both alike and the ratio says how the cost grows with the length."""
    k = min(100, n // 2)
    with tempfile.TemporaryDirectory() as d:
        long = make_writer(os.path.join(d, "long"))
        for _ in range(n - k):
            long.add(frame)
        new = make_writer(os.path.join(d, "new"))
        first, last = [], []
        for _ in range(k):
            for w, ts in ((new, first), (long, last)):
                t = time.perf_counter()
                w.add(frame)
                ts.append(time.perf_counter() - t)
        new.close()
        long.close()
    return (round(float(np.median(first)) * 1000, 3), round(float(np.median(last)) * 1000, 3))


def add_arguments(parser) -> None:
    from hearth.benchmarks import _worlds
    _worlds.add_arguments(parser, homes=2)   # --world W (repeatable), --homes N, --no-demo


def _render_figures(world, K, rng, n: int) -> dict:
    """Median wall and CPU ms of one noisy 640x480 frame of ``world``'s busiest room, from
    the parking positions of its furniture, with the scene prebuilt."""
    from hearth.robot.sim import render_view, world_scene
    views = _kitchen_views(world)
    scene = world_scene(world)
    for T in views:                                   # warm caches (rays per camera)
        render_view(world, K, T, rng, scene=scene)
    i = iter(range(10 ** 9))
    cpu: list = []
    ms = _median_ms(lambda: render_view(world, K, views[next(i) % len(views)], rng, scene=scene),
                    max(n, len(views)), cpu)
    return dict(render_640x480_ms=ms, render_640x480_cpu_ms=cpu[0], views=len(views),
                triangles=int(len(scene._tri_labels)))


def run(args) -> dict:
    from hearth.perception.camera import Intrinsics
    from hearth.robot.adapter import wait
    from hearth.robot.clock import SimClock
    from hearth.robot.noise import KinectNoise, add_kinect_noise
    from hearth.robot.recording import RecordingRobot, ReplayRobot
    from hearth.robot.sim import render_view, world_scene
    from hearth.robot.simulated import SimulatedRobot

    quick = getattr(args, "quick", False)
    n = 5 if quick else 15
    rng = np.random.default_rng(getattr(args, "seed", 0) or 0)
    from hearth.benchmarks import _worlds
    specs = _worlds.world_specs(args, homes=2)
    if not specs:
        raise _worlds.NoScenes("robot: no world to run on (--no-demo needs --world or --homes)")
    world = _worlds.load(specs[0])
    K = Intrinsics.kinect()
    views = _kitchen_views(world)
    scene = world_scene(world)
    for T in views:                                   # warm caches (rays per camera)
        render_view(world, K, T, rng, scene=scene)
    i = iter(range(10 ** 9))

    def one():
        render_view(world, K, views[next(i) % len(views)], rng, scene=scene)

    out: dict = {}
    cpu: list = []
    frames = n * len(views) // 3
    faults = _minor_faults()
    out["render_640x480_ms"] = _median_ms(one, frames, cpu)
    out["render_640x480_cpu_ms"] = cpu[0]
    if faults is not None:
        out["render_640x480_page_faults"] = round((_minor_faults() - faults) / frames)
    out["load_average_1min"] = round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None
    clean = [scene.render(K, T) for T in views]
    out["raycast_and_shade_ms"] = _median_ms(lambda: scene.render(K, views[next(i) % len(views)]),
                                             n * 2)
    out["noise_ms"] = _median_ms(lambda: add_kinect_noise(clean[next(i) % len(clean)], rng), n * 2)
    out["scene_build_ms"] = _median_ms(lambda: world_scene(world), n)
    out["render_320x240_ms"] = _median_ms(
        lambda: render_view(world, K.scaled(0.5), views[next(i) % len(views)], rng, scene=scene),
        n * 2)
    model = KinectNoise()
    for z in (1.0, 2.0, 3.0):
        out[f"depth_std_{z:.0f}m_mm"] = round(_plane_std(z, rng) * 1000, 3)
        out[f"depth_std_{z:.0f}m_model_mm"] = round(float(model.axial_std(z)) * 1000, 3)
    # A simulated robot: capture (with the scene cached), and with a door moving (rebuild).
    clock = SimClock()
    app, door = _door(world)
    start = world.parking_positions(app)[0][1]
    sim = SimulatedRobot(world.copy(), clock, start_pose=start, seed=1)
    sim.look_at(world.T_world(app)[:3, 3] + [0, 0, 0.5])
    sim.capture()
    out["sim_capture_ms"] = _median_ms(sim.capture, n)

    def moved_capture():
        sim.truth.set_joint_state(door, float(rng.uniform(0, 1.0)))
        sim.capture()
    out["sim_capture_after_truth_change_ms"] = _median_ms(moved_capture, n)
    # Record and replay.
    with tempfile.TemporaryDirectory() as d:
        rec = RecordingRobot(SimulatedRobot(world.copy(), clock, seed=2,
                                            start_pose=start),
                             d)
        frame = rec.inner.capture()
        out["record_frame_ms"] = _median_ms(lambda: rec.writer.add(frame), n)
        rp = ReplayRobot(d, clock=clock)
        wait(rp.navigate_to(start), clock)
        out["replay_capture_ms"] = _median_ms(rp.capture, n)
    # Linear in the length: a 2,000-capture recording (160x120 frames, so that what grows with
    # the length is not hidden behind the PNG encoding) at its start and at its end.
    from hearth.robot.recording import RecordingWriter
    n_rec = 400 if quick else 2000
    small = render_view(world, K.scaled(0.25), views[0], rng, scene=scene)
    first, last = _record_scaling(lambda d: RecordingWriter(d, small.intrinsics), small, n_rec)
    out["record_captures"] = n_rec
    out["record_ms_per_capture_first_100"], out["record_ms_per_capture_last_100"] = first, last
    out["record_last_to_first_ratio"] = round(last / first, 3)
    try:
        from hearth.robot.rosbag import BagWriter, require_ros
        require_ros()
    except Exception:  # noqa: BLE001 - the ros extra is optional
        out["record_mcap_note"] = "ros extra not installed"
    else:
        first, last = _record_scaling(lambda d: BagWriter(d, small.intrinsics), small, n_rec)
        out["record_mcap_ms_per_capture_first_100"] = first
        out["record_mcap_ms_per_capture_last_100"] = last
        out["record_mcap_last_to_first_ratio"] = round(last / first, 3)
    out["views"] = len(views)
    # Every world asked for (the demo and generated homes by default): its busiest room.
    # The frame figures above are the first world's; render_640x480_ms_pooled is the median
    # of the worlds' medians.
    from hearth.benchmarks import _worlds
    out["worlds"] = specs
    out["per_world"] = {specs[0]: dict(render_640x480_ms=out["render_640x480_ms"],
                                       render_640x480_cpu_ms=out["render_640x480_cpu_ms"],
                                       views=len(views), triangles=int(len(scene._tri_labels)))}
    for spec in specs[1:]:
        out["per_world"][spec] = _render_figures(_worlds.load(spec), K, rng, frames)
    out["render_640x480_ms_pooled"] = round(float(np.median(
        [w["render_640x480_ms"] for w in out["per_world"].values()])), 2)
    out["target_render_640x480_ms"] = 25.0
    out["target_record_last_to_first_ratio"] = 1.2
    out["note"] = ("medians on this machine; render = ray casting + shading + Kinect noise "
                   "with the scene prebuilt; cpu_ms = process CPU time of all threads; "
                   "page_faults = fresh pages taken from the kernel per frame (mean)")
    return out
