"""Trained models on disk, each with the training configuration it came from.

perception/ only gets and returns estimator objects; this module is where their files live.
A model is stored as one joblib file ``<name>.joblib`` in the model directory
(``$HEARTH_MODEL_DIR``, default ``~/.cache/hearth``) holding a dict: ``model`` (the object),
``config`` (a JSON-able dict: everything the training depended on), ``fingerprint`` (the
first 16 hex digits of the SHA-256 of that config as sorted JSON), ``saved_at`` (Unix time)
and ``format`` (``FORMAT``). A file whose fingerprint differs from the wanted configuration's
is *stale*: ``load`` says so (``Loaded.reason``) and the caller retrains or reports it.
Writes go to a temporary file first and are renamed, so a crash never leaves half a model.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

FORMAT = 1


def model_dir() -> Path:
    return Path(os.environ.get("HEARTH_MODEL_DIR", Path.home() / ".cache" / "hearth"))


def fingerprint(config: dict) -> str:
    text = json.dumps(config, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def path_of(name: str, directory: Optional[Path] = None) -> Path:
    return Path(directory if directory is not None else model_dir()) / f"{name}.joblib"


def save(name: str, model: Any, config: dict, directory: Optional[Path] = None) -> Path:
    import joblib
    path = path_of(name, directory)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    joblib.dump({"format": FORMAT, "fingerprint": fingerprint(config), "config": config,
                 "saved_at": time.time(), "model": model}, tmp, compress=3)
    os.replace(tmp, path)
    return path


@dataclass
class Loaded:
    """``model`` is None unless the file exists and matches; ``reason`` says why not
    ("missing", "unreadable: ...", "stale: ...")."""
    model: Any
    path: Path
    reason: str = ""
    config: Optional[dict] = None

    @property
    def ok(self) -> bool:
        return self.model is not None


def load(name: str, config: dict, directory: Optional[Path] = None) -> Loaded:
    """The stored model if it was trained with ``config``."""
    import joblib
    path = path_of(name, directory)
    if not path.exists():
        return Loaded(None, path, "missing")
    try:
        blob = joblib.load(path)
    except Exception as err:  # a truncated or foreign file is as good as none
        return Loaded(None, path, f"unreadable: {type(err).__name__}")
    if not isinstance(blob, dict) or blob.get("format") != FORMAT:
        return Loaded(None, path, "unreadable: not a hearth model file")
    if blob.get("fingerprint") != fingerprint(config):
        old = blob.get("config") or {}
        changed = sorted(k for k in set(old) | set(config) if old.get(k) != config.get(k))
        return Loaded(None, path, f"stale: trained with other {', '.join(changed) or 'settings'}",
                      old)
    return Loaded(blob["model"], path, "", blob.get("config"))
