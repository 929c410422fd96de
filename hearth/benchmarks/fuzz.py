"""Hostile and careless files: fuzzing the world, mission and recording loaders.

Each case is a small folder written to a temporary directory: the shipped demo world
(``data/demo_home/world.xml``) or the shipped missions (``missions/*.yaml`` with
``missions/subtrees/``) mutated by a seeded generator (attribute and value replacements with
NaN, infinities, 1e308, zero sizes, escaping paths; deleted, duplicated, moved and renamed
elements and keys; nodes wrapped in retries and timeouts; YAML anchors, aliases and tags;
truncations and flipped bytes), or a small recording written per docs/recording-format.md
with its manifest and frames mutated. Next to the file each world case has planted
neighbours: a regular mesh, a directory, a FIFO and a symbolic link to /etc/passwd.

A case is run in a worker process (killed and restarted when it overstays ``--timeout``) and
ends as one of:

- ``refused``: the loader's own error (WorldError, MissionError, RobotError);
- ``accepted``, then checked independently of the loader: a world is saved, loaded again
  (and again after a joint, a knob and an object are updated), compared with the original,
  turned into meshes and every node's world pose computed; a mission's tree is built with
  its parameters and every number in it is checked; a recording's every frame is read.
  A failure there is ``accepted_then_unloadable``; a number the format does not allow
  (non-finite, beyond its bound) is ``accepted_out_of_bounds``; a mesh, point cloud,
  include or frame outside the case's folder (or not a regular file) counts in
  ``paths_outside_world``;
- ``traceback`` (any other exception), ``hang`` (over the time limit), ``crash`` (the worker
  died, e.g. in open3d).

The hand-made cases of issues 19 and 44 run as fixed cases with an expected outcome
(``fixed``); issue 44's carry a class (``CLASSES``: mesh-content, fifo, nul, huge-integer,
template, size, ...) and are counted by class (``fixed_by_class``). A fourth loader, ``bag``,
runs hand-made ROS 2 bag cases (when the ``ros`` extra is installed). Accepted missions also
have their utterance templates compiled and matched against the worst known utterance.

The ``http`` block sends hostile requests to a real server over the demo home (issue 44):
hand-made ones by class (cross-site POST/PUT with foreign ``Origin`` or ``Sec-Fetch-Site``,
malformed ``Host``, bodies with Infinity, NaN, 1e400, 5,000-digit integers, lone surrogates,
a key twice, the worst template's utterance) with the answer each must get, and
``--http-requests`` schema-generated ones (hearth/executive/command/fuzz.py) with hostile bodies and
foreign origins mixed in; it counts ``5xx`` and ``cross_site_accepted`` and reports how long
``/api/health`` took while the worst template was matched.

Targets: ``tracebacks``, ``hangs``, ``crashes``, ``accepted_then_unloadable``,
``accepted_out_of_bounds``, ``paths_outside_world``, ``5xx``, ``cross_site_accepted`` all 0,
per loader and in total.

``tests/fuzz/test_fuzz_loaders.py`` runs the same generators in-process on a few hundred cases.
"""
from __future__ import annotations

import copy
import itertools
import json
import math
import multiprocessing
import re
import os
import random
import signal
import stat
import statistics
import tempfile
import time
from dataclasses import dataclass
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any, Iterable, Iterator, Optional

LOADERS = ("world", "mission", "recording", "bag")
#: Classes of hostile input the fixed cases are sorted into (issue 44 added the last six).
CLASSES = ("numbers", "paths", "size", "structure", "mesh-content", "fifo", "nul",
           "huge-integer", "cross-site", "template", "host")
FAILURES = ("tracebacks", "hangs", "crashes", "accepted_then_unloadable",
            "accepted_out_of_bounds", "paths_outside_world")
_OUTCOME_KEY = {"traceback": "tracebacks", "hang": "hangs", "crash": "crashes",
                "unloadable": "accepted_then_unloadable", "out_of_bounds": "accepted_out_of_bounds"}

#: The world format's bound on coordinates, lengths and angles (hearth.worldmodel.validate.MAX_COORD),
#: restated here so the check is independent of the loader.
WORLD_MAX_COORD = 1e4
#: A refusal is a line a person reads: longer than this, it counts as a traceback.
MAX_LINE = 500


def add_arguments(parser) -> None:
    parser.add_argument("--cases", type=int, default=None,
                        help="mutated cases per world and mission loader (default 2000; "
                             "--quick 200); recordings get a quarter")
    parser.add_argument("--timeout", type=float, default=60.0,
                        help="seconds a case may take before it counts as a hang")
    parser.add_argument("--http-requests", type=int, default=None,
                        help="schema-generated requests to the HTTP API (default 500; --quick "
                             "100), besides the hand-made hostile ones")


# ---------------------------------------------------------------------------------------------
# Cases

@dataclass
class Case:
    """A folder of files and what to load from it.

    ``files`` maps a relative path to bytes, or to ``("symlink", target)``, ``("dir",)``,
    ``("fifo",)`` or ``("sparse", size)`` (a file of ``size`` bytes that takes no disk). ``entry`` is the file (or, for a recording, the folder) the loader opens.
    ``expect`` is set for fixed cases: "refused" or "accepted".
    """
    loader: str
    name: str
    files: dict[str, Any]
    entry: str
    expect: Optional[str] = None
    klass: str = ""          # fixed cases: the class of hostile input (CLASSES)


@dataclass
class Verdict:
    outcome: str            # accepted refused traceback hang crash unloadable out_of_bounds
    detail: str = ""
    outside: int = 0        # paths outside the case folder an accepted file makes us read
    ms: float = 0.0


def materialise(case: Case, root: Path) -> Path:
    """Write the case's files under ``root``; return the entry's path."""
    for rel, content in case.files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, (bytes, bytearray)):
            p.write_bytes(content)
        elif content[0] == "symlink":
            os.symlink(content[1], p)
        elif content[0] == "dir":
            p.mkdir(exist_ok=True)
        elif content[0] == "fifo":
            os.mkfifo(p)
        elif content[0] == "sparse":
            with open(p, "wb") as f:
                f.truncate(content[1])
    return root / case.entry


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


# ---------------------------------------------------------------------------------------------
# Base files

def _demo_world() -> bytes:
    from hearth import demo_world_path
    return demo_world_path().read_bytes()


def _missions() -> dict[str, bytes]:
    from hearth import missions_dir
    base = missions_dir()
    return {str(p.relative_to(base)): p.read_bytes() for p in sorted(base.rglob("*.yaml"))}


_PLY = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        b"0 0 0\n0.1 0 0\n0 0.1 0\n3 0 1 2\n")

def _tiny_png() -> bytes:
    import zlib
    import struct

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00\xff\x00\x00")) + chunk(b"IEND", b""))


_OBJ = b"v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n"

