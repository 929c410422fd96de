"""Running one fuzz case in-process and checking what its loader accepted independently of the
loader (``run_case``; ``check_world``, ``check_mission``, ``check_recording``,
``check_bag``): the worker of hearth/benchmarks/fuzz.py runs these, and so do the tests."""
from __future__ import annotations

import math
import os
import signal
import stat
import tempfile
import time
from pathlib import Path
from typing import Any, Optional

from hearth.benchmarks.fuzz_case import Case, materialise, MAX_LINE, Verdict, WORLD_MAX_COORD
from hearth.benchmarks.fuzz_generate import WORST_UTTERANCE


# ---------------------------------------------------------------------------------------------
# Checks, in-process (the worker runs these; so do the tests)

class _Hang(BaseException):
    """Raised by the alarm; a BaseException so that no loader's ``except Exception`` eats it."""


def run_case(case: Case, timeout: float = 30.0) -> Verdict:
    """Materialise ``case`` in a temporary folder and check it, with an alarm for hangs."""
    check = {"world": check_world, "mission": check_mission, "recording": check_recording,
             "bag": check_bag}[case.loader]
    with tempfile.TemporaryDirectory(prefix="hearth-fuzz-") as d:
        root = Path(d)
        entry = materialise(case, root)

        def on_alarm(signum, frame):
            raise _Hang()
        old = signal.signal(signal.SIGALRM, on_alarm)
        signal.setitimer(signal.ITIMER_REAL, timeout)
        t0 = time.perf_counter()
        try:
            verdict = check(root, entry)
        except _Hang:
            verdict = Verdict("hang", f"over {timeout:g} s")
        except MemoryError:
            verdict = Verdict("traceback", "MemoryError")
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
        verdict.ms = (time.perf_counter() - t0) * 1000
        return verdict


def _describe(err: BaseException) -> str:
    import traceback
    tb = traceback.extract_tb(err.__traceback__)
    where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
    return f"{type(err).__name__}: {str(err)[:200]}{where}"


def _inside(root: Path, rel: str, base: Optional[Path] = None) -> bool:
    """Whether ``rel`` (relative to ``base``, default ``root``) stays inside ``root`` once
    symbolic links are followed and, if it exists, is a regular file (not a device, a FIFO,
    a directory). A missing file is not "outside": the checks that read it catch it."""
    real_root = os.path.realpath(root)
    full = os.path.realpath(os.path.join(base or root, rel))
    if os.path.commonpath([real_root, full]) != real_root:
        return False
    try:
        return stat.S_ISREG(os.stat(full).st_mode)
    except FileNotFoundError:
        return True
    except OSError:
        return False


def _one_line_each(message: str) -> Optional[str]:
    """Why a refusal's message is not one located line per problem (None: it is)."""
    lines = message.splitlines()
    if not lines:
        return "empty message"
    for line in lines:
        if "Traceback" in line or not line.strip():
            return f"not one line per problem: {message[:200]!r}"
        if len(line) > MAX_LINE:
            return f"a line of {len(line)} characters: {line[:160]!r}"
    return None


# -- worlds ------------------------------------------------------------------------------------

def _world_numbers(apartment) -> list[tuple[str, float]]:
    """(where, value) for every float in the map, found by walking its dataclasses (not the
    loader's own list of fields)."""
    import dataclasses
    out: list[tuple[str, float]] = []
    stack: list[tuple[str, Any]] = [("apartment", apartment)]
    while stack:
        where, obj = stack.pop()
        if isinstance(obj, bool) or obj is None or isinstance(obj, str):
            continue
        if isinstance(obj, (int, float)):
            out.append((where, obj))
        elif isinstance(obj, dict):
            stack.extend((f"{where}.{k}", v) for k, v in obj.items())
        elif isinstance(obj, (list, tuple)):
            stack.extend((f"{where}[{i}]", v) for i, v in enumerate(obj))
        elif dataclasses.is_dataclass(obj):
            name = getattr(obj, "id", None) or type(obj).__name__
            stack.extend((f"{name}.{f.name}", getattr(obj, f.name))
                         for f in dataclasses.fields(obj) if f.name != "line")
    return out


