"""Keeping the belief map on disk: what a mission learns outlives the process.

``MapKeeper(world, path)`` listens to the map's changes (object moves, door and knob states,
search statistics) and saves the whole map after each one, atomically
(``hearth.worldmodel.io.save_world``: temporary file, fsync, rename), from a writer thread of its
own so a save never stalls a tick. Changes that arrive while a save runs are folded into the
next save. ``close()`` writes what is still pending. A process started on the saved file
starts from what the last one learned.

History is bounded: before a save the map keeps its newest ``max_history`` entries
(``World.compact_history``); the search statistics are counts, so they do not grow.

Where the map lives (``map_path``): the world file given, or ``--map-out PATH`` (read from
there when it exists, so a restarted process carries on), and for the bundled demo home,
whose shipped file is package data and never written, a copy in the state directory
(``$HEARTH_STATE_DIR``, default ``~/.local/share/hearth``).
"""
from __future__ import annotations

import logging
import os
import shutil
import threading
from pathlib import Path
from typing import Optional

log = logging.getLogger("hearth.mapstore")

#: History entries kept with a saved map (the newest).
MAX_HISTORY = 2000


def state_dir() -> Path:
    """Hearth's own state (``$HEARTH_STATE_DIR``, default ``~/.local/share/hearth``)."""
    return Path(os.environ.get("HEARTH_STATE_DIR") or Path.home() / ".local" / "share" / "hearth")


def map_path(world_file, map_out=None) -> Path:
    """The file a run loads its belief map from and keeps it in.

    ``map_out`` wins (created from ``world_file`` on first use); the shipped demo home is
    kept as a copy in the state directory (created on first use); any other world file is
    itself the map."""
    from hearth import demo_world_path
    world_file = Path(world_file)
    if map_out is not None:
        target = Path(map_out)
    elif world_file.resolve() == demo_world_path().resolve():
        target = state_dir() / "demo_home" / "world.xml"
    else:
        return world_file
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        if world_file.resolve() != target.resolve():
            shutil.copyfile(world_file, target)
    return target


class MapKeeper:
    """Save ``world`` to ``path`` after every change (see the module docstring)."""

    def __init__(self, world, path, max_history: int = MAX_HISTORY):
        self.world = world
        self.path = Path(path)
        self.max_history = max_history
        self.saves = 0
        self.error: Optional[str] = None
        self._pending = threading.Event()
        self._dirty = False
        self._stop = False
        self._lock = threading.Lock()
        self._unsubscribe = world.subscribe(self._changed)
        self._thread = threading.Thread(target=self._run, name="hearth-map-keeper", daemon=True)
        self._thread.start()

    def _changed(self, _change) -> None:
        self._dirty = True
        self._pending.set()

    def _run(self) -> None:
        while True:
            self._pending.wait()
            if self._stop and not self._pending.is_set():
                return
            self._pending.clear()
            if self._dirty:
                self._dirty = False
                self.save()
            if self._stop and not self._pending.is_set():
                return

    def save(self) -> None:
        """Write the map now (compacting its history first)."""
        from hearth.worldmodel.io import save_world
        with self._lock:
            try:
                self.world.compact_history(self.max_history)
                save_world(self.world, self.path)
                self.saves += 1
            except Exception as err:  # noqa: BLE001 - a failed save must not stop the robot
                self.error = f"{self.path}: could not save the map: {err}"
                log.error(self.error)

    def close(self) -> None:
        """Stop listening, write what is pending, stop the writer thread."""
        self._unsubscribe()
        self._stop = True
        self._pending.set()
        self._thread.join(timeout=30)

    def __enter__(self) -> "MapKeeper":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