#: What sits next to a fuzzed world file: meshes a hostile path may name, and meshes whose
#: contents are hostile (issue 44: material libraries and textures out of the folder or FIFOs,
#: counts that allocate gigabytes, non-finite vertices, formats naming external files).
WORLD_NEIGHBOURS: dict[str, Any] = {
    "ok.ply": _PLY, "sub/inner.ply": _PLY, "emptydir": ("dir",), "fifo.ply": ("fifo",),
    "escape.ply": ("symlink", "/etc/passwd"), "etc": ("symlink", "/etc"),
    "ok.obj": b"mtllib ok.mtl\n" + _OBJ, "ok.mtl": b"newmtl a\nKd 1 0 0\nmap_Kd tex.png\n", "tex.png": _tiny_png(),
    "passwd.obj": b"mtllib ../../../../../../etc/passwd\n" + _OBJ,
    "pipe.mtl": ("fifo",), "fifo_mtl.obj": b"mtllib pipe.mtl\n" + _OBJ,
    "tex.mtl": b"newmtl a\nmap_Kd -s 1 1 1 ../../../../etc/shadow\n",
    "texture.obj": b"mtllib tex.mtl\n" + _OBJ,
    "nan.obj": b"v nan 0 0\n" + _OBJ,
    "huge.ply": _PLY.replace(b"element vertex 3", b"element vertex 2000000000"),
    "nan.ply": _PLY.replace(b"0 0 0\n0.1 0 0", b"nan 0 0\ninf 0 0"),
    "truncated.ply": _PLY[:-12],
    "m.gltf": b'{"buffers": [{"uri": "/etc/passwd"}]}',
}
#: The neighbours whose contents are hostile (mesh-content class).
HOSTILE_MESHES = ["passwd.obj", "fifo_mtl.obj", "texture.obj", "nan.obj", "huge.ply",
                  "nan.ply", "truncated.ply", "m.gltf"]
#: The utterance that froze the server against a template of 60 optional groups (issue 44).
WORST_UTTERANCE = "x " * 21 + "y"


def _recording_files(n: int = 2, width: int = 32, height: int = 24,
                     version: int = 1) -> dict[str, Any]:
    """A small valid recording, written per docs/recording-format.md (not through Hearth's
    writer, so the reader is tested against the documented format): ``version`` 1 (all in
    manifest.json) or 2 (captures.jsonl and actions.jsonl beside it)."""
    import cv2
    import numpy as np
    files: dict[str, Any] = {}
    caps = []
    for i in range(n):
        color = np.full((height, width, 3), 40 * (i + 1), np.uint8)
        depth = np.full((height, width), 1500 + 10 * i, np.uint16)
        ok1, c = cv2.imencode(".png", color)
        ok2, d = cv2.imencode(".png", depth)
        files[f"rec/frames/{i:06d}_color.png"] = c.tobytes()
        files[f"rec/frames/{i:06d}_depth.png"] = d.tobytes()
        T = [[0, 0, 1, 1.0 + i], [-1, 0, 0, 2.0], [0, -1, 0, 1.2], [0, 0, 0, 1]]
        caps.append({"index": i, "timestamp": 1.5 * i, "color": f"frames/{i:06d}_color.png",
                     "depth": f"frames/{i:06d}_depth.png",
                     "base_pose": {"x": 1.0 + i, "y": 2.0, "yaw": 0.0}, "T_world_camera": T,
                     "pan": 0.0, "tilt": 0.3, "parking": None, "goal": None, "truth": None})
    manifest = {"format": "hearth-recording", "version": 1, "depth_scale": 0.001,
                "intrinsics": {"fx": 30.0, "fy": 30.0, "cx": (width - 1) / 2,
                               "cy": (height - 1) / 2, "width": width, "height": height},
                "info": {"mission": "fuzz"}, "start_pose": {"x": 1.0, "y": 2.0, "yaw": 0.0},
                "captures": caps, "actions": []}
    if version == 2:
        manifest.update(version=2, captures="captures.jsonl", actions="actions.jsonl")
        files["rec/captures.jsonl"] = "".join(json.dumps(c) + "\n" for c in caps).encode()
        files["rec/actions.jsonl"] = (b'{"i": 0, "time": 1.0, "action": "say", "args": {}}\n'
                                      b'{"i": 0, "status": "succeeded", "reason": ""}\n')
    files["rec/manifest.json"] = json.dumps(manifest, indent=1).encode()
    return files


# ---------------------------------------------------------------------------------------------
# Mutators

HOSTILE_NUMBERS = ["NaN", "INF", "-INF", "1e308", "-1e308", "1e999", "1e-400", "0", "-0", "-1",
                   "10000", "10000.000001", "-10000.5", "5e-324", "", " ", "abc", "1,5", "0x10",
                   "1_0", "9" * 400, "+.5", "1 2", "1 2 3 4", "NaN NaN NaN", "0 0 0",
                   "1e308 0 0", "-1 -1 -1", "1e5", "3.4e38", "2", "0.5 0.5 0.5", "INF 0 0"]
HOSTILE_PATHS = ["../../etc/passwd", "/etc/passwd", "/dev/zero", "/proc/self/environ",
                 "../../../../proc/self/maps", "emptydir", "escape.ply", "fifo.ply", "ok.ply",
                 "missing.ply", "./ok.ply", "sub/../ok.ply", "sub/../../x.ply", "~/x.ply",
                 "C:\\x.ply", "etc/passwd", "sub/inner.ply", "//etc/passwd", ".", "",
                 "ok.obj", *HOSTILE_MESHES]
HOSTILE_TEXT = ["", " ", "x" * 5000, "\u202e", "\u00e9t\u00e9", "a b", "<", "&", "1abc", "_",
                "a" * 4097, "kitchen", "no_such_cup", "no_such_knob_1", "\U0001F600", "true", "off"]
_ATTRS = ["x", "y", "z", "roll", "pitch", "yaw", "radius", "length", "size", "scale", "color",
          "file", "pointcloud", "bounds", "lower", "upper", "state", "angle", "axis", "sizeX",
          "sizeY", "standoff", "depth", "id", "type", "default", "time", "searched", "found",
          "version", "ref", "on", "graspable", "markerColor", "off", "relation", "name"]


def _world_value(rng: random.Random, old: Optional[str]) -> str:
    r = rng.random()
    if r < 0.55:
        return rng.choice(HOSTILE_NUMBERS)
    if r < 0.7:
        return rng.choice(HOSTILE_PATHS)
    if r < 0.85:
        return rng.choice(HOSTILE_TEXT)
    return repr(rng.uniform(-1, 1) * 10 ** rng.randint(-5, 12))


