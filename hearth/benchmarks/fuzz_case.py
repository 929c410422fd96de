"""A fuzz case and its verdict (hearth/benchmarks/fuzz.py): the loaders, the classes of hostile
input, the failures counted, ``Case``, ``Verdict`` and ``materialise`` (a case as files in a
folder)."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional


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
