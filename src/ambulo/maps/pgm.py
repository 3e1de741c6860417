"""Netpbm grey maps (PGM, ``P5`` binary and ``P2`` plain), what map_saver writes, read and written with
numpy alone (http://netpbm.sourceforge.net/doc/pgm.html): a header of whitespace-separated tokens
``magic width height maxval`` with ``#`` comments, one whitespace byte, then the rows top first
(1 byte per pixel if maxval < 256, else 2 bytes big-endian)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..utils.atomic import atomic_write_bytes
from ..utils.checks import Described, InvalidValueError


def read_pgm(path: str | Path) -> tuple[np.ndarray, float]:
    """((H, W) uint8 or uint16 pixels, top row first; maxval, the value of white)."""
    path = Path(path)
    data = path.read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4 and pos < len(data):
        if data[pos:pos + 1] == b"#":  # a comment runs to the end of its line
            end = data.find(b"\n", pos)
            pos = len(data) if end < 0 else end + 1
        elif data[pos:pos + 1].isspace():
            pos += 1
        else:
            start = pos
            while pos < len(data) and not data[pos:pos + 1].isspace() and data[pos:pos + 1] != b"#":
                pos += 1
            tokens.append(data[start:pos])
    try:
        magic, (width, height, maxval) = tokens[0], (int(t) for t in tokens[1:4])
    except (ValueError, IndexError):
        magic = width = height = maxval = None
    if magic not in (b"P5", b"P2") or not (width and height and maxval) or not 0 < maxval < 65536:
        raise InvalidValueError(f"map image {str(path)!r}", Described("not a PGM"),
                                "expected a P5 or P2 header 'P5 <width> <height> <maxval>'",
                                "save it with map_saver, or as PNG")
    dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
    if magic == b"P5":
        body = data[pos + 1:pos + 1 + width * height * dtype.itemsize]  # one whitespace byte after maxval
        pixels = np.frombuffer(body, dtype) if len(body) == width * height * dtype.itemsize else None
    else:
        values = data[pos:].split()
        pixels = np.array([int(v) for v in values[:width * height]]) if len(values) >= width * height else None
    if pixels is None:
        raise InvalidValueError(f"map image {str(path)!r}", Described("truncated"),
                                f"its header says {width} x {height} pixels, the file holds fewer",
                                "re-save the image")
    return pixels.reshape(height, width).astype(np.uint8 if maxval < 256 else np.uint16), float(maxval)


def write_pgm(path: str | Path, pixels: np.ndarray, *, comment: str = "") -> Path:
    """Write (H, W) uint8 ``pixels`` (top row first) as a binary P5 PGM, maxval 255; atomic."""
    if pixels.ndim != 2 or pixels.dtype != np.uint8:
        raise InvalidValueError("PGM pixels", Described(f"{pixels.dtype} of shape {pixels.shape}"),
                                "expected a 2-D uint8 array", "convert with .astype(np.uint8)")
    header = b"P5\n" + (f"# {comment}\n".encode() if comment else b"")
    header += f"{pixels.shape[1]} {pixels.shape[0]}\n255\n".encode()
    atomic_write_bytes(path, header + np.ascontiguousarray(pixels).tobytes())
    return Path(path)


__all__ = ["read_pgm", "write_pgm"]
