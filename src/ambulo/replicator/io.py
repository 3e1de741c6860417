"""A small, fast, deterministic PNG encoder and depth-image encoding.

PNG deflate is ``zlib`` by default. ISA-L (the ``isal`` package, ~4x faster at the same
size) is used when ``AMBULO_PNG_DEFLATE=isal`` is set and it is installed: once in ~60,000
encodes it produced different bytes for the same pixels (issue #7's measurement), and
ambulo promises byte-identical datasets for a seed, so speed is opt-in. Both release the
GIL, so a writer thread overlaps with rendering. Files are written with
``ambulo.utils.atomic``.
"""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np

_isal_zlib = None
if os.environ.get("AMBULO_PNG_DEFLATE", "zlib").lower() == "isal":
    try:
        from isal import __version__ as _isal_version
        from isal import isal_zlib as _isal_zlib
    except ImportError:
        pass

# Recorded in metadata: the same frames give other (equally valid) PNG bytes with the other deflate.
PNG_DEFLATE = f"isal {_isal_version}" if _isal_zlib is not None else f"zlib {zlib.ZLIB_RUNTIME_VERSION}"


def deflate(data: bytes, zlib_level: int) -> bytes:
    """zlib-format stream of ``data``; ``zlib_level`` 0-9 as in ``zlib.compress``.

    ISA-L has levels 0-3: zlib's 1-3, 4-6 and 7-9 map to 1, 2 and 3. Level 0
    (store) stays zlib's, since ISA-L's level 0 still compresses.
    """
    if _isal_zlib is None or zlib_level == 0:
        return zlib.compress(data, zlib_level)
    return _isal_zlib.compress(data, min(3, (zlib_level + 2) // 3))


def _chunk(kind: bytes, data: bytes) -> bytes:
    crc = zlib.crc32(data, zlib.crc32(kind))  # chained: no copy of kind + data
    return b"".join((struct.pack(">I", len(data)), kind, data, struct.pack(">I", crc & 0xFFFFFFFF)))


def encode_png(image: np.ndarray, compress_level: int = 1) -> bytes:
    """PNG bytes of (H, W) grey or (H, W, 3|4) colour, uint8 or uint16.

    Rows use the "Up" filter (difference to the row above), computed with
    NumPy; it compresses rendered images and depth far better than no filter
    at the same level. The bytes are a pure function of the image, the level
    and ``PNG_DEFLATE``.
    """
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"encode_png needs uint8 or uint16, got {image.dtype}")
    h, w = image.shape[:2]
    channels = 1 if image.ndim == 2 else image.shape[2]
    color_type = {1: 0, 3: 2, 4: 6}[channels]
    bit_depth = 8 * image.dtype.itemsize
    rows = np.ascontiguousarray(image, dtype=image.dtype.newbyteorder(">")).view(np.uint8).reshape(h, -1)
    filtered = np.empty((h, rows.shape[1] + 1), np.uint8)
    filtered[:, 0] = 2  # filter type Up
    filtered[0, 1:] = rows[0]
    np.subtract(rows[1:], rows[:-1], out=filtered[1:, 1:])
    header = struct.pack(">IIBBBBB", w, h, bit_depth, color_type, 0, 0, 0)
    return b"".join([
        b"\x89PNG\r\n\x1a\n", _chunk(b"IHDR", header),
        _chunk(b"IDAT", deflate(filtered.data, compress_level)), _chunk(b"IEND", b""),
    ])


def depth_to_mm_u16(depth_m: np.ndarray) -> np.ndarray:
    """Depth (m) as uint16 millimetres; 0 marks no return or beyond 65.535 m (the usual convention)."""
    mm = np.rint(np.where(np.isfinite(depth_m), depth_m, 0.0) * 1000.0)
    mm[(mm > 65535) | (mm < 0)] = 0
    return mm.astype(np.uint16)
