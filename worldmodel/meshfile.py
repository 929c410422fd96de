"""What a mesh or point-cloud file a world names may hold, checked before open3d reads it.

``worldmodel.validate.asset_problem`` has made sure the path stays in the world's folder and
names a regular file; this module looks inside (issue 44): open3d allocates what a header
claims (a PLY of "2e9 vertices" in a few bytes ended in ``std::bad_alloc``), follows the
material library an ``.obj`` names wherever it points (``mtllib ../../../etc/passwd``, or a
FIFO in the folder, where drawing the scene blocked for ever) and the textures that library
names, and reads ``nan`` and ``inf`` vertices as they are. So, before open3d is called:

- the file is one of the formats listed in ``MESH_SUFFIXES`` / ``CLOUD_SUFFIXES`` (glTF and
  FBX name external buffers and images, which this check does not follow: refused), of at
  most ``MAX_ASSET_BYTES``, read without blocking;
- the counts its header gives (PLY elements, OFF, binary STL, PCD points) are bounded by
  ``MAX_ASSET_ELEMENTS`` and by what the file's size can hold;
- every file an ``.obj`` names (``mtllib``) and every texture its ``.mtl`` names is resolved
  as the world's own mesh paths are: inside the world's folder, a regular file;

then open3d reads it (its own warnings silenced: the problem is said in one line here) and
every vertex or point must be finite. The answer is cached per file version (device, inode,
size, modification time), so a world is not re-read on every save.
"""
from __future__ import annotations

import os
import re
import stat
from functools import lru_cache
from typing import Callable, Optional

from hearth.errors import HearthError
from hearth.files import read_limited

MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off")
CLOUD_SUFFIXES = (".ply", ".pcd")
#: One mesh or point-cloud file, in bytes (a generated home's largest mesh is ~100 kB).
MAX_ASSET_BYTES = 64 << 20
#: Vertices, faces and points a file may declare (each element of a PLY counts).
MAX_ASSET_ELEMENTS = 4_000_000
#: A header is read from this many first bytes.
_HEAD_BYTES = 64 << 10
_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2,
              "int16": 2, "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4,
              "float": 4, "float32": 4, "double": 8, "float64": 8}


class _Refused(HearthError):
    """Why a file may not be used (internal: turned into the caller's message)."""