def mutate_world(rng: random.Random, base: bytes) -> tuple[str, bytes]:
    """One mutated world file (and a short description of what was done)."""
    from lxml import etree
    root = etree.fromstring(base)
    els = [e for e in root.iter() if isinstance(e.tag, str)]
    done = []
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        el = rng.choice(els)
        op = rng.random()
        if op < 0.45:
            attr = rng.choice(list(el.attrib) or _ATTRS) if rng.random() < 0.75 else rng.choice(_ATTRS)
            value = _world_value(rng, el.get(attr))
            el.set(attr, value)
            done.append(f"{el.tag}@{attr}={value[:20]!r}")
        elif op < 0.52 and el.attrib:
            attr = rng.choice(list(el.attrib))
            del el.attrib[attr]
            done.append(f"del {el.tag}@{attr}")
        elif op < 0.60 and el.getparent() is not None:
            el.getparent().remove(el)
            done.append(f"del <{el.tag}>")
        elif op < 0.67 and el.getparent() is not None:
            el.addnext(copy.deepcopy(el))
            done.append(f"dup <{el.tag}>")
        elif op < 0.72:
            target = rng.choice(els)
            if el is not root and target is not el and el not in target.iterancestors():
                target.append(el)
                done.append(f"move <{el.tag}> into <{target.tag}>")
        elif op < 0.76:
            tag = rng.choice(["room", "part", "mesh", "box", "knob", "pose", "x", "SmallObject"])
            done.append(f"rename <{el.tag}> to <{tag}>")
            el.tag = tag
        elif op < 0.86:
            models = [e for e in els if e.tag == "model"] or [root]
            m = rng.choice(models)
            path = rng.choice(HOSTILE_PATHS)
            etree.SubElement(m, "mesh", file=path, color="0.5 0.5 0.5")
            done.append(f"mesh file={path!r}")
        elif op < 0.90:
            rooms = [e for e in els if e.tag == "room"]
            path = rng.choice(HOSTILE_PATHS)
            rng.choice(rooms).set("pointcloud", path)
            done.append(f"pointcloud={path!r}")
        elif op < 0.93:
            parent = rng.choice([e for e in els if e.tag in ("LargeArticulatedObject", "part")]
                                or [root])
            depth = rng.randint(2, 60)
            cur = parent
            for i in range(depth):
                cur = etree.SubElement(cur, "part", id=f"fz_{rng.randint(0, 10**9)}_{i}",
                                       type="door")
                etree.SubElement(cur, "joint", type="fixed")
            done.append(f"{depth} nested parts")
        elif op < 0.95:
            n = rng.choice((10, 200, 1200))
            room = rng.choice([e for e in els if e.tag == "room"])
            for i in range(n):
                c = copy.deepcopy(room)
                for e in c.iter():
                    if "id" in e.attrib:
                        e.set("id", f"{e.get('id')}_c{i}")
                room.addnext(c)
            done.append(f"{n} room copies")
        else:
            descs = [e for e in els if e.tag == "description"] or [el]
            d = rng.choice(descs)
            d.text = rng.choice(HOSTILE_TEXT)
            done.append(f"text of <{d.tag}>")
    data = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    if rng.random() < 0.15:
        data, what = _mutate_bytes(rng, data, [b"<!DOCTYPE a [<!ENTITY x SYSTEM 'file:///etc/passwd'>]>",
                                               b"&x;", b"<![CDATA[", b"\xff\xfe", b"\x00",
                                               b"<a>" * 300])
        done.append(what)
    return "; ".join(done) or "unchanged", data


def _mutate_bytes(rng: random.Random, data: bytes, tokens: list[bytes]) -> tuple[bytes, str]:
    op = rng.random()
    if op < 0.3:
        cut = rng.randrange(len(data))
        return data[:cut], f"truncated at {cut}"
    if op < 0.6:
        b = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b), "flipped bytes"
    pos = rng.randrange(len(data))
    tok = rng.choice(tokens)
    return data[:pos] + tok + data[pos:], f"inserted {tok[:20]!r}"


_DEEP = None


def _mission_value(rng: random.Random):
    r = rng.random()
    pool = [float("nan"), float("inf"), -float("inf"), 10**26, -1, 0, 1e308, 2**63, 2**64 + 1,
            "", "x" * 5000, None, True, [], {}, [1, 2], {"x": float("nan"), "y": 0},
            "{missing}", "$missing", "/etc/passwd", "../../etc/passwd#x", "/dev/zero#x",
            "/proc/self/environ#x", "subtrees/search.yaml#nope", "subtrees/search.yaml",
            "../missions/go_to_rest.yaml", "subtrees", 1.5, "sequence", {"succeed": None},
            {"inverter": {"succeed": "x"}}, 3, 1000, 1001, 86400, 86401, 1e-300, "1e400",
            "{x} < .nan", "$presence == home", "not {x}", "[1, 2", "{a: [}", 0.0, -0.0,
            "subtrees/search.yaml\x00#note", "a\x00b", "n" * 300, 10 ** 4000]
    if r < 0.9:
        return copy.deepcopy(rng.choice(pool))
    value: Any = "x"
    for _ in range(rng.randint(20, 250)):
        value = [value]
    return value


def _yaml_classes():
    import yaml
    return (getattr(yaml, "CSafeLoader", yaml.SafeLoader),
            getattr(yaml, "CSafeDumper", yaml.SafeDumper))


_YAML_LOADER, _YAML_DUMPER = _yaml_classes()

_KINDS = ["sequence", "selector", "parallel", "retry", "timeout", "repeat", "inverter",
          "force_success", "force_failure", "for_each", "guard", "watch", "skill", "condition",
          "succeed", "fail", "include", "state_machine"]


def _paths(data, prefix=()):
    """Every (container, key) in a plain YAML structure."""
    out = []
    stack = [data]
    while stack:
        cur = stack.pop()
        if isinstance(cur, dict):
            for k, v in cur.items():
                out.append((cur, k))
                stack.append(v)
        elif isinstance(cur, list):
            for i, v in enumerate(cur):
                out.append((cur, i))
                stack.append(v)
    return out


