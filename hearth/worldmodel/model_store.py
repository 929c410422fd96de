"""Trained models on disk, one file per model and home, each with what it was trained from.

The one place where perception's fitted estimators become files (hearth/perception/ only gets and
returns objects). A model is asked for by ``name`` ("knobs", "segmentation"), by the
``world`` it was trained for and by its training ``config``:

- ``world`` is a JSON-able description of what of a home the training depends on (the knob
  models: the knobs' designs, sizes, states and the appliances that carry them; see
  ``hearth.perception.knob_training.world_signature``), or None for a model that does not depend on
  the home (the segmentation forest is trained on random rooms). Its fingerprint is part of
  the file name, ``<name>-<world fingerprint>.joblib`` (``<name>.joblib`` without a world), so
  models of different homes live side by side: training for home B leaves home A's model
  current.
- ``config`` is everything else the training depended on (training settings, the reader's
  trained settings, a code version). A file for the right home trained with another
  configuration is *stale*: ``load`` says which settings changed, and the caller retrains or
  reports it.

A file is a joblib dump of a dict: ``format`` (``FORMAT``), ``model`` (the object), ``config``,
``world`` (the signature), ``fingerprint`` (of config and world together), ``about`` (what a
person wants to know: the world's id and file) and ``saved_at`` (Unix time). Files are
written with the world model's ``atomic_write`` (a unique temporary file in the same
directory, fsync, rename, fsync of the directory), so two processes training the same model
never see half a file and never write over each other's temporary file.

The directory is ``$HEARTH_MODEL_DIR``, else ``~/.cache/hearth``.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional

FORMAT = 2


def model_dir() -> Path:
    return Path(os.environ.get("HEARTH_MODEL_DIR", Path.home() / ".cache" / "hearth"))


def fingerprint(value: Any) -> str:
    """The first 16 hex digits of the SHA-256 of ``value`` as sorted JSON."""
    text = json.dumps(value, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def path_of(name: str, world: Optional[dict] = None, directory: Optional[Path] = None) -> Path:
    """Where the model ``name`` for ``world`` (a signature; None: any home) is stored."""
    base = Path(directory) if directory is not None else model_dir()
    return base / (f"{name}.joblib" if world is None else f"{name}-{fingerprint(world)}.joblib")


def _flat(d: Any, prefix: str = "") -> dict:
    """Nested dicts as one level of dotted keys (lists stay values)."""
    if not isinstance(d, dict):
        return {prefix: d}
    out: dict = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out


def changed_settings(old: dict, new: dict) -> list[str]:
    """Dotted names of the settings that differ between two configurations."""
    a, b = _flat(old), _flat(new)
    return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))


@dataclass
class Loaded:
    """``model`` is None unless the file exists and matches; ``reason`` says why not
    ("missing", "unreadable: ...", "stale: trained with other ...")."""
    model: Any
    path: Path
    reason: str = ""
    config: Optional[dict] = None
    about: Optional[dict] = None

    @property
    def ok(self) -> bool:
        return self.model is not None


def _blob_fingerprint(config: dict, world: Optional[dict]) -> str:
    return fingerprint({"config": config, "world": world})


def save(name: str, model: Any, config: dict, world: Optional[dict] = None,
         directory: Optional[Path] = None, about: Optional[dict] = None) -> Path:
    """Store ``model`` (atomically) and return its path."""
    import joblib

    from hearth.worldmodel.io import atomic_write
    path = path_of(name, world, directory)
    buf = io.BytesIO()
    joblib.dump({"format": FORMAT, "fingerprint": _blob_fingerprint(config, world),
                 "config": config, "world": world, "about": dict(about or {}),
                 "saved_at": time.time(), "model": model}, buf, compress=3)
    atomic_write(path, buf.getvalue())
    _MEMORY[(str(path), _blob_fingerprint(config, world))] = model
    return path


def load(name: str, config: dict, world: Optional[dict] = None,
         directory: Optional[Path] = None) -> Loaded:
    """The stored model for ``world`` if it was trained with ``config``."""
    import joblib
    path = path_of(name, world, directory)
    if not path.exists():
        return Loaded(None, path, "missing")
    try:
        blob = joblib.load(path)
    except Exception as err:  # a truncated or foreign file is as good as none
        return Loaded(None, path, f"unreadable: {type(err).__name__}")
    if not isinstance(blob, dict) or blob.get("format") != FORMAT:
        return Loaded(None, path, "unreadable: not a hearth model file of this version")
    if blob.get("fingerprint") != _blob_fingerprint(config, world):
        old = blob.get("config") or {}
        what = changed_settings(old, config)
        if blob.get("world") != world:
            what.append("home")
        return Loaded(None, path, f"stale: trained with other {', '.join(what) or 'settings'}",
                      old, blob.get("about"))
    return Loaded(blob["model"], path, "", blob.get("config"), blob.get("about"))


#: Models loaded or trained in this process, by (path, fingerprint).
_MEMORY: dict = {}


@dataclass
class ModelInfo:
    """Where a model came from: ``source`` "memory", "disk" or "trained"; ``seconds`` of
    training; ``reason`` why it was trained (the stored one was missing or stale, "forced")."""
    path: Path
    source: str
    seconds: float = 0.0
    reason: str = ""


class ModelUnavailable(Exception):
    """No current model is stored and training was not allowed; ``loaded`` says why."""

    def __init__(self, loaded: Loaded):
        super().__init__(f"{loaded.reason} ({loaded.path})")
        self.loaded = loaded


def load_or_train(name: str, config: dict, train: Callable[[], Any], world: Optional[dict] = None,
                  directory: Optional[Path] = None, retrain: bool = True, force: bool = False,
                  about: Optional[dict] = None) -> tuple[Any, ModelInfo]:
    """The model from memory, from disk, or from ``train()`` (then stored). ``retrain=False``:
    a missing or stale model raises ``ModelUnavailable``; ``force``: train whatever is stored.
    A model directory that cannot be written keeps the trained model in memory only."""
    path = path_of(name, world, directory)
    key = (str(path), _blob_fingerprint(config, world))
    if not force and key in _MEMORY:
        return _MEMORY[key], ModelInfo(path, "memory")
    loaded = load(name, config, world, directory)
    if loaded.ok and not force:
        _MEMORY[key] = loaded.model
        return loaded.model, ModelInfo(path, "disk")
    if not retrain and not force:
        raise ModelUnavailable(loaded)
    t0 = time.perf_counter()
    model = train()
    seconds = time.perf_counter() - t0
    try:
        save(name, model, config, world, directory, about)
    except OSError:
        _MEMORY[key] = model   # read-only model directory
    return model, ModelInfo(path, "trained", seconds, "forced" if force else loaded.reason)


def forget() -> None:
    """Drop the models held in memory (the files stay)."""
    _MEMORY.clear()
