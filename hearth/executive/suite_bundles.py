"""Worlds and trained models as bytes, for suite workers that share no disk with the machine
that submits the suite (hearth/executive/suite.py, the ray engine): a world's bundle and its
fingerprint, unpacked and checked where it arrives (``arrived_world``); the models a suite's
missions need (``MISSION_MODELS``), found, trained and kept."""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Optional

from hearth.executive.suite_worker import MISSION_MODELS, SuiteError, _WORKER


# ---------------------------------------------------------------------------------------
# Worlds and models as bytes
# ---------------------------------------------------------------------------------------
WORLD_FILE = "world.xml"


def world_bundle(spec: str) -> dict[str, bytes]:
    """A world (``demo``, ``home:SEED``, a file) as ``{relative path: bytes}``: the world
    file as ``world.xml`` and every mesh and point cloud it refers to. References that lead
    out of the world's folder are copied in and the world is saved again pointing at them
    (``hearth.robot.scenario.copy_world_files``); otherwise the file travels as it is."""
    import tempfile

    from hearth.executive.scenarios import world_path
    from hearth.robot.scenario import copy_world_files
    from hearth.worldmodel.io import load_world, save_world
    path = world_path(spec)
    world = load_world(path)
    with tempfile.TemporaryDirectory(prefix="hearth-bundle-") as tmp:
        d = Path(tmp)
        copy_world_files([world], d)
        if (d / "files").exists():       # something outside the folder: rewritten
            save_world(world, d / WORLD_FILE)
        else:
            (d / WORLD_FILE).write_bytes(path.read_bytes())
        return {p.relative_to(d).as_posix(): p.read_bytes()
                for p in sorted(d.rglob("*")) if p.is_file()}


def bundle_fingerprint(bundle: dict[str, bytes]) -> str:
    h = hashlib.sha256()
    for name in sorted(bundle):
        h.update(name.encode() + b"\0" + hashlib.sha256(bundle[name]).digest())
    return h.hexdigest()[:16]


def unpack_world(bundle: dict[str, bytes], directory: Path) -> Path:
    """Write a bundle into ``directory``; the world file's path."""
    for name, data in bundle.items():
        rel = PurePosixPath(name)
        if rel.is_absolute() or ".." in rel.parts:
            raise SuiteError(f"world bundle: unsafe path {name!r}")
        dst = directory.joinpath(*rel.parts)
        dst.parent.mkdir(parents=True, exist_ok=True)
        _write_atomic(dst, data)
    return directory / WORLD_FILE


def arrived_world(bundle: dict[str, bytes], bundle_fp: str, directory: Path):
    """The world of a bundle as it arrived in a worker, checked: its contents hash to the
    fingerprint the sender computed (``bundle_fingerprint``), it unpacks under
    ``directory/<fingerprint>`` and loads (schema, semantics and every file it refers to:
    ``hearth.worldmodel.io.load_world``). A world loaded once per worker process is reused. Raises
    SuiteError or the world model's errors: the sender loaded the same world before
    bundling it, so any failure here is the transport's."""
    from hearth.worldmodel.io import load_world
    cache = _WORKER.setdefault("worlds", {})
    got = cache.get(bundle_fp)
    if got is not None:
        return load_world(got)
    if bundle_fingerprint(bundle) != bundle_fp:
        raise SuiteError(f"world bundle {bundle_fp}: contents differ from what was sent "
                         f"({len(bundle)} files)")
    world_file = unpack_world(bundle, directory / bundle_fp)
    world = load_world(world_file)
    cache[bundle_fp] = world_file
    return world


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


@dataclass(frozen=True)
class ModelNeed:
    """A trained model the cases need: ``name`` ("knobs", "segmentation") and the world it is
    trained for (None: one for every home)."""
    name: str
    world: Optional[str] = None


def model_needs(cases) -> list[ModelNeed]:
    """The models ``cases`` ask for (``MISSION_MODELS``), each once."""
    out: dict[ModelNeed, None] = {}
    for c in cases:
        for name in MISSION_MODELS.get(c.mission, ()):
            out[ModelNeed(name, c.world if name == "knobs" else None)] = None
    return list(out)


def stored_model(need: ModelNeed) -> Optional[tuple[str, bytes]]:
    """(file name, bytes) of the current stored model, or None when it is missing or stale."""
    loaded = _check_model(need)
    if not loaded.ok:
        return None
    return loaded.path.name, loaded.path.read_bytes()


def _check_model(need: ModelNeed, world=None):
    if need.name == "knobs":
        from hearth.executive.scenarios import resolve_world
        from hearth.skills.knob_models import check
        return check(world if world is not None else resolve_world(need.world))
    from hearth.skills.segmentation_model import check
    return check()


def train_model(need: ModelNeed, world=None) -> tuple[str, bytes]:
    """Train ``need`` in this process into the model store (``$HEARTH_MODEL_DIR``); its file
    (name, bytes)."""
    if need.name == "knobs":
        from hearth.executive.scenarios import resolve_world
        from hearth.skills.knob_models import load_or_train
        _, info = load_or_train(world if world is not None else resolve_world(need.world))
    else:
        from hearth.skills.segmentation_model import get
        _, info = get()
    return info.path.name, Path(info.path).read_bytes()


def keep_model(filename: str, data: bytes) -> Path:
    """Store a model file trained elsewhere in this machine's model store."""
    from hearth.worldmodel.io import atomic_write
    from hearth.worldmodel.model_store import model_dir
    path = model_dir() / filename
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, data)
    return path


def describe_need(need: ModelNeed) -> str:
    return f"knob models for {need.world}" if need.name == "knobs" else "the segmentation forest"