def mutate_mission(rng: random.Random, files: dict[str, bytes]) -> tuple[str, dict[str, bytes], str]:
    """One mutated copy of the shipped missions: (description, files, entry)."""
    import yaml
    names = sorted(n for n in files if "/" not in n)
    entry = rng.choice(names)
    target = entry
    if rng.random() < 0.2 and b"subtrees/search.yaml" in files[entry]:
        target = "subtrees/search.yaml"
    out = dict(files)
    done = []
    if rng.random() < 0.75:
        data = yaml.load(files[target], Loader=_YAML_LOADER)
        for _ in range(rng.choice((1, 1, 2, 3))):
            spots = _paths(data)
            if not spots:
                break
            cont, key = rng.choice(spots)
            op = rng.random()
            if op < 0.45:
                cont[key] = _mission_value(rng)
                done.append(f"{key!r} := {str(cont[key])[:30]!r}")
            elif op < 0.55:
                del cont[key]
                done.append(f"del {key!r}")
            elif op < 0.62 and isinstance(cont, list):
                cont.insert(key, copy.deepcopy(cont[key]))
                done.append(f"dup [{key}]")
            elif op < 0.72 and isinstance(cont, dict) and key in _KINDS:
                new = rng.choice(_KINDS)
                cont[new] = cont.pop(key)
                done.append(f"kind {key} -> {new}")
            elif op < 0.85 and isinstance(cont[key], dict):
                wrap = rng.choice(["retry", "timeout", "repeat", "inverter", "parallel"])
                node: dict = {wrap: cont[key] if wrap != "parallel" else [cont[key]]}
                extra = {"retry": "times", "timeout": "seconds", "repeat": "times",
                         "parallel": "threshold"}.get(wrap)
                if extra:
                    node[extra] = rng.choice([float("nan"), float("inf"), 10**26, 0, -1, 3, 1000,
                                              1001, 86400.5, 1e-9, "3", True, None])
                    if wrap == "parallel":
                        node["policy"] = "threshold"
                cont[key] = node
                done.append(f"wrap in {wrap}")
            elif op < 0.88 and isinstance(data, dict):
                k = rng.choice((3, 30, 60, 99, 200))
                data["utterances"] = [rng.choice([
                    "(x) " * k + "go", "(x|y) " * k + "{%s} go" % rng.choice(
                        list(data.get("parameters") or {"nope": 0})),
                    "{a} {b}", "(" + "|".join(["x"] * k) + ") go", "", "\x00", "(" * k,
                    "x" * (100 * k)])]
                done.append(f"utterance of {k} groups")
            elif op < 0.92 and isinstance(cont[key], dict):
                n = rng.choice((2, 50, 2500))
                cont[key] = {"sequence": [copy.deepcopy(cont[key]) for _ in range(n)]}
                done.append(f"{n} copies")
            else:
                cont[key] = {"include": rng.choice(["/etc/passwd#x", "../../etc/passwd",
                                                    "/proc/self/environ#x", "/dev/zero#x",
                                                    "subtrees/search.yaml#find_object",
                                                    "subtrees/search.yaml#nope", "nope",
                                                    "subtrees/", "go_to_rest.yaml",
                                                    f"{entry}#x", entry])}
                done.append("include")
        try:
            text = yaml.dump(data, Dumper=_YAML_DUMPER, sort_keys=False, allow_unicode=True,
                             width=1000)
        except (yaml.YAMLError, RecursionError):
            text = files[target].decode()
        raw = text.encode("utf-8", "surrogatepass")
    else:
        raw = files[target]
    if rng.random() < 0.35 or not done:
        tokens = [b"\n  bomb: &a [x, x, x, x, x, x, x, x, x]\n  b2: &b [*a, *a, *a, *a, *a, *a, *a, *a]\n"
                  b"  b3: &c [*b, *b, *b, *b, *b, *b, *b, *b]\n  b4: [*c, *c, *c, *c, *c, *c, *c]\n",
                  b"&a", b"*a", b"*b", b" !!python/object/apply:os.system ['true']", b" !!binary aGk=",
                  b" !!set {a, b}", b" 2001-12-14", b"\t", b"%YAML 1.1\n---\n", b"\n---\n", b"<<: *a",
                  b" .nan", b" .inf", b" 1e400", b" 0x7fffffffffffffffffff", b" " + b"9" * 5000,
                  b"\xff\xfe", b"\x00", b"\xef\xbb\xbf", b"? [a, b]\n: c\n", b"[" * 500,
                  b"{" * 2000, b"\n" + b"  " * 300 + b"x: 1\n"]
        raw, what = _mutate_bytes(rng, raw, tokens)
        done.append(what)
    out[target] = raw
    return "; ".join(done), out, entry


_REC_VALUES = [float("nan"), float("inf"), -float("inf"), 0, -1, 0.0, 1e308, -1e308, 10**30,
               "", "x", None, True, [], {}, [1, 2, 3], [[1, 0, 0, 0]] * 4, "/etc/passwd",
               "../../etc/passwd", "/dev/zero", "frames", "../rec/frames/000000_color.png",
               "frames/000001_depth.png", 65536, 2**31, 1e-12, -0.0, 640, 480, "NaN"]


