"""A small, fast, deterministic PNG encoder and depth-image encoding.

PNG deflate is zlib-ng's (the ``zlib-ng`` package, in the ``data`` extra) when it is installed,
else the standard library's ``zlib``: at level 1 zlib-ng takes a third of zlib's time for files
~30% larger (``benchmarks/results/cpu-2026-11-28-replicator.md``), and like zlib it gives the
same bytes for the same pixels every time. ``AMBULO_PNG_DEFLATE`` picks one: ``zlib-ng``,
``zlib``, or ``isal`` (ISA-L, faster still, but once in ~60,000 encodes it produced different
bytes for the same pixels (issue #7's measurement), and ambulo promises byte-identical datasets
for a seed, so it is opt-in). The one in use is ``PNG_DEFLATE``, recorded in each dataset. All
release the GIL, so a writer thread overlaps with rendering. Files are written with
``ambulo.utils.atomic``.
"""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np

from ambulo.utils.checks import InvalidValueError

DEFLATES = ("zlib-ng", "zlib", "isal")


def _pick_deflate(wanted: str):
    """(name and version, compress function, zlib-level mapping) of the deflate ``wanted``
    ('' = zlib-ng when installed, else zlib); an unavailable one falls back to zlib."""
    wanted = wanted.lower()
    if wanted not in ("", *DEFLATES):
        raise InvalidValueError("AMBULO_PNG_DEFLATE", wanted, "not a deflate ambulo knows",
                                f"set it to one of {', '.join(DEFLATES)}, or unset it")
    if wanted in ("", "zlib-ng"):
        try:
            from zlib_ng import zlib_ng
        except ImportError:
            pass
        else:
            return f"zlib-ng {zlib_ng.ZLIBNG_VERSION}", zlib_ng.compress, lambda level: level
    if wanted == "isal":
        try:
            from isal import __version__ as isal_version
            from isal import isal_zlib
        except ImportError:
            pass
        else:
            # ISA-L has levels 0-3: zlib's 1-3, 4-6 and 7-9 map to 1, 2 and 3
            return f"isal {isal_version}", isal_zlib.compress, lambda level: min(3, (level + 2) // 3)
    return f"zlib {zlib.ZLIB_RUNTIME_VERSION}", zlib.compress, lambda level: level


# Recorded in metadata: the same frames give other (equally valid) PNG bytes with another deflate.
PNG_DEFLATE, _compress, _level = _pick_deflate(os.environ.get("AMBULO_PNG_DEFLATE", ""))


def _pick_crc32():
    """zlib-ng's CRC-32 when installed (carry-less multiply: ~4x zlib's on a frame's PNG data),
    else zlib's: the same function, so the same chunk checksums whichever deflate is in use."""
    try:
        from zlib_ng import zlib_ng
    except ImportError:
        return zlib.crc32
    return zlib_ng.crc32


_crc32 = _pick_crc32()


def deflate(data, zlib_level: int) -> bytes:
    """zlib-format stream of ``data`` (bytes or a buffer); ``zlib_level`` 0-9 as in ``zlib.compress``.

    Level 0 (store) is always zlib's: the others' level 0 may still compress.
    """
    if zlib_level == 0:
        return zlib.compress(data, 0)
    return _compress(data, _level(zlib_level))


def _chunk(kind: bytes, data: bytes) -> bytes:
    crc = _crc32(data, _crc32(kind))  # chained: no copy of kind + data
    return b"".join((struct.pack(">I", len(data)), kind, data, struct.pack(">I", crc & 0xFFFFFFFF)))


def encode_png(image: np.ndarray, compress_level: int = 1) -> bytes:
    """PNG bytes of (H, W) grey or (H, W, 3|4) colour, uint8 or uint16.

    Rows use the "Up" filter (difference to the row above), computed with
    NumPy; it compresses rendered images and depth far better than no filter
    at the same level. The bytes are a pure function of the image, the level
    and ``PNG_DEFLATE``. A big-endian uint16 image (``>u2``, PNG's order) is
    used as it is, without the byte-swapped copy a native one needs.
    """
    if image.dtype.kind != "u" or image.dtype.itemsize not in (1, 2):
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


def depth_to_mm_u16(depth_m: np.ndarray, byteorder: str = "=") -> np.ndarray:
    """Depth (m) as uint16 millimetres; 0 marks no return or beyond 65.535 m (the usual convention).

    ``byteorder`` '>' gives big-endian uint16, what ``encode_png`` writes, in the same pass."""
    mm = np.multiply(depth_m, 1000.0)  # in the input's precision, as numbers times a Python float are
    np.rint(mm, out=mm)
    # 0 outside [0, 65535], NaN and +-inf (no return) included; one mask, written in place
    bad = mm <= 65535
    bad &= mm >= 0
    np.logical_not(bad, out=bad)
    np.copyto(mm, 0, where=bad)
    return mm.astype(np.dtype(np.uint16).newbyteorder(byteorder))
