"""Objects learned from views, written into the map (docs/objects.md, "Learned objects").

``add_learned_object`` turns a learned model (hearth.perception.object_learning.LearnedModel, or
anything with its fields) into mesh files beside the world file and a SmallObject on the
furniture it stands on, with the name and words a person gave it: from then on the object
detector, the verifier, the command layer's vocabulary and the map's queries use it as
they use a drawn object. Nothing is written into the map until every mesh file is on disk,
and a name that is already taken is refused before anything is written.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from hearth.worldmodel.errors import WorldError
from hearth.worldmodel.nodes import Model, SmallObject, Visual
from hearth.worldmodel.pose import Pose

#: Where learned meshes go, below the world file's folder.
LEARNED_DIR = "learned"
#: Longest name a learned object may have (it becomes file names).
MAX_NAME = 60


def object_id_for(name: str) -> str:
    """A map id for a person's name of an object ("pill organiser" -> "pill_organiser")."""
    return re.sub(r"[^a-z0-9]+", "_", name.strip().lower()).strip("_")


def check_name(world, name: str) -> str:
    """The id a new object called ``name`` gets; WorldError when the name is empty, too
    long, or already names something in the map (its id, or a small object whose name or
    whose colour and type are those words)."""
    from hearth.worldmodel.world import tokens
    oid = object_id_for(name)
    if not oid:
        raise WorldError(f"{name!r} is no name for an object: give it words")
    if len(name) > MAX_NAME:
        raise WorldError(f"the name {name[:20]!r}... is longer than {MAX_NAME} characters")
    if oid in world:
        raise WorldError(f"the map already has {oid!r}: choose another name", node=oid)
    want = set(tokens(name))
    for o in world.small_objects():
        names = [o.name, f"{o.color} {o.type}".strip(), o.type, o.id.replace("_", " ")]
        if any(n and set(tokens(n)) == want for n in names):
            raise WorldError(f"{name!r} already names the {world.label(o.id)} "
                             f"{world.describe_location(o.id)}: choose another name", node=o.id)
    return oid