def mutate_recording(rng: random.Random, base: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """One mutated recording: manifest fields and frames."""
    import cv2
    import numpy as np
    files = dict(base)
    manifest = json.loads(base["rec/manifest.json"])
    done = []
    for _ in range(rng.choice((1, 1, 2))):
        op = rng.random()
        if op < 0.6:
            spots = _paths(manifest)
            cont, key = rng.choice(spots)
            if rng.random() < 0.8:
                cont[key] = copy.deepcopy(rng.choice(_REC_VALUES))
                done.append(f"{key!r} := {str(cont[key])[:30]!r}")
            else:
                del cont[key]
                done.append(f"del {key!r}")
        else:
            frames = sorted(k for k, v in files.items()
                            if k.startswith("rec/frames/") and isinstance(v, bytes))
            if not frames:
                continue
            f = rng.choice(frames)
            kind = rng.random()
            if kind < 0.2:
                del files[f]
                done.append(f"deleted {f}")
            elif kind < 0.4:
                files[f] = files[f][:rng.randrange(len(files[f]))]
                done.append(f"truncated {f}")
            elif kind < 0.55:
                b = bytearray(files[f])
                for _ in range(8):
                    b[rng.randrange(len(b))] = rng.randrange(256)
                files[f] = bytes(b)
                done.append(f"corrupted {f}")
            elif kind < 0.7:
                img = np.zeros((rng.choice((24, 10)), rng.choice((32, 7)), rng.choice((1, 3))),
                               rng.choice((np.uint8, np.uint16)))
                files[f] = cv2.imencode(".png", img)[1].tobytes()
                done.append(f"replaced {f} by {img.shape} {img.dtype}")
            elif kind < 0.8:
                files[f] = ("dir",)
                done.append(f"{f} is a directory")
            elif kind < 0.9:
                files[f] = ("symlink", "/etc/passwd")
                done.append(f"{f} links to /etc/passwd")
            else:
                files[f] = ("fifo",)
                done.append(f"{f} is a FIFO")
    files["rec/manifest.json"] = json.dumps(manifest).encode()
    if "rec/captures.jsonl" in files and rng.random() < 0.3:    # version 2's own files
        name = rng.choice(["rec/captures.jsonl", "rec/actions.jsonl", "rec/manifest.json"])
        op = rng.random()
        if op < 0.4 and isinstance(files[name], bytes):
            files[name], what = _mutate_bytes(rng, files[name], [
                b"9" * 5000, b"-" + b"9" * 41, b"\\u0000", b"\\ud800", b"1e400", b"NaN",
                b"[" * 3000, b"\n{}\n", b"\x00"])
            done.append(f"{name}: {what}")
        elif op < 0.55:
            files[name] = ("fifo",)
            done.append(f"{name} is a FIFO")
        elif op < 0.7:
            files[name] = ("symlink", rng.choice(["/dev/zero", "/etc/passwd", "../x"]))
            done.append(f"{name} is a link out")
        elif op < 0.8:
            files[name] = ("sparse", rng.choice((1 << 20, 200 << 20, 3 << 30)))
            done.append(f"{name} is sparse")
        else:
            files[name] = ("dir",)
            done.append(f"{name} is a directory")
    if rng.random() < 0.1:
        files["rec/manifest.json"], what = _mutate_bytes(
            rng, files["rec/manifest.json"], [b"NaN", b"Infinity", b"[" * 5000, b"\xff"])
        done.append(what)
    return "; ".join(done), files


# ---------------------------------------------------------------------------------------------
# Fixed cases (issue 19's hand-made ones)

def fixed_cases() -> list[Case]:
    import re
    world = _demo_world().decode()
    missions = _missions()
    out: list[Case] = []

    def w(name, text, expect="refused", klass=""):
        out.append(Case("world", name, {**WORLD_NEIGHBOURS, "world.xml": text.encode()},
                        "world.xml", expect, klass))

    def first(pattern, repl, text=world):
        new, n = re.subn(pattern, repl, text, count=1)
        assert n == 1, pattern
        return new

    w("demo_world", world, "accepted")
    w("nan_pose", first(r'<pose x="3" y="2.2"/>', '<pose x="NaN" y="2.2"/>'))
    w("inf_parking", first(r'(<position id="[^"]*" x=")[^"]*"', r'\1INF"'))
    w("nan_parking", first(r'(<position id="[^"]*" x="[^"]*" y=")[^"]*"', r'\1NaN"'))
    w("nan_joint_limit", first(r'upper="[^"]*"', 'upper="NaN"'))
    w("inf_joint_state", first(r'(<joint [^>]*)state="[^"]*"', r'\1state="INF"'))
    w("nan_knob_angle", first(r'(<knob [^>]*)angle="[^"]*"', r'\1angle="NaN"'))
    w("coordinate_1e308", first(r'<pose x="3" y="2.2"/>', '<pose x="1e308" y="2.2"/>'))
    w("size_1e999", first(r'size="1.2 0.8 0.03"', 'size="1.2 1e999 0.03"'))
    w("knob_radius_zero", first(r'(<knob [^>]*)radius="[^"]*"', r'\1radius="0"'))
    w("handle_radius_zero", first(r'(<handle [^>]*)radius="[^"]*"', r'\1radius="0"'))
    for label, path in (("mesh_etc_passwd", "../../etc/passwd"), ("mesh_absolute", "/etc/passwd"),
                        ("mesh_dev_zero", "/dev/zero"), ("mesh_proc", "/proc/self/environ"),
                        ("mesh_directory", "emptydir"), ("mesh_fifo", "fifo.ply"),
                        ("mesh_symlink_out", "escape.ply"), ("mesh_dir_symlink_out", "etc/passwd")):
        w(label, first(r'(<model>)', rf'\1<mesh file="{path}" color="0.5 0.5 0.5"/>'))
    w("mesh_inside", first(r'(<model>)', r'\1<mesh file="sub/inner.ply" color="0.5 0.5 0.5"/>'),
      "accepted")
    w("pointcloud_proc", first(r'(<room id="kitchen")', r'\1 pointcloud="../../../proc/self/environ"'))
    w("attribute_10MB", first(r'(<(?:LargeObject|LargeArticulatedObject) [^>]*)name="[^"]*"',
                              r'\1name="' + "x" * 10_000_000 + '"'))
    w("rooms_20000", world.replace("</apartment>", "".join(
        f'<room id="fr{i}" name="r"/>' for i in range(20000)) + "</apartment>"))
    w("part_nesting_100", first(r"(</LargeArticulatedObject>)", "".join(
        f'<part id="fp{i}" type="door"><joint type="fixed"/>' for i in range(100))
        + "</part>" * 100 + r"\1"))
    w("billion_laughs", '<?xml version="1.0"?>\n<!DOCTYPE l [<!ENTITY a "aaaaaaaaaa">'
      '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>\n<apartment id="x" version="1">'
      '<room id="r" name="&b;"/></apartment>\n')

    def m(name, text, expect="refused", extra=None, klass=""):
        files = {**missions, "case.yaml": text.encode(), **(extra or {})}
        out.append(Case("mission", name, files, "case.yaml", expect, klass))

    bomb = ("a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n"
            + "".join(f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n"
                      for p, c in zip("abcdefgh", "bcdefghi")))
    indent = lambda text, n: "".join(" " * n + line + "\n" for line in text.splitlines())
    m("alias_bomb_blackboard", "name: bomb\nblackboard:\n" + indent(bomb, 2)
      + "tree:\n  succeed: ok\n")
    m("alias_bomb_parameter_default", "name: bomb\nparameters:\n  p:\n    type: any\n"
      "    default:\n" + indent(bomb, 6) + "tree:\n  succeed: ok\n")
    m("alias_bomb_skill_input", "name: bomb\ntree:\n  skill: Say\n  inputs:\n    text:\n"
      + indent(bomb, 6))
    m("alias_recursive", "name: r\nblackboard: {x: &a [*a]}\ntree:\n  succeed: ok\n")
    m("wide_10000", "name: wide\ntree:\n  sequence:\n"
      + "    - skill: Say\n      inputs: {text: hi}\n" * 10_000, "accepted")
    m("deep_3000_inverters", "name: deep\ntree: " + "{inverter: " * 3000 + "{succeed: ok}"
      + "}" * 3000 + "\n")
    m("deep_yaml_flow", "name: deep\ntree: " + "[" * 100_000 + "\n")
    m("retry_1e26", "name: r\ntree:\n  retry: {succeed: ok}\n  times: 100000000000000000000000000\n")
    m("retry_1e6", "name: r\ntree:\n  retry: {succeed: ok}\n  times: 1000000\n")
    m("timeout_nan", "name: r\ntree:\n  timeout: {succeed: ok}\n  seconds: .nan\n")
    m("timeout_inf", "name: r\ntree:\n  timeout: {succeed: ok}\n  seconds: .inf\n")
    m("timeout_1e9", "name: r\ntree:\n  timeout: {succeed: ok}\n  seconds: 1000000000\n")
    m("nan_input", "name: r\ntree:\n  skill: NavigateTo\n  inputs: {target: {x: .nan, y: 0}}\n")
    m("huge_integer", "name: r\nblackboard: {n: " + "9" * 5000 + "}\ntree:\n  succeed: ok\n")
    m("python_tag", "name: r\nblackboard: {n: !!python/object/apply:os.system ['true']}\n"
      "tree:\n  succeed: ok\n")
    for label, target in (("include_etc_passwd", "/etc/passwd#x"),
                          ("include_proc_environ", "../../../../proc/self/environ#x"),
                          ("include_dev_zero", "/dev/zero#x"),
                          ("include_directory", "subtrees/#x"),
                          ("include_escape", "../../../../etc/passwd")):
        m(label, f"name: r\ntree:\n  include: '{target}'\n")
    m("include_inside", "name: r\nblackboard: {notes: []}\ntree:\n"
      "  include: subtrees/search.yaml#note\n  params: {text: hi, about: x, notes: '{notes}'}\n",
      "accepted")
    inc_bomb = "name: r\ntree:\n  include: s0\nsubtrees:\n" + "".join(
        f"  s{i}:\n    tree:\n      sequence:\n        - include: s{i + 1}\n"
        f"        - include: s{i + 1}\n" for i in range(24)) + "  s24:\n    tree: {succeed: ok}\n"
    m("include_bomb", inc_bomb)

    rec = _recording_files()
    man = json.loads(rec["rec/manifest.json"])

    def r(name, manifest=None, files=None, expect="refused"):
        f = {**rec, **(files or {})}
        if manifest is not None:
            f["rec/manifest.json"] = json.dumps(manifest).encode()
        for k, v in list(f.items()):
            if v is None:
                del f[k]
        out.append(Case("recording", name, f, "rec", expect))

    def with_(path, value):
        d = copy.deepcopy(man)
        cur = d
        for k in path[:-1]:
            cur = cur[k]
        cur[path[-1]] = value
        return d

    import cv2
    import numpy as np
    r("valid", expect="accepted")
    r("missing_png", files={"rec/frames/000001_depth.png": None})
    r("truncated_png", files={"rec/frames/000001_color.png": rec["rec/frames/000001_color.png"][:40]})
    r("corrupt_png", files={"rec/frames/000000_depth.png": b"\x89PNG\r\n\x1a\n" + b"\x00" * 64})
    r("depth_8_bit", files={"rec/frames/000000_depth.png":
                            cv2.imencode(".png", np.zeros((24, 32), np.uint8))[1].tobytes()})
    r("wrong_size", files={"rec/frames/000001_color.png":
                           cv2.imencode(".png", np.zeros((10, 7, 3), np.uint8))[1].tobytes()})
    r("depth_scale_nan", with_(["depth_scale"], float("nan")))
    r("depth_scale_zero", with_(["depth_scale"], 0))
    r("depth_scale_negative", with_(["depth_scale"], -0.001))
    r("pose_nan", with_(["captures", 0, "base_pose", "x"], float("nan")))
    r("fx_zero", with_(["intrinsics", "fx"], 0))
    r("frame_etc_passwd", with_(["captures", 0, "color"], "/etc/passwd"))
    r("frame_escape", with_(["captures", 0, "depth"], "../../../../etc/passwd"))
    out.extend(_issue_44_cases(world, first, w, m))
    return out


def _issue_44_cases(world: str, first, w, m) -> list[Case]:
    """Issue 44's hand-made cases, each tagged with its class (CLASSES)."""
    import cv2
    import numpy as np
    out: list[Case] = []

    def mesh(path):
        return first(r'(<model>)', rf'\1<mesh file="{path}" color="0.5 0.5 0.5"/>')

    for name in HOSTILE_MESHES:
        w(f"mesh_{name}", mesh(name), klass="fifo" if "fifo" in name else "mesh-content")
    w("mesh_obj_with_material_inside", mesh("ok.obj"), "accepted", klass="mesh-content")
    w("pointcloud_nan", first(r'(<room id="kitchen")', r'\1 pointcloud="nan.ply"'),
      klass="mesh-content")
    w("attributes_100000", first(r'(<room id="kitchen")', r'\1 ' + " ".join(
        f'a{i}="1"' for i in range(100_000))), klass="size")
    w("duplicate_surface_id", first(r'(<surface id="top")', r'<surface id="top" sizeX="1" '
                                    r'sizeY="1"><pose z="0.5"/></surface>\1'), klass="structure")
    # an object and a place of the base world, whatever it is
    obj = re.search(r'<SmallObject id="([^"]+)"', world).group(1)
    place = re.search(r'<Large(?:Articulated)?Object id="([^"]+)"', world).group(1)
    stats = lambda *rows: world.replace("</apartment>", "<searchStats>" + "".join(
        f'<stat object="{o}" place="{p}" searched="{a}" found="{b}"/>' for o, p, a, b in rows)
        + "</searchStats></apartment>")
    w("stat_found_above_searched", stats((obj, place, 2, 5)), klass="numbers")
    w("stat_unknown_place", stats((obj, "nowhere", 2, 1)), klass="structure")
    w("stat_twice", stats((obj, place, 2, 1), (obj, place, 3, 1)), klass="structure")
    # (w and m append to fixed_cases' list; recordings and bags to this one)

    m("include_nul", 'name: r\ntree:\n  include: "subtrees/search.yaml\\0#note"\n', klass="nul")
    m("name_300_characters", f"name: {'n' * 300}\ntree:\n  succeed: ok\n", klass="size")
    worst = "name: worst\nutterances: ['" + "(x) " * 60 + "go']\ntree:\n  succeed: ok\n"
    m("template_60_optional_groups", worst, "accepted", klass="template")
    m("template_150_tokens", worst.replace("(x) " * 60, "(x) " * 150), klass="template")
    m("template_slots_40_words", "name: t\nparameters:\n  a: {type: string}\n"
      "  b: {type: string}\nutterances: ['" + "(x|y) " * 20 + "{a} x {b} (x) go']\n"
      "tree:\n  succeed: ok\n", "accepted", klass="template")
    m("blackboard_integer_5000_digits", "name: r\nblackboard: {n: " + "9" * 5000 + "}\n"
      "tree:\n  succeed: ok\n", klass="huge-integer")

    rec = _recording_files(version=2)

    def r2(name, klass, files=None, expect="refused", edit=None):
        f = {**rec, **(files or {})}
        if edit is not None:
            man = json.loads(f["rec/manifest.json"])
            edit(man)
            f["rec/manifest.json"] = json.dumps(man).encode()
        out.append(Case("recording", name, f, "rec", expect, klass))

    caps = rec["rec/captures.jsonl"].decode().splitlines()
    big = "9" * 5000
    r2("v2_valid", "", expect="accepted")
    r2("manifest_integer_5000_digits", "huge-integer", {"rec/manifest.json": rec[
        "rec/manifest.json"].replace(b'"version": 2', f'"version": {big}'.encode())})
    r2("captures_integer_5000_digits", "huge-integer", {"rec/captures.jsonl": (
        caps[0].replace('"index": 0', f'"index": {big}') + "\n" + caps[1] + "\n").encode()})
    r2("actions_integer_5000_digits", "huge-integer",
       {"rec/actions.jsonl": f'{{"i": {big}, "action": "say", "args": {{}}}}\n'.encode()})
    r2("frame_path_nul", "nul", {"rec/captures.jsonl": (
        caps[0].replace("_color.png", "_color.png\\u0000x") + "\n").encode()})
    for name in ("captures.jsonl", "actions.jsonl", "manifest.json"):
        r2(f"{name}_fifo", "fifo", {f"rec/{name}": ("fifo",)})
        r2(f"{name}_dev_zero", "fifo", {f"rec/{name}": ("symlink", "/dev/zero")})
        r2(f"{name}_sparse_3GB", "size", {f"rec/{name}": ("sparse", 3 << 30)})
    r2("captures_link_out", "paths", {"rec/captures.jsonl": ("symlink", "../out.jsonl"),
                                      "out.jsonl": rec["rec/captures.jsonl"]})
    r2("depth_scale_1e300", "numbers", edit=lambda d: d.update(depth_scale=1e300))
    r2("depth_scale_1e-60", "numbers", edit=lambda d: d.update(depth_scale=1e-60))
    r2("start_pose_1e300", "numbers",
       edit=lambda d: d.update(start_pose={"x": 1e300, "y": 0.0, "yaw": 0.0}))
    r2("frames_16384_square", "size", edit=lambda d: d["intrinsics"].update(
        width=16384, height=16384, cx=8191.5, cy=8191.5))
    r2("rgba_colour", "structure", {"rec/frames/000001_color.png": cv2.imencode(
        ".png", np.zeros((24, 32, 4), np.uint8))[1].tobytes()})
    r2("twenty_thousand_captures_of_one_frame", "size",
       {"rec/captures.jsonl": ((caps[0] + "\n") * 20_000).encode()}, expect="accepted")

    if _has_ros():
        def b(name, klass, files, entry="bag.mcap"):
            out.append(Case("bag", name, files, entry, "refused", klass))
        b("mcap_fifo", "fifo", {"bag.mcap": ("fifo",)})
        b("mcap_dev_zero", "fifo", {"bag.mcap": ("symlink", "/dev/zero")})
        for kind, content in (("fifo", ("fifo",)), ("dev_zero", ("symlink", "/dev/zero")),
                              ("sparse_3GB", ("sparse", 3 << 30)),
                              ("nested_30000", ("a: " + "[" * 30_000 + "]" * 30_000).encode())):
            b(f"topic_map_{kind}", "fifo" if kind in ("fifo", "dev_zero") else "size",
              {"bag.mcap": b"\x89MCAP0\r\n", "bag.topics.yaml": content})
        b("rosbag2_metadata_fifo", "fifo", {"bagdir/metadata.yaml": ("fifo",),
                                            "bagdir/x.mcap": b"\x89MCAP0\r\n"}, "bagdir")
    return out


# ---------------------------------------------------------------------------------------------
# Generated cases

def generated_cases(loader: str, n: int, seed: int) -> Iterator[Case]:
    """``n`` mutated cases for ``loader``, the same ones for the same seed (made one at a time:
    some are megabytes)."""
    rng = random.Random(f"{loader}:{seed}")
    if loader == "world":
        base = _demo_world()
        for _ in range(n):
            what, data = mutate_world(rng, base)
            yield Case("world", what, {**WORLD_NEIGHBOURS, "world.xml": data}, "world.xml")
    elif loader == "mission":
        base = _missions()
        for _ in range(n):
            what, files, entry = mutate_mission(rng, base)
            yield Case("mission", what, files, entry)
    elif loader == "recording":
        bases = (_recording_files(), _recording_files(version=2))
        for i in range(n):
            what, files = mutate_recording(rng, bases[i % 2])
            yield Case("recording", what, files, "rec")


# ---------------------------------------------------------------------------------------------
# Running cases in worker processes

def _worker(conn, timeout: float) -> None:   # pragma: no cover - runs in a child process
    import resource
    os.chdir(tempfile.gettempdir())
    _registry()                                  # import the skills once, before timing
    import hearth.worldmodel.geometry  # noqa: F401
    import hearth.robot.recording  # noqa: F401
    try:    # a memory bomb ends as MemoryError (a traceback) rather than swapping
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = 6 * 1024 ** 3
        if hard == resource.RLIM_INFINITY or hard > limit:
            resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ValueError, OSError):
        pass
    conn.send("ready")
    while True:
        try:
            case = conn.recv()
        except EOFError:
            return
        if case is None:
            return
        try:
            verdict = run_case(case, timeout)
        except BaseException as err:  # noqa: BLE001 - report, keep serving
            verdict = Verdict("traceback", "in the fuzz harness: " + _describe(err))
        conn.send(verdict)


