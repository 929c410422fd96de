"""Frame files of a recording: checked whole before a mission starts, decoded when served.

``check_png(path, ...)`` reads one PNG and proves it decodes: signature, every chunk's CRC,
the header's size, bit depth and colour type, and the image data inflating to exactly the
size the header promises with a valid filter byte on every row. Written by hand (``zlib``
and ``struct``) because OpenCV reports a broken PNG by printing libpng's complaint on stderr
and returning None, which tells the user neither what is wrong nor stays one line; after this
check the decoder cannot fail on the file. ``decode_color`` / ``decode_depth`` decode checked
bytes with OpenCV.

``inside(directory, relative)``: a frame path must name a regular file inside the
recording's folder (no absolute paths, no ``..`` out of it, no symlink out of it, no device).
"""
from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from hearth.util.files import file_inside

SIGNATURE = b"\x89PNG\r\n\x1a\n"
MAX_FRAME_BYTES = 256 << 20          # one frame file; a 4k 16-bit PNG is ~20 MB
#: Pixels of one frame, and the longest side: a 4096 x 4096 colour frame inflates to 50 MB
#: and is checked in about half a second; 16384 x 16384 (the bound before) took minutes to
#: open a recording of a few frames (issue 44).
MAX_FRAME_PIXELS = 4096 * 4096
MAX_IMAGE_SIDE = 8192
_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_KINDS = {0: "grey", 2: "RGB", 3: "palette", 4: "grey+alpha", 6: "RGBA"}
# Adam7 passes: (x start, y start, x step, y step)
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2),
          (0, 1, 1, 2))


class FrameFileError(ValueError):
    """What is wrong with one frame file (the message names no file; the caller does)."""


@dataclass(frozen=True)
class PngInfo:
    width: int
    height: int
    bit_depth: int
    color_type: int

    @property
    def kind(self) -> str:
        return f"{self.bit_depth}-bit {_KINDS.get(self.color_type, '?')}"


def inside(directory: Path, relative: str, limit: int = MAX_FRAME_BYTES,
           what: str = "frame") -> Path:
    """The file ``relative`` names under ``directory``, which must be a regular file inside
    it (symlinks resolved) of at most ``limit`` bytes; FrameFileError otherwise. ``what``
    names the file in messages (a frame; the recording's ``captures.jsonl``...)."""
    if not isinstance(relative, str) or not relative:
        raise FrameFileError(f"{what} path must be a non-empty string")
    if "\x00" in relative:
        raise FrameFileError(f"{what} path {relative[:80]!r} holds a NUL byte")
    if os.path.isabs(relative):
        raise FrameFileError(f"{what} path {relative[:80]!r} is absolute; paths are relative "
                             "to the recording's folder")
    full, why = file_inside(directory, relative)
    if why in ("leaves", "leaves through a link", "not relative"):
        raise FrameFileError(f"{what} path {relative[:80]!r} leaves the recording's folder")
    if why == "missing":
        raise FrameFileError("missing")
    if why == "not regular":
        raise FrameFileError(f"{what} path {relative[:80]!r} is not a regular file")
    try:
        st = os.stat(full)
    except OSError as err:
        raise FrameFileError(f"unreadable ({err.strerror})") from None
    if st.st_size > limit:
        raise FrameFileError(f"{st.st_size} bytes, more than the {limit >> 20} MiB "
                             f"a {what} file may have")
    return Path(full)