def _world_out_of_bounds(apartment) -> Optional[str]:
    for where, v in _world_numbers(apartment):
        if ".time" in where or ".searched" in where or ".found" in where:
            if not math.isfinite(v):
                return f"{where} = {v!r}"
        elif not math.isfinite(v) or abs(v) > WORLD_MAX_COORD:
            return f"{where} = {v!r}"
    return None


def _world_files(apartment) -> list[str]:
    out = []
    models = [m for m in apartment.library.values()]
    for room in apartment.rooms:
        if room.pointcloud is not None:
            out.append(room.pointcloud)
    from hearth.worldmodel.validate import iter_nodes
    for node, _ in iter_nodes(apartment):
        if hasattr(node, "model"):
            models.append(node.model)
    for m in models:
        out.extend(v.file or "" for v in m.visuals if v.shape == "mesh")
    return out


def _mesh_references(base: Path, rel: str) -> list[str]:
    """The files an accepted ``.obj`` names (``mtllib``) and the textures those name, relative
    to ``base``: read here independently of the loader, so that a file a mesh would make the
    renderer open counts in ``paths_outside_world`` too."""
    out: list[str] = []
    todo = [rel] if rel.lower().endswith(".obj") else []
    while todo:
        cur = todo.pop()
        full = os.path.join(base, cur)
        if not _inside(base, cur) or not os.path.isfile(full) or os.path.getsize(full) > 1 << 20:
            continue
        for raw in Path(full).read_bytes().splitlines():
            words = raw.decode("utf-8", "replace").split()
            if not words:
                continue
            key = words[0].lower()
            if key == "mtllib":
                refs = words[1:]
            elif cur.lower().endswith(".mtl") and (key.startswith("map_") or key in
                                                   ("bump", "disp", "decal", "refl", "norm")):
                refs = words[-1:]
            else:
                continue
            for ref in refs:
                r = os.path.normpath(os.path.join(os.path.dirname(cur), ref))
                out.append(r)
                if r.lower().endswith(".mtl"):
                    todo.append(r)
    return out


def check_world(root: Path, entry: Path) -> Verdict:
    from hearth.worldmodel.errors import WorldError
    from hearth.worldmodel.io import load_world, save_world

    try:
        world = load_world(entry)
    except WorldError as err:
        why = _one_line_each(str(err))
        return Verdict("traceback", why) if why else Verdict("refused", str(err).splitlines()[0])
    except Exception as err:  # noqa: BLE001 - the point of the check
        return Verdict("traceback", _describe(err))
    files = _world_files(world.apartment)
    files += [r for f in files for r in _mesh_references(entry.parent, f)]
    outside = sum(not _inside(root, f, entry.parent) for f in files)
    bad = _world_out_of_bounds(world.apartment)
    if bad:
        return Verdict("out_of_bounds", bad, outside)
    missing = [f for f in files if not os.path.exists(os.path.join(entry.parent, f))]
    if missing:     # open3d reads a missing mesh as an empty one, with a warning
        return Verdict("unloadable", f"accepted with a missing file {missing[0]!r}", outside)
    try:
        copy_path = entry.with_name("saved.xml")
        save_world(world, copy_path)
        again = load_world(copy_path)
        if again != world:
            return Verdict("unloadable", "load(save(w)) differs from w", outside)
        _update(world)
        save_world(world, copy_path)
        again = load_world(copy_path)
        if again != world:
            return Verdict("unloadable", "load(save(w)) differs from w after updates", outside)
        _use(again)
    except WorldError as err:
        return Verdict("unloadable", str(err).splitlines()[0], outside)
    except Exception as err:  # noqa: BLE001
        return Verdict("unloadable", _describe(err), outside)
    return Verdict("accepted", "", outside)


def _update(world) -> None:
    """What a mission does to a map: move a joint, turn a knob, move a small object."""
    from hearth.worldmodel.pose import Pose
    parts = [p for p in world.nodes("Part") if p.joint.type != "fixed"]
    if parts:
        j = parts[0].joint
        world.set_joint_state(parts[0].id, (j.lower + j.upper) / 2, source="fuzz")
    knobs = world.knobs()
    if knobs:
        k = knobs[0]
        world.set_knob_state(k.id, k.states[-1].name, source="fuzz")
    smalls, larges = world.small_objects(), world.large_objects()
    if smalls and larges:
        world.move_object(smalls[0].id, larges[-1].id, Pose(0.01, 0.02, 0.5), source="fuzz")