class _Worker:
    def __init__(self, ctx, timeout: float):
        self.ctx, self.timeout = ctx, timeout
        self.start()

    def start(self) -> None:
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_worker, args=(child, self.timeout), daemon=True)
        self.proc.start()
        child.close()
        if not self.conn.poll(600) or self.conn.recv() != "ready":   # imports: seconds
            raise RuntimeError("fuzz worker did not start")

    def restart(self) -> None:
        from hearth.executive.suite_local import stop_worker
        stop_worker(self.proc, self.conn, kill=True)
        self.start()

    def close(self) -> None:
        from hearth.executive.suite_local import stop_worker
        stop_worker(self.proc, self.conn)


def run_cases(cases: Iterable[Case], jobs: int = 1, timeout: float = 30.0
              ) -> list[tuple[Case, Verdict]]:
    """(case, verdict) for every case, run in ``jobs`` worker processes; a case's files are
    dropped once it has run."""
    ctx = multiprocessing.get_context("spawn")
    workers = [_Worker(ctx, timeout) for _ in range(max(1, jobs))]
    todo = iter(cases)
    results: list[tuple[Case, Verdict]] = []
    busy: dict[int, tuple[Case, float]] = {}
    more = True

    def done(wi: int, verdict: Verdict) -> None:
        case, _ = busy.pop(wi)
        case.files = {}
        results.append((case, verdict))
    try:
        while more or busy:
            for wi, w in enumerate(workers):
                if wi not in busy and more:
                    case = next(todo, None)
                    if case is None:
                        more = False
                        break
                    w.conn.send(case)
                    busy[wi] = (case, time.monotonic())
            ready = wait([workers[wi].conn for wi in busy], timeout=0.5) if busy else []
            for wi in list(busy):
                w = workers[wi]
                if w.conn in ready:
                    try:
                        done(wi, w.conn.recv())
                    except (EOFError, OSError):
                        done(wi, Verdict("crash", f"worker died (exit {w.proc.exitcode})"))
                        w.restart()
                elif not w.proc.is_alive():
                    done(wi, Verdict("crash", f"worker died (exit {w.proc.exitcode})"))
                    w.restart()
                elif time.monotonic() - busy[wi][1] > timeout + 15:   # where no alarm reaches
                    done(wi, Verdict("hang", f"over {timeout + 15:g} s (worker killed)"))
                    w.restart()
    finally:
        for w in workers:
            w.close()
    return results