def _write_ply(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> None:
    """A binary little-endian PLY mesh, written to a temporary name and renamed."""
    import os
    v = np.asarray(vertices, dtype="<f4")
    f = np.asarray(triangles, dtype="<i4")
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    faces = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, f
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(v.tobytes())
        out.write(faces.tobytes())
        out.flush()
        os.fsync(out.fileno())
    os.replace(tmp, path)


def add_learned_object(world, model, name: str, parent_id: str, *,
                       kind: str = "", words: str = "", colour: str = "",
                       directory: Optional[Path] = None, source: str = "learn") -> SmallObject:
    """Write ``model``'s meshes (one file per colour) under ``directory`` (default: the
    world's folder) / learned/, then add a SmallObject ``name`` on ``parent_id`` where the
    model stands. Returns the new node. WorldError (nothing written) on a name already
    taken or a model without a mesh."""
    oid = check_name(world, name)
    meshes: Sequence = getattr(model, "meshes", ())
    if not meshes:
        raise WorldError(f"the model of {name!r} has no surface to save")
    base = Path(directory if directory is not None else (world.base_dir or Path.cwd()))
    folder = base / LEARNED_DIR
    folder.mkdir(parents=True, exist_ok=True)
    visuals = []
    for k, (V, F, rgb) in enumerate(meshes):
        rel = f"{LEARNED_DIR}/{oid}-{k}.ply"
        _write_ply(base / rel, V, F)
        visuals.append(Visual("mesh", file=rel, color=tuple(float(c) for c in rgb)))
    T_parent = np.linalg.inv(world.T_world(parent_id)) @ np.asarray(model.T_world_object)
    pose = Pose.from_matrix(T_parent)
    kind = kind or name.split()[-1]
    obj = SmallObject(id=oid, type=kind, pose=pose, relation="on", name=name.strip(),
                      description=" ".join(w for w in (words, "learned from views") if w),
                      color=colour, graspable=True, model=Model(visuals=visuals))
    world.add_small_object(obj, parent_id, source=source)
    return obj


def support_colour(world, furniture_id: str, point) -> Optional[tuple]:
    """The colour (RGB in [0, 1]) of the furniture's visual whose top face holds the world
    ``point`` (within 1.5 cm of its top, over its extent), or None: a reference a camera's
    colours can be corrected against."""
    from hearth.worldmodel.geometry import object_meshes
    p = np.asarray(point, dtype=float)
    best = None
    for lm in object_meshes(world, world.get(furniture_id)):
        v = np.asarray(lm.mesh.vertices)
        if not len(v):
            continue
        lo, hi = v.min(axis=0), v.max(axis=0)
        if np.all(p[:2] >= lo[:2]) and np.all(p[:2] <= hi[:2]) and abs(hi[2] - p[2]) < 0.015:
            area = float(np.prod(hi[:2] - lo[:2]))
            if best is None or area > best[0]:
                best = (area, tuple(float(c) for c in lm.color))
    return None if best is None else best[1]


# -- model sets: learned models of objects the map already has --------------------------------
#
# The benchmarks compare recognition and fetching with drawn and with learned models of the
# same objects. A model set is a directory: one PLY mesh per colour of each learned object
# and ``models.json`` naming, per object id, its meshes (file, colour, pose in the object's
# frame) and, under ``not_learned``, the objects that could not be learned and why.
# ``apply_model_set`` gives a map those models in place of the drawn ones.

#: The manifest of a model set.
MODEL_SET_FILE = "models.json"


def write_model_set(directory, models: dict, not_learned: dict, info: Optional[dict] = None) -> Path:
    """Write a model set under ``directory``: ``models`` maps an object id to its meshes,
    (vertices, triangles, RGB in [0, 1], 4x4 T_object_mesh: where the learned mesh stands
    in the object's own frame). The manifest is written last (a set without it is
    incomplete). Returns the manifest's path."""
    import json
    import os
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    entries = {}
    for oid, meshes in sorted(models.items()):
        vis = []
        for k, (V, F, rgb, T) in enumerate(meshes):
            name = f"{oid}-{k}.ply"
            _write_ply(folder / name, V, F)
            p = Pose.from_matrix(np.asarray(T, dtype=float))
            vis.append(dict(file=name, color=[round(float(c), 4) for c in rgb],
                            pose=[round(float(x), 6) for x in (p.x, p.y, p.z, p.roll, p.pitch, p.yaw)]))
        entries[oid] = vis
    manifest = dict(version=1, objects=entries, not_learned=dict(sorted(not_learned.items())),
                    **(info or {}))
    path = folder / MODEL_SET_FILE
    tmp = folder / f".{MODEL_SET_FILE}.tmp"
    tmp.write_text(json.dumps(manifest, indent=1))
    os.replace(tmp, path)
    return path


def read_model_set(directory) -> dict:
    """The manifest of the model set in ``directory``; WorldError (naming the file) when it
    is missing or not one."""
    import json
    path = Path(directory) / MODEL_SET_FILE
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise WorldError(f"{path}: no model set here (no {MODEL_SET_FILE})") from None
    except ValueError as err:
        raise WorldError(f"{path}: not a model set ({err})") from None
    if not isinstance(data, dict) or data.get("version") != 1 or not isinstance(data.get("objects"), dict):
        raise WorldError(f"{path}: not a model set of version 1")
    return data


def apply_model_set(world, directory) -> list[str]:
    """Give every small object of ``world`` that the model set in ``directory`` has learned
    that model in place of its own (in place; the objects' poses stay: the learned meshes
    carry their pose in the object's frame). Returns the ids replaced."""
    folder = Path(directory).resolve()
    data = read_model_set(folder)
    done = []
    for oid, vis in data["objects"].items():
        if oid not in world:
            continue
        visuals = [Visual("mesh", pose=Pose(*v["pose"]), file=str(folder / v["file"]),
                          color=tuple(float(c) for c in v["color"])) for v in vis]
        world.get(oid).model = Model(visuals=visuals)
        done.append(oid)
    return done