def _use(world) -> None:
    """What the simulator and the skills do with a map: meshes, world poses, parking poses."""
    import numpy as np
    from hearth.worldmodel.geometry import scene_meshes
    for m in scene_meshes(world):
        v = np.asarray(m.mesh.vertices)
        if v.size and not np.isfinite(v).all():
            raise ValueError(f"non-finite mesh vertices for {m.node}")
    for nid in world.ids():
        if not np.isfinite(world.T_world(nid)).all():
            raise ValueError(f"non-finite world pose for {nid}")
    for o in world.large_objects():
        world.parking_positions(o.id)


# -- missions ----------------------------------------------------------------------------------

_REGISTRY: Optional[dict] = None


def _registry() -> dict:
    global _REGISTRY
    if _REGISTRY is None:
        from hearth.executive.missionfile import skill_registry
        _REGISTRY = skill_registry()
    return _REGISTRY


_SAMPLE = {"string": "x", "node_id": "no_such_table", "number": 1.0, "integer": 1,
           "boolean": True, "pose": {"x": 0.0, "y": 0.0}, "list": [], "dict": {}, "any": "x"}


def _finite_everywhere(value, depth: int = 0) -> bool:
    if depth > 400:
        return False
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_finite_everywhere(v, depth + 1) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(_finite_everywhere(v, depth + 1) for v in value)
    return True


def _mission_out_of_bounds(mission) -> Optional[str]:
    from hearth.executive.missionfile import Lit
    for n in mission.nodes():
        a = n.attrs
        if n.kind == "retry" and not 1 <= a["times"] <= 1000:
            return f"{n.path}: retry times {a['times']}"
        if n.kind == "repeat" and not (a["times"] == -1 or 1 <= a["times"] <= 1_000_000):
            return f"{n.path}: repeat times {a['times']}"
        if n.kind == "timeout" and not (math.isfinite(a["seconds"]) and 0 < a["seconds"] <= 86400):
            return f"{n.path}: timeout seconds {a['seconds']}"
        for port, ref in n.inputs.items():
            if isinstance(ref, Lit) and not _finite_everywhere(ref.value):
                return f"{n.path}: input {port} = {ref.value!r}"
    if not _finite_everywhere(mission.blackboard):
        return "blackboard holds a non-finite number"
    for p in mission.parameters.values():
        if not _finite_everywhere(p.default):
            return f"parameter {p.name} default {p.default!r}"
    return None


def check_mission(root: Path, entry: Path) -> Verdict:
    from hearth.executive.errors import MissionError
    from hearth.executive.missionfile import load_mission, validate_file
    from hearth.executive.tree import build_tree

    skills = _registry()
    try:
        mission = load_mission(entry, skills)
    except MissionError as err:
        why = _one_line_each(str(err))
        if why:
            return Verdict("traceback", why)
        try:   # `hearth validate` must agree that it is bad (a library of subtrees aside)
            library = str(err).startswith(f"{entry}:") and "has subtrees but no tree" in str(err)
            if not validate_file(entry, skills) and not library:
                return Verdict("unloadable", "load_mission refuses what validate_file accepts")
        except Exception as err2:  # noqa: BLE001
            return Verdict("traceback", "validate_file: " + _describe(err2))
        return Verdict("refused", str(err).splitlines()[0])
    except Exception as err:  # noqa: BLE001
        return Verdict("traceback", _describe(err))
    outside = sum(not _inside(root, f, Path.cwd()) for f in mission.files)
    bad = _mission_out_of_bounds(mission)
    if bad:
        return Verdict("out_of_bounds", bad, outside)
    built = None
    try:
        given = {n: (p.enum[0] if p.enum else _SAMPLE.get(p.type.split("|")[0], "x"))
                 for n, p in mission.parameters.items() if p.default is None and p.required}
        try:
            params = mission.resolve_parameters(given)
        except MissionError:
            params = None   # a sample value the mission refuses (an enum of lists...): skip
        if params is not None:
            built = build_tree(mission, params, f"/fuzz/{os.getpid()}")
        from hearth.executive.render import ascii_tree
        ascii_tree(mission.root)
    except Exception as err:  # noqa: BLE001
        return Verdict("unloadable", _describe(err), outside)
    finally:
        if built is not None:
            built.teardown()
            built = None
    try:     # what `hearth serve` does with the file's utterances: compile, then match
        from hearth.executive.command.vocabulary import normalise, read_templates
        templates = read_templates(mission, str(entry))
    except MissionError as err:
        why = _one_line_each(str(err))
        return Verdict("traceback", why) if why else Verdict("refused", str(err).splitlines()[0])
    except Exception as err:  # noqa: BLE001
        return Verdict("traceback", "utterances: " + _describe(err), outside)
    try:
        for t in templates:
            for said in (t.example(), WORST_UTTERANCE, " ".join([t.example()] * 8)):
                t.match(normalise(said)[:500])
    except Exception as err:  # noqa: BLE001
        return Verdict("unloadable", "matching an utterance: " + _describe(err), outside)
    return Verdict("accepted", "", outside)