# ---------------------------------------------------------------------------------------------
# The HTTP API (issue 44): hostile requests to a real server

_WORST_MISSION = ("hearth: 1\nname: worst\nutterances: ['" + "(x) " * 60 + "go']\n"
                  "tree:\n  skill: Act\n")


def _http_cases(port: int, run_id: str) -> list[tuple[str, str, str, str, dict, bytes, int]]:
    """(class, name, method, path, headers, body, expected status) of the hand-made requests."""
    js = {"content-type": "application/json"}
    out = []
    for origin in ("http://evil.com", "null", f"http://127.0.0.1:{port + 1}"):
        for method, path in (("POST", "/api/stop"), ("POST", f"/api/runs/{run_id}/cancel"),
                             ("POST", "/api/runs"), ("PUT", "/api/autonomy")):
            body = b'{"mission": "bench_chores"}' if path == "/api/runs" else \
                b'{"level": 3}' if path == "/api/autonomy" else b""
            out.append(("cross-site", f"{method} {path} from {origin}", method, path,
                        {"Origin": origin, **js}, body, 403))
    out.append(("cross-site", "POST /api/stop with Sec-Fetch-Site: cross-site", "POST",
                "/api/stop", {"Sec-Fetch-Site": "cross-site"}, b"", 403))
    for host in ("localhost:80@evil.com", f"localhost:{port}@evil.com", "localhost:99999",
                 f"127.0.0.1:{port + 1}", "a b", "localhost, evil.com"):
        out.append(("host", f"Host {host}", "GET", "/api/health", {"Host": host}, b"", 421))
    for name, value in (("infinity", b"Infinity"), ("nan", b"NaN"), ("1e400", b"1e400"),
                        ("5000_digits", b"9" * 5000)):
        out.append(("huge-integer" if "digit" in name else "numbers", f"priority {name}",
                    "POST", "/api/runs", js, b'{"mission":"bench_chores","priority":' + value
                    + b"}", 422))
    out.append(("nul", "parameter value with NUL and a lone surrogate", "PUT",
                "/api/parameters/presence", js, b'{"value":"\\u0000\\ud800"}', 422))
    out.append(("structure", "a key twice", "POST", "/api/runs", js,
                b'{"mission":"bench_chores","mission":"worst"}', 422))
    out.append(("template", "the worst template's utterance", "POST", "/api/commands", js,
                ('{"text": "%s"}' % WORST_UTTERANCE).encode(), 200))
    return out


