"""The first thing a Ray task of a shipped suite runs (``RayEngine(ship_code=True)``).

Ray accepts a local folder of code (``py_modules``) only for a whole job, at ``ray.init``; a
suite that joins an instance someone else started cannot ship its code that way. So the
submitter zips Hearth's packages into the object store and each task starts here: this module
imports only the standard library (it travels by value, ``register_pickle_by_value``), unpacks
the zip once per worker into ``$TMPDIR/hearth-code-<fingerprint>``, puts it first on
``sys.path`` (dropping Hearth modules a worker imported from elsewhere), and only then
unpickles the call (its case, runner, model need), so that every Hearth class in it comes from
the shipped code. Written by hand: Ray has no public API for this.
"""
from __future__ import annotations

import io
import os
import pickle
import shutil
import sys
import tempfile
import zipfile

PACKAGES = ("hearth",)


def unpack_code(fingerprint: str, code_zip: bytes) -> str:
    """The folder holding the shipped packages (unpacked on first use, atomically)."""
    root = os.path.join(tempfile.gettempdir(), f"hearth-code-{fingerprint}")
    if not os.path.isdir(root):
        tmp = tempfile.mkdtemp(prefix=f"hearth-code-{fingerprint}.part-")
        with zipfile.ZipFile(io.BytesIO(code_zip)) as z:
            z.extractall(tmp)
        try:
            os.rename(tmp, root)
        except OSError:              # another worker of this node got there first
            shutil.rmtree(tmp, ignore_errors=True)
    return root


def use_code(root: str) -> None:
    """Import Hearth from ``root`` from now on in this process."""
    for name in list(sys.modules):
        mod = sys.modules[name]
        if name.split(".")[0] in PACKAGES:
            f = getattr(mod, "__file__", None) or ""
            if not f.startswith(root + os.sep):
                del sys.modules[name]
    if not sys.path or sys.path[0] != root:
        sys.path.insert(0, root)


def boot(fingerprint: str, code_zip: bytes, call: bytes, *args):   # pragma: no cover - Ray
    """Run ``function(*call_args, *args)`` from the shipped code; ``call`` is the pickled
    ``(function, call_args)``. A module-level function pickles by reference (its module and
    name), so unpickling it here, after ``use_code``, imports it from the shipped code: this
    module needs to know nothing of the suite it boots."""
    use_code(unpack_code(fingerprint, code_zip))
    function, call_args = pickle.loads(call)
    return function(*call_args, *args)