def content_problem(full: str, base: str, kind: str = "mesh") -> Optional[str]:
    """Why the regular file ``full`` (inside the world folder ``base``) may not be read as a
    ``kind`` ("mesh" or "pointcloud"); None when it may."""
    try:
        st = os.stat(full)
    except OSError as err:
        return f"cannot be read ({err.strerror})"
    return _cached(full, base, kind, st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


@lru_cache(maxsize=1024)
def _cached(full: str, base: str, kind: str, *version) -> Optional[str]:
    try:
        _check(full, base, kind)
    except _Refused as err:
        return err.message
    return None


def _read(path: str, what: str = "the file") -> bytes:
    return read_limited(path, MAX_ASSET_BYTES, _Refused,
                        f"{what} is larger than {MAX_ASSET_BYTES >> 20} MiB")


def _check(full: str, base: str, kind: str) -> None:
    suffix = os.path.splitext(full)[1].lower()
    allowed = MESH_SUFFIXES if kind == "mesh" else CLOUD_SUFFIXES
    if suffix not in allowed:
        raise _Refused(f"is not a {kind} format Hearth reads ({', '.join(allowed)})")
    try:
        data = _read(full)
    except _Refused as err:
        raise _Refused(err.message if err.message.startswith("the file") else
                       f"cannot be read ({err.message})") from None
    declared = {".ply": _ply, ".obj": _obj, ".stl": _stl, ".off": _off, ".pcd": _pcd}[suffix](
        data, full, base)
    _finite(full, kind, declared)


def _bound(count: int, what: str, room: int, per_item: int) -> None:
    """Refuse a declared count beyond MAX_ASSET_ELEMENTS or beyond what ``room`` bytes hold
    at ``per_item`` bytes each at least."""
    if count > MAX_ASSET_ELEMENTS:
        raise _Refused(f"declares {count} {what} (at most {MAX_ASSET_ELEMENTS})")
    if count * per_item > room:
        raise _Refused(f"declares {count} {what}, more than its {room} bytes of data can hold")


def _header_lines(data: bytes, end: Callable[[str], bool], what: str) -> tuple[list[str], int]:
    """The header's lines up to and including the one ``end`` accepts, and where the data
    after it starts."""
    head = data[:_HEAD_BYTES]
    lines, pos = [], 0
    while True:
        nl = head.find(b"\n", pos)
        if nl < 0:
            raise _Refused(f"is not a {what} file (no complete header in its first "
                           f"{_HEAD_BYTES >> 10} KiB)")
        line = head[pos:nl].decode("ascii", "replace").strip()
        lines.append(line)
        pos = nl + 1
        if end(line):
            return lines, pos


def _count(text: str, what: str) -> int:
    if not re.fullmatch(r"[0-9]{1,12}", text):
        raise _Refused(f"has a header count {text[:20]!r} for {what} that is not a whole number")
    return int(text)


def _ply(data: bytes, full: str, base: str) -> int:
    if not data.startswith(b"ply"):
        raise _Refused("is not a PLY file (it does not start with 'ply')")
    lines, start = _header_lines(data, lambda l: l == "end_header", "PLY")
    fmt = None
    elements: list[list] = []        # [name, count, row bytes or None for lists/ascii]
    for line in lines[1:-1]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            elements.append([words[1], _count(words[2], f"element {words[1]}"), 0])
        elif words[0] == "property" and elements and len(words) >= 3:
            if words[1] == "list":
                elements[-1][2] = None
            elif words[1] in _PLY_SIZES and elements[-1][2] is not None:
                elements[-1][2] += _PLY_SIZES[words[1]]
            elif words[1] not in _PLY_SIZES:
                raise _Refused(f"has a PLY property of unknown type {words[1][:20]!r}")
        else:
            raise _Refused(f"has a PLY header line Hearth does not read: {line[:40]!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise _Refused(f"has no PLY format Hearth reads (format {fmt!r})")
    total = sum(e[1] for e in elements)
    room = len(data) - start
    if total > MAX_ASSET_ELEMENTS:
        raise _Refused(f"declares {total} PLY elements (at most {MAX_ASSET_ELEMENTS})")
    for name, count, row in elements:
        # an ascii row is at least one digit and a separator; a list row at least its count
        _bound(count, f"{name} elements", room, 2 if fmt == "ascii" else (row or 1))
    return next((e[1] for e in elements if e[0] == "vertex"), 0)


def _resolve_inside(ref: str, folder: str, base: str, what: str) -> str:
    """The path ``ref`` names relative to ``folder``; refused unless it stays in ``base``
    (symbolic links followed) and names a regular file."""
    if not ref or "\x00" in ref or os.path.isabs(ref) or ref.startswith("~"):
        raise _Refused(f"names {what} {ref[:60]!r}, which is not a path relative to the "
                       f"world file's folder")
    full = os.path.realpath(os.path.join(folder, ref))
    if os.path.commonpath([base, full]) != base:
        raise _Refused(f"names {what} {ref[:60]!r}, which leaves the world file's folder")
    try:
        st = os.stat(full)
    except OSError:
        raise _Refused(f"names {what} {ref[:60]!r}, which is not in the world file's "
                       "folder") from None
    if not stat.S_ISREG(st.st_mode):
        raise _Refused(f"names {what} {ref[:60]!r}, which is not a regular file")
    return full


#: Keywords of a .mtl line whose last word is a texture file (what tinyobjloader reads).
_TEXTURE = re.compile(r"(?:map_\w+|bump|disp|decal|refl|norm)\Z", re.IGNORECASE)


def _obj(data: bytes, full: str, base: str) -> int:
    folder = os.path.dirname(full)
    vertices = 0
    for raw in data.splitlines():
        line = raw.strip()
        if line.startswith(b"v "):
            vertices += 1
        elif line.startswith(b"mtllib"):
            for ref in line.decode("utf-8", "replace").split()[1:]:
                mtl = _resolve_inside(ref, folder, base, "the material library")
                _mtl(mtl, base)
    return vertices


def _mtl(path: str, base: str) -> None:
    folder = os.path.dirname(path)
    name = os.path.basename(path)
    for raw in _read(path, f"its material library {name!r}").splitlines():
        words = raw.decode("utf-8", "replace").split()
        if len(words) >= 2 and _TEXTURE.match(words[0]):
            _resolve_inside(words[-1], folder, base, f"(in {name[:40]}) the texture")


def _stl(data: bytes, full: str, base: str) -> int:
    if len(data) >= 84:
        n = int.from_bytes(data[80:84], "little")
        if 84 + 50 * n == len(data):            # binary: the size says it
            _bound(n, "triangles", len(data) - 84, 50)
            return 3 * n
    if data.lstrip()[:5].lower() != b"solid":
        raise _Refused("is not an STL file (neither binary of its declared size nor ASCII)")
    return data.count(b"vertex")


def _off(data: bytes, full: str, base: str) -> int:
    lines = [l for l in data[:_HEAD_BYTES].decode("ascii", "replace").splitlines()
             if l.strip() and not l.lstrip().startswith("#")]
    if not lines or not lines[0].strip().startswith("OFF"):
        raise _Refused("is not an OFF file (it does not start with 'OFF')")
    rest = lines[0].strip()[3:].split() or (lines[1].split() if len(lines) > 1 else [])
    if len(rest) < 2:
        raise _Refused("is not an OFF file (no vertex and face counts)")
    nv, nf = _count(rest[0], "vertices"), _count(rest[1], "faces")
    _bound(nv + nf, "vertices and faces", len(data), 2)
    return nv


def _pcd(data: bytes, full: str, base: str) -> int:
    lines, start = _header_lines(data, lambda l: l.upper().startswith("DATA"), "PCD")
    fields = {l.split()[0].upper(): l.split()[1:] for l in lines if l.split()}
    points = _count((fields.get("POINTS") or ["?"])[0], "points")
    mode = (fields.get("DATA") or ["?"])[0].lower()
    if mode not in ("ascii", "binary"):
        raise _Refused(f"has PCD data {mode!r}; Hearth reads ascii and binary")
    row = 2
    if mode == "binary":
        try:
            row = sum(int(s) * int(c) for s, c in zip(fields.get("SIZE", []),
                                                       fields.get("COUNT", ["1"] * 64)))
        except ValueError:
            raise _Refused("has a PCD SIZE or COUNT that is not a whole number") from None
    _bound(points, "points", len(data) - start, max(row, 1))
    return points


def _finite(full: str, kind: str, declared: int) -> None:
    import numpy as np
    import open3d as o3d
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        if kind == "mesh":
            xyz = np.asarray(o3d.io.read_triangle_mesh(full).vertices)
        else:
            xyz = np.asarray(o3d.io.read_point_cloud(full).points)
    if declared and not len(xyz):
        raise _Refused(f"does not read as a {kind} (its header declares {declared} "
                       f"{'vertices' if kind == 'mesh' else 'points'}, none could be read)")
    if xyz.size and not np.isfinite(xyz).all():
        raise _Refused(f"has {int((~np.isfinite(xyz)).any(axis=1).sum())} vertices that are "
                       "not finite (nan or inf)")