def check_http(n: int, seed: int) -> dict:
    """The hand-made hostile requests and ``n`` schema-generated ones (with hostile bodies and
    foreign origins) against a real server over the demo home; health asked while the worst
    template is matched. Failures: a 5xx, an answer other than the expected one, a foreign
    page's state change accepted."""
    import threading

    import httpx

    from hearth.executive.command.api import create_app
    from hearth.executive.command.fuzz import run_fuzz
    from hearth.executive.command.server import ServerThread
    from hearth.benchmarks.api import _service
    from hearth.robot.clock import SimClock

    report: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "worst.yaml").write_text(_WORST_MISSION)
        service, _ = _service(tmp, SimClock(), 10.0)
        try:
            with ServerThread(create_app(service)) as srv, \
                    httpx.Client(base_url=srv.url, timeout=60.0) as c:
                run_id = c.post("/api/runs", json={"mission": "bench_chores"}).json()["run"]["id"]
                by_class: dict[str, dict[str, int]] = {}
                failures = []
                for klass, name, method, path, headers, body, expect in _http_cases(
                        srv.port, run_id):
                    r = c.request(method, path, headers=headers, content=body)
                    row = by_class.setdefault(klass, {"requests": 0, "failures": 0})
                    row["requests"] += 1
                    if r.status_code != expect:
                        row["failures"] += 1
                        failures.append({"class": klass, "case": name, "status": r.status_code,
                                         "expected": expect, "answer": r.text[:200]})
                # health while the worst template is matched (figures, not a gate)
                t0 = time.perf_counter()
                done: dict[str, float] = {}

                def worst() -> None:
                    c.post("/api/commands", json={"text": WORST_UTTERANCE})
                    done["ms"] = (time.perf_counter() - t0) * 1000
                th = threading.Thread(target=worst)
                th.start()
                health = c.get("/api/health")
                health_ms = (time.perf_counter() - t0) * 1000
                th.join(120)
                schema = c.get("/openapi.json").json()
                fuzz = run_fuzz(c, schema, ["bench_chores", "worst", "presence", run_id,
                                            WORST_UTTERANCE, "x x go", ""], n, seed=seed)
        finally:
            service.executive.shutdown()
            service.close()
    fixed_5xx = sum(f["status"] >= 500 for f in failures)
    report.update(
        fixed_requests=sum(r["requests"] for r in by_class.values()), by_class=by_class,
        fixed_failures=failures[:20], generated_requests=fuzz["requests"],
        generated_by_status=fuzz["by_class"], generated_failures=fuzz["failures"][:20],
        cross_site_accepted=fuzz["cross_site_accepted"] + sum(
            f["status"] < 400 for f in failures if f["class"] == "cross-site"),
        **{"5xx": fixed_5xx + sum(f["status"] >= 500 for f in fuzz["failures"])},
        health_ok_during_worst_template=health.status_code == 200,
        health_ms_during_worst_template=round(health_ms, 1),
        worst_template_command_ms=round(done.get("ms", float("nan")), 1))
    report["failures"] = len(failures) + len(fuzz["failures"])
    return report


# ---------------------------------------------------------------------------------------------
# Report

def summarise(results: list[tuple[Case, Verdict]]) -> dict:
    counts = {"cases": len(results), "accepted": 0, "refused": 0, **{k: 0 for k in FAILURES}}
    ms = []
    for _, v in results:
        if v.outcome in ("accepted", "refused"):
            counts[v.outcome] += 1
        else:
            counts[_OUTCOME_KEY[v.outcome]] += 1
        if v.outside:
            counts["paths_outside_world"] += 1
        ms.append(v.ms)
    counts["median_ms"] = round(statistics.median(ms), 2) if ms else 0.0
    return counts


def failures(results: list[tuple[Case, Verdict]], limit: int = 12) -> list[dict]:
    out = []
    for c, v in results:
        if v.outcome not in ("accepted", "refused") or v.outside:
            out.append({"loader": c.loader, "case": c.name[:120], "outcome": v.outcome,
                        "detail": v.detail[:240], "paths_outside": v.outside})
    return out[:limit]


def by_class(results: list[tuple[Case, Verdict]]) -> dict:
    """The fixed cases by class: cases, and those that did not end as expected."""
    out: dict[str, dict[str, int]] = {}
    for c, v in results:
        if c.expect is None or not c.klass:
            continue
        row = out.setdefault(c.klass, {"cases": 0, "failed": 0})
        row["cases"] += 1
        row["failed"] += v.outcome != c.expect or bool(v.outside)
    return out


def run(args) -> dict:
    quick = getattr(args, "quick", False)
    n = getattr(args, "cases", None) or (200 if quick else 2000)
    seed = getattr(args, "seed", 0) or 0
    jobs = max(1, getattr(args, "jobs", 1) or 1)
    timeout = getattr(args, "timeout", 60.0) or 60.0
    t0 = time.perf_counter()
    sizes = {"world": n, "mission": n, "recording": max(50, n // 4), "bag": 0}
    fixed = fixed_cases()
    cases = itertools.chain(*(generated_cases(l, sizes[l], seed) for l in LOADERS), fixed)
    results = run_cases(cases, jobs=jobs, timeout=timeout)
    out: dict[str, Any] = {"seed": seed, "timeout_s": timeout}
    for loader in LOADERS:
        out[loader] = summarise([(c, v) for c, v in results if c.loader == loader])
        out[loader]["fixed_cases"] = sum(c.loader == loader and c.expect is not None
                                         for c, _ in results)
    out["total"] = {k: sum(out[l][k] for l in LOADERS)
                    for k in ("cases", "accepted", "refused", *FAILURES)}
    out["world_and_mission"] = {k: out["world"][k] + out["mission"][k] for k in FAILURES}
    fixed_report, fixed_failed = {}, []
    for c, v in results:
        if c.expect is None:
            continue
        fixed_report[f"{c.loader}/{c.name}"] = {"expected": c.expect, "outcome": v.outcome,
                                                "ms": round(v.ms, 1), "message": v.detail[:160]}
        if v.outcome != c.expect or v.outside:
            fixed_failed.append(f"{c.loader}/{c.name}")
    out["fixed"] = fixed_report
    out["fixed_failed"] = fixed_failed
    out["fixed_by_class"] = by_class(results)
    http_n = getattr(args, "http_requests", None) or (100 if quick else 500)
    out["http"] = check_http(http_n, seed)
    out["total"]["5xx"] = out["http"]["5xx"]
    out["total"]["cross_site_accepted"] = out["http"]["cross_site_accepted"]
    out["failures"] = failures(results, limit=40)
    out["targets"] = {**{k: 0 for k in FAILURES}, "5xx": 0, "cross_site_accepted": 0}
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out
