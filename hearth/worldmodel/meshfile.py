"""What a mesh or point-cloud file a world names may hold, checked before open3d reads it.

``hearth.worldmodel.validate.asset_problem`` has made sure the path stays in the world's folder and
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

then the vertices (or points) are read here, with numpy, and must all be finite; a body
shorter than its header declares is refused. (Reading them with open3d instead printed
RPly's complaints on stderr, a second line, and stopped at the first "inf".) The answer is
cached per file version (device, inode, size, modification time), so a world is not re-read
on every save.
"""
from __future__ import annotations

import os
import re
from functools import lru_cache
from typing import Callable, Optional

import numpy as np

from hearth.util.errors import HearthError
from hearth.util.files import file_inside, read_limited

MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off")
TEXTURE_SUFFIXES = (".png", ".jpg", ".jpeg")
CLOUD_SUFFIXES = (".ply", ".pcd")
#: One mesh or point-cloud file, in bytes (a generated home's largest mesh is ~100 kB).
MAX_ASSET_BYTES = 64 << 20
#: Vertices, faces and points a file may declare (each element of a PLY counts).
MAX_ASSET_ELEMENTS = 4_000_000
#: A header is read from this many first bytes.
_HEAD_BYTES = 64 << 10
#: PLY scalar types -> numpy (the last character is the size in bytes).
_PLY_TYPES = {"char": "i1", "uchar": "u1", "int8": "i1", "uint8": "u1", "short": "i2",
              "ushort": "u2", "int16": "i2", "uint16": "u2", "int": "i4", "uint": "u4",
              "int32": "i4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


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
    xyz = {".ply": _ply, ".obj": _obj, ".stl": _stl, ".off": _off, ".pcd": _pcd}[suffix](
        data, full, base)
    bad = int((~np.isfinite(xyz)).any(axis=1).sum()) if xyz.size else 0
    if bad:
        raise _Refused(f"has {bad} vertices that are not finite (nan or inf)")


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


def _numbers(rows: list[list[bytes]], what: str) -> np.ndarray:
    """(n, 3) floats from rows of at least three words (the first three taken)."""
    if any(len(r) < 3 for r in rows):
        raise _Refused(f"has a {what} with fewer than three numbers")
    try:
        return np.array([r[:3] for r in rows], dtype=float).reshape(-1, 3)
    except ValueError:
        raise _Refused(f"has a {what} that is not three numbers") from None


def _text_lines(data: bytes) -> list[bytes]:
    """Non-empty lines, comments (#) dropped."""
    return [l for l in (raw.strip() for raw in data.splitlines()) if l and not l.startswith(b"#")]


def _ply(data: bytes, full: str, base: str) -> np.ndarray:
    if not data.startswith(b"ply"):
        raise _Refused("is not a PLY file (it does not start with 'ply')")
    lines, start = _header_lines(data, lambda l: l == "end_header", "PLY")
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, Optional[str]]]]] = []
    for line in lines[1:-1]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            elements.append((words[1], _count(words[2], f"element {words[1]}"), []))
        elif words[0] == "property" and elements and len(words) >= 3:
            if words[1] == "list":
                elements[-1][2].append((words[-1], None))
            elif words[1] in _PLY_TYPES:
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
            else:
                raise _Refused(f"has a PLY property of unknown type {words[1][:20]!r}")
        else:
            raise _Refused(f"has a PLY header line Hearth does not read: {line[:40]!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise _Refused(f"has no PLY format Hearth reads (format {fmt!r})")
    room = len(data) - start
    for name, count, props in elements:
        # an ascii row is at least one digit and a separator; a binary row its scalars' bytes
        row = 2 if fmt == "ascii" else max(1, sum(int(t[-1]) for _, t in props if t))
        _bound(count, f"{name} elements", room, row)
    total = sum(e[1] for e in elements)
    if total > MAX_ASSET_ELEMENTS:
        raise _Refused(f"declares {total} PLY elements (at most {MAX_ASSET_ELEMENTS})")
    index = next((i for i, e in enumerate(elements) if e[0] == "vertex"), None)
    if index is None:
        return np.zeros((0, 3))
    _, n, props = elements[index]
    names = [p for p, _ in props]
    if not {"x", "y", "z"} <= set(names) or any(t is None for _, t in props):
        raise _Refused("has a PLY vertex element without scalar x, y, z properties")
    cols = [names.index(c) for c in ("x", "y", "z")]
    if fmt == "ascii":
        body = data[start:].splitlines()
        skip = sum(e[1] for e in elements[:index])
        rows = [r.split() for r in body[skip:skip + n]]
        if len(rows) < n or any(len(r) < len(props) for r in rows):
            raise _Refused("is a truncated PLY file (fewer vertex values than its header "
                           "declares)")
        return _numbers([[r[c] for c in cols] for r in rows], "PLY vertex")
    if any(t is None for e in elements[:index] for _, t in e[2]):
        raise _Refused("has a PLY list element before its vertices (Hearth reads PLY files "
                       "whose vertices come before any list)")
    order = "<" if fmt == "binary_little_endian" else ">"
    offset = start + sum(e[1] * sum(int(t[-1]) for _, t in e[2]) for e in elements[:index])
    dtype = np.dtype([(f"p{i}", order + t) for i, (_, t) in enumerate(props)])
    if offset + n * dtype.itemsize > len(data):
        raise _Refused("is a truncated PLY file (fewer vertex bytes than its header declares)")
    rows = np.frombuffer(data, dtype, count=n, offset=offset)
    return np.stack([rows[f"p{c}"].astype(float) for c in cols], axis=1)


def _resolve_inside(ref: str, folder: str, base: str, what: str) -> str:
    """The path ``ref`` names relative to ``folder``; refused unless it stays in ``base``
    (symbolic links followed) and names a regular file (``hearth.util.files.file_inside``)."""
    full, why = file_inside(base, ref, start=folder)
    if why is None:
        return full
    said = {"not relative": "is not a path relative to the world file's folder",
            "leaves": "leaves the world file's folder",
            "leaves through a link": "leaves the world file's folder",
            "missing": "is not in the world file's folder",
            "not regular": "is not a regular file"}.get(why, "cannot be read")
    raise _Refused(f"names {what} {ref[:60]!r}, which {said}")


#: Keywords of a .mtl line whose last word is a texture file (what tinyobjloader reads).
_TEXTURE = re.compile(r"(?:map_\w+|bump|disp|decal|refl|norm)\Z", re.IGNORECASE)


def _obj(data: bytes, full: str, base: str) -> np.ndarray:
    folder = os.path.dirname(full)
    rows = []
    for line in _text_lines(data):
        if line.startswith(b"v "):
            rows.append(line.split()[1:])
            if len(rows) > MAX_ASSET_ELEMENTS:
                raise _Refused(f"has more than {MAX_ASSET_ELEMENTS} vertices")
        elif line.startswith(b"mtllib"):
            for ref in line.decode("utf-8", "replace").split()[1:]:
                mtl = _resolve_inside(ref, folder, base, "the material library")
                _mtl(mtl, base)
    return _numbers(rows, "vertex (v)")


def _mtl(path: str, base: str) -> None:
    folder = os.path.dirname(path)
    name = os.path.basename(path)
    for raw in _read(path, f"its material library {name!r}").splitlines():
        words = raw.decode("utf-8", "replace").split()
        if len(words) >= 2 and _TEXTURE.match(words[0]):
            _resolve_inside(words[-1], folder, base, f"(in {name[:40]}) the texture")
            if not words[-1].lower().endswith(TEXTURE_SUFFIXES):
                raise _Refused(f"names (in {name[:40]}) the texture {words[-1][:60]!r}, which "
                               f"is not an image open3d reads ({', '.join(TEXTURE_SUFFIXES)})")


def _stl(data: bytes, full: str, base: str) -> np.ndarray:
    if len(data) >= 84:
        n = int.from_bytes(data[80:84], "little")
        if 84 + 50 * n == len(data):            # binary: the size says it
            _bound(n, "triangles", len(data) - 84, 50)
            tri = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
            return np.frombuffer(data, tri, count=n, offset=84)["v"].reshape(-1, 3).astype(float)
    if data.lstrip()[:5].lower() != b"solid":
        raise _Refused("is not an STL file (neither binary of its declared size nor ASCII)")
    rows = [l.split()[1:] for l in _text_lines(data) if l.startswith(b"vertex")]
    if len(rows) > MAX_ASSET_ELEMENTS:
        raise _Refused(f"has more than {MAX_ASSET_ELEMENTS} vertices")
    return _numbers(rows, "vertex")


def _off(data: bytes, full: str, base: str) -> np.ndarray:
    lines = _text_lines(data)
    if not lines or not lines[0].startswith(b"OFF"):
        raise _Refused("is not an OFF file (it does not start with 'OFF')")
    counts, body = (lines[0][3:].split(), lines[1:]) if lines[0][3:].split() else \
        ((lines[1].split() if len(lines) > 1 else []), lines[2:])
    if len(counts) < 2:
        raise _Refused("is not an OFF file (no vertex and face counts)")
    nv = _count(counts[0].decode("ascii", "replace"), "vertices")
    nf = _count(counts[1].decode("ascii", "replace"), "faces")
    _bound(nv + nf, "vertices and faces", len(data), 2)
    if len(body) < nv:
        raise _Refused("is a truncated OFF file (fewer vertices than its header declares)")
    return _numbers([l.split() for l in body[:nv]], "vertex")


_PCD_TYPES = {("F", "4"): "f4", ("F", "8"): "f8", ("I", "1"): "i1", ("I", "2"): "i2",
              ("I", "4"): "i4", ("I", "8"): "i8", ("U", "1"): "u1", ("U", "2"): "u2",
              ("U", "4"): "u4", ("U", "8"): "u8"}


def _pcd(data: bytes, full: str, base: str) -> np.ndarray:
    lines, start = _header_lines(data, lambda l: l.upper().startswith("DATA"), "PCD")
    fields = {l.split()[0].upper(): l.split()[1:] for l in lines
              if l.split() and not l.startswith("#")}
    points = _count((fields.get("POINTS") or ["?"])[0], "points")
    mode = (fields.get("DATA") or ["?"])[0].lower()
    names = fields.get("FIELDS", [])
    sizes, types = fields.get("SIZE", []), fields.get("TYPE", [])
    counts = fields.get("COUNT", ["1"] * len(names))
    if not {"x", "y", "z"} <= set(names) or not len(names) == len(sizes) == len(types) == \
            len(counts) or any(c != "1" for c in counts):
        raise _Refused("has a PCD header without x, y, z fields of one value each")
    if mode not in ("ascii", "binary"):
        raise _Refused(f"has PCD data {mode!r}; Hearth reads ascii and binary")
    cols = [names.index(c) for c in ("x", "y", "z")]
    if mode == "ascii":
        _bound(points, "points", len(data) - start, 2)
        rows = [l.split() for l in _text_lines(data[start:])[:points]]
        if len(rows) < points:
            raise _Refused("is a truncated PCD file (fewer points than its header declares)")
        return _numbers([[r[c] for c in cols] if len(r) == len(names) else [] for r in rows],
                        "point")
    try:
        dtype = np.dtype([(f"p{i}", "<" + _PCD_TYPES[(t.upper(), s)])
                          for i, (t, s) in enumerate(zip(types, sizes))])
    except KeyError:
        raise _Refused("has a PCD field TYPE and SIZE Hearth does not read") from None
    _bound(points, "points", len(data) - start, dtype.itemsize)
    rows = np.frombuffer(data, dtype, count=points, offset=start)
    return np.stack([rows[f"p{c}"].astype(float) for c in cols], axis=1)