# -- recordings --------------------------------------------------------------------------------

def check_recording(root: Path, entry: Path) -> Verdict:
    """Open a recording as ``hearth run --recording`` does (``Recording(dir)``), then read every
    frame, as a replayed mission would, one by one, long after it started."""
    import numpy as np
    from hearth.robot.errors import RobotError
    from hearth.robot.recording import Recording

    try:
        rec = Recording(entry)
    except RobotError as err:
        why = _one_line_each(str(err))
        return Verdict("traceback", why) if why else Verdict("refused", str(err).splitlines()[0])
    except Exception as err:  # noqa: BLE001
        return Verdict("traceback", _describe(err))
    outside = sum(not _inside(root, p, entry) for c in rec.captures for p in (c.color, c.depth))
    nums = [rec.depth_scale]
    if rec.intrinsics is not None:
        K = rec.intrinsics
        nums += [K.fx, K.fy, K.cx, K.cy]
        if not (K.fx > 0 and K.fy > 0 and K.width > 0 and K.height > 0):
            return Verdict("out_of_bounds", f"intrinsics {K}", outside)
    if not rec.depth_scale > 0:
        return Verdict("out_of_bounds", f"depth_scale {rec.depth_scale}", outside)
    for c in rec.captures:
        nums += [c.timestamp, c.pan, c.tilt]
        nums += list(np.asarray(c.T_world_camera, dtype=float).ravel())
        if c.base_pose is not None:
            nums += list(c.base_pose.as_tuple())
    if not all(math.isfinite(x) for x in nums):
        return Verdict("out_of_bounds", "a non-finite number", outside)
    try:    # every distinct frame (20,000 captures of one frame: that frame once)
        seen: set[tuple[str, str]] = set()
        for i, c in enumerate(rec.captures):
            if (c.color, c.depth) not in seen:
                seen.add((c.color, c.depth))
                rec.frame(i)
    except RobotError as err:
        return Verdict("unloadable", "mid-mission: " + str(err).splitlines()[0], outside)
    except Exception as err:  # noqa: BLE001
        return Verdict("traceback", "mid-mission: " + _describe(err), outside)
    return Verdict("accepted", "", outside)


# -- bags --------------------------------------------------------------------------------------

def check_bag(root: Path, entry: Path) -> Verdict:
    """Open a ROS 2 bag as ``hearth run --recording BAG`` does (with its side file)."""
    from hearth.robot.errors import RobotError
    from hearth.robot.recording import open_recording
    try:
        rec = open_recording(entry)
    except RobotError as err:
        why = _one_line_each(str(err))
        return Verdict("traceback", why) if why else Verdict("refused", str(err).splitlines()[0])
    except Exception as err:  # noqa: BLE001
        return Verdict("traceback", _describe(err))
    try:
        for i in range(len(rec)):
            rec.frame(i)
    except RobotError as err:
        return Verdict("unloadable", "mid-mission: " + str(err).splitlines()[0])
    except Exception as err:  # noqa: BLE001
        return Verdict("traceback", "mid-mission: " + _describe(err))
    return Verdict("accepted")


def _has_ros() -> bool:
    import importlib.util
    return importlib.util.find_spec("rosbags") is not None