def check_png(data: bytes) -> PngInfo:
    """Prove that ``data`` is a complete, uncorrupted PNG; its header fields."""
    if not data.startswith(SIGNATURE):
        raise FrameFileError("not a PNG file" if len(data) >= 8 else "truncated PNG (empty)")
    pos, info, idat, ended = 8, None, [], False
    n = len(data)
    while pos < n:
        if pos + 8 > n:
            raise FrameFileError("truncated PNG (a chunk header is cut off)")
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        end = pos + 12 + length
        if end > n:
            raise FrameFileError(f"truncated PNG (the {kind.decode('latin-1')} chunk is cut off)")
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[end - 4:end])
        if zlib.crc32(body, zlib.crc32(kind)) & 0xFFFFFFFF != crc:
            raise FrameFileError(f"corrupt PNG (CRC mismatch in the {kind.decode('latin-1')} "
                                 "chunk)")
        if info is None:
            if kind != b"IHDR" or length != 13:
                raise FrameFileError("corrupt PNG (no IHDR chunk first)")
            w, h, depth, ctype, comp, filt, interlace = struct.unpack(">IIBBBBB", body)
            if w == 0 or h == 0 or ctype not in _CHANNELS or comp != 0 or filt != 0 \
                    or interlace > 1:
                raise FrameFileError("corrupt PNG (invalid IHDR)")
            info = PngInfo(w, h, depth, ctype)
            if max(w, h) > MAX_IMAGE_SIDE or w * h > MAX_FRAME_PIXELS:
                raise FrameFileError(f"{w}x{h} is too large for a frame (at most "
                                     f"{MAX_FRAME_PIXELS} pixels, sides up to {MAX_IMAGE_SIDE})")
            interlaced = interlace == 1
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            ended = True
            break
        pos = end
    if info is None:
        raise FrameFileError("truncated PNG (no IHDR chunk)")
    if not ended:
        raise FrameFileError("truncated PNG (no IEND chunk)")
    bpp = _CHANNELS[info.color_type] * info.bit_depth           # bits per pixel
    if interlaced:
        passes = [(-(-(info.width - x0) // dx), -(-(info.height - y0) // dy))
                  for x0, y0, dx, dy in _ADAM7]
        passes = [(pw, ph) for pw, ph in passes if pw > 0 and ph > 0]
    else:
        passes = [(info.width, info.height)]
    expected = sum(ph * (1 + (pw * bpp + 7) // 8) for pw, ph in passes)
    if expected > 8 * MAX_FRAME_BYTES:
        raise FrameFileError(f"{info.width}x{info.height} is too large for a frame")
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(b"".join(idat), expected + 1)
    except zlib.error:
        raise FrameFileError("corrupt PNG (the image data does not inflate)") from None
    if len(raw) != expected or not inflater.eof:
        raise FrameFileError(f"corrupt PNG (the image data has {len(raw)} bytes, the header "
                             f"promises {expected})")
    raw_arr = np.frombuffer(raw, dtype=np.uint8)
    start = 0
    for pw, ph in passes:                 # every row starts with its filter type, 0..4
        stride = 1 + (pw * bpp + 7) // 8
        if ph and raw_arr[start:start + ph * stride:stride].max() > 4:
            raise FrameFileError("corrupt PNG (bad row filter)")
        start += ph * stride
    return info


def check_color_png(data: bytes) -> PngInfo:
    info = check_png(data)
    # Three channels (RGB, or a palette of RGB entries): an alpha channel or grey is not
    # what the format says, and OpenCV would silently drop or invent channels.
    if info.color_type not in (2, 3) or (info.color_type == 2 and info.bit_depth != 8):
        raise FrameFileError(f"colour must be an 8-bit 3-channel (RGB) PNG, this one is "
                             f"{info.kind}")
    return info


def check_depth_png(data: bytes) -> PngInfo:
    info = check_png(data)
    if info.bit_depth != 16 or info.color_type != 0:
        raise FrameFileError(f"depth must be a 16-bit single-channel PNG, this one is "
                             f"{info.kind}")
    return info


def decode_color(data: bytes) -> np.ndarray:
    """Checked colour PNG bytes -> uint8 RGB (H, W, 3)."""
    bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise FrameFileError("unreadable colour PNG")
    return np.ascontiguousarray(bgr[..., ::-1])


def decode_depth(data: bytes) -> np.ndarray:
    """Checked depth PNG bytes -> uint16 (H, W)."""
    raw = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
        raise FrameFileError("depth must be a 16-bit single-channel PNG")
    return raw
