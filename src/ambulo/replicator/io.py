"""A small, fast PNG encoder and depth-image encoding.

PNG deflate is ISA-L's (the ``isal`` package, in the ``data`` extra) when it is installed, else
zlib-ng's (``zlib-ng``), else the standard library's ``zlib``. On a frame's four images at level 1
ISA-L took 0.57 ms for 47 kB, zlib-ng 0.85 ms for 63 kB and zlib 2.58 ms for 48 kB
(``benchmarks/results/cpu-2026-11-28-replicator.md``). ISA-L once in ~60,000 encodes gave other
(equally valid) bytes for the same pixels (issue #7's measurement): a dataset promises the same
decoded pixels and annotations for a seed, not the same file bytes, so that costs nothing
(``tests/replicator/test_png_format.py`` decodes every deflate and row filter back to the pixels).
``AMBULO_PNG_DEFLATE`` picks one: ``isal``, ``zlib-ng`` or ``zlib``. The one in use is
``PNG_DEFLATE``, recorded in each dataset's metadata. All release the GIL, so a writer thread
overlaps with rendering. Files are written with ``ambulo.utils.atomic``.
"""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np

from ambulo.utils.checks import InvalidValueError
from ambulo.utils.compiled import HAVE_NUMBA, Kernel

DEFLATES = ("isal", "zlib-ng", "zlib")
"""Fastest first: '' (the default) takes the first one installed."""


def _pick_deflate(wanted: str):
    """(name and version, compress function, zlib-level mapping) of the deflate ``wanted``
    ('' = the first of ``DEFLATES`` installed); an unavailable one falls back to zlib."""
    wanted = wanted.lower()
    if wanted not in ("", *DEFLATES):
        raise InvalidValueError("AMBULO_PNG_DEFLATE", wanted, "not a deflate ambulo knows",
                                f"set it to one of {', '.join(DEFLATES)}, or unset it")
    if wanted in ("", "isal"):
        try:
            from isal import __version__ as isal_version
            from isal import isal_zlib
        except ImportError:
            pass
        else:
            # ISA-L has levels 0-3: zlib's 1-3, 4-6 and 7-9 map to 1, 2 and 3
            return f"isal {isal_version}", isal_zlib.compress, lambda level: min(3, (level + 2) // 3)
    if wanted in ("", "zlib-ng"):
        try:
            from zlib_ng import zlib_ng
        except ImportError:
            pass
        else:
            return f"zlib-ng {zlib_ng.ZLIBNG_VERSION}", zlib_ng.compress, lambda level: level
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


ROW_FILTERS = {"none": 0, "sub": 1, "up": 2}
"""PNG's row filters that ``encode_png`` writes (one for every row), by name: their type byte."""


def encode_png(image: np.ndarray, compress_level: int = 1, row_filter: str = "up") -> bytes:
    """PNG bytes of (H, W) grey or (H, W, 3|4) colour, uint8 or uint16.

    ``row_filter`` (``ROW_FILTERS``), computed with NumPy: "up" (difference to the row above) suits
    most images; "sub" (difference to the pixel on the left) depth, whose rows change smoothly
    (at ISA-L level 1: 19 kB and 0.27 ms for a 320x240 depth image, "up" 25 kB and 0.34 ms);
    "none" flat-shaded renders and id images (rendered rgb 17 kB, 0.22 ms; "up" 18 kB, 0.25 ms).
    A decoder gives back the same pixels whichever filter and deflate. A big-endian uint16 image
    (``>u2``, PNG's order) is used as it is, without the byte-swapped copy a native one needs.
    """
    if image.dtype.kind != "u" or image.dtype.itemsize not in (1, 2):
        raise ValueError(f"encode_png needs uint8 or uint16, got {image.dtype}")
    if row_filter not in ROW_FILTERS:
        raise ValueError(f"row_filter must be one of {sorted(ROW_FILTERS)}, got {row_filter!r}")
    h, w = image.shape[:2]
    channels = 1 if image.ndim == 2 else image.shape[2]
    color_type = {1: 0, 3: 2, 4: 6}[channels]
    bit_depth = 8 * image.dtype.itemsize
    rows = np.ascontiguousarray(image, dtype=image.dtype.newbyteorder(">")).view(np.uint8).reshape(h, -1)
    filtered = np.empty((h, rows.shape[1] + 1), np.uint8)
    filtered[:, 0] = ROW_FILTERS[row_filter]
    if row_filter == "up":
        filtered[0, 1:] = rows[0]
        np.subtract(rows[1:], rows[:-1], out=filtered[1:, 1:])
    elif row_filter == "sub":  # bytes minus those one pixel to the left (PNG's "bpp")
        step = channels * image.dtype.itemsize
        filtered[:, 1:1 + step] = rows[:, :step]
        np.subtract(rows[:, step:], rows[:, :-step], out=filtered[:, 1 + step:])
    else:
        filtered[:, 1:] = rows
    return _png_bytes(filtered, w, h, bit_depth, color_type, compress_level)


def _png_bytes(filtered: np.ndarray, w: int, h: int, bit_depth: int, color_type: int, compress_level: int) -> bytes:
    """A PNG of its (H, 1 + row bytes) uint8 ``filtered`` rows (each led by its filter type byte)."""
    header = struct.pack(">IIBBBBB", w, h, bit_depth, color_type, 0, 0, 0)
    return b"".join([
        b"\x89PNG\r\n\x1a\n", _chunk(b"IHDR", header),
        _chunk(b"IDAT", deflate(filtered.data, compress_level)), _chunk(b"IEND", b""),
    ])


def encode_depth_png(depth_m: np.ndarray, compress_level: int = 1) -> bytes:
    """``encode_png(depth_to_mm_u16(depth_m, ">"), compress_level, "sub")``: the same PNG bytes, the
    millimetres and the row filter made in one compiled pass over (H, W) float32/float64 ``depth_m``
    with numba (~6 NumPy passes and two temporary images without it)."""
    if HAVE_NUMBA and depth_m.ndim == 2 and depth_m.dtype in _FLOAT_BITS and depth_m.size:
        h, w = depth_m.shape
        rows = _depth_sub_rows(depth_m, _DEPTH_SCALE[depth_m.dtype])
        return _png_bytes(rows, w, h, 16, 0, compress_level)
    return encode_png(depth_to_mm_u16(depth_m, ">"), compress_level, "sub")


def encode_ids_png(ids: np.ndarray, compress_level: int = 1) -> bytes:
    """``encode_png(ids.astype(">u2"), compress_level, "none")`` of (H, W) integer ``ids`` (instance or
    semantic ids, 0..65535): the same PNG bytes, the big-endian rows written in one compiled pass with
    numba (a cast and a copy without it)."""
    if HAVE_NUMBA and ids.ndim == 2 and ids.dtype.kind in "iu" and ids.size:
        h, w = ids.shape
        return _png_bytes(_u16_none_rows(ids), w, h, 16, 0, compress_level)
    return encode_png(ids.astype(">u2"), compress_level, "none")


def warm_up() -> None:
    """Compile the PNG kernels, or load them from the cache, for a frame's float32 depth and int32 ids
    (``FrameProducer`` calls it while it builds its scene, not in the first frame's writes)."""
    if HAVE_NUMBA:
        encode_depth_png(np.zeros((1, 1), np.float32), 0)
        encode_ids_png(np.zeros((1, 1), np.int32), 0)


def _depth_sub_rows_py(depth_m, scale):
    """(H, 1 + 2 W) uint8: each row's filter byte (1, "sub") and its big-endian uint16 millimetres, each
    byte minus the one a pixel (two bytes) to its left. The millimetres are ``depth_to_mm_u16``'s: the
    product in the depth's precision (``scale``: 1000 and the float's 2^(mantissa bits) in its dtype),
    rounded half to even, 0 outside [0, 65535] and for NaN."""
    h, w = depth_m.shape
    out = np.empty((h, 1 + 2 * w), np.uint8)
    row = np.empty(w + 1, np.int64)  # the row's millimetres after a 0 (the "pixel" left of the first)
    row[0] = 0
    for r in range(h):
        for c in range(w):  # branch-free, so that it vectorizes
            # rounded half to even by adding and taking away 2^23 (float32; 2^52 for float64): exact for
            # 0 <= x < 2^23, and anything else gives 0 anyway; a call of rint would not vectorize
            mm = (depth_m[r, c] * scale[0] + scale[1]) - scale[1]
            row[c + 1] = np.int64(mm) if (mm >= 0) & (mm <= 65535) else 0  # NaN fails both comparisons
        out[r, 0] = 1
        for c in range(w):
            out[r, 1 + 2 * c] = ((row[c + 1] >> 8) - (row[c] >> 8)) & 0xFF
            out[r, 2 + 2 * c] = (row[c + 1] - row[c]) & 0xFF
    return out


def _u16_none_rows_py(ids):
    """(H, 1 + 2 W) uint8: each row's filter byte (0, "none") and its ids as big-endian uint16."""
    h, w = ids.shape
    out = np.empty((h, 1 + 2 * w), np.uint8)
    for r in range(h):
        out[r, 0] = 0
        for c in range(w):
            v = ids[r, c] & 0xFFFF
            out[r, 1 + 2 * c] = v >> 8
            out[r, 2 + 2 * c] = v & 0xFF
    return out


_depth_sub_rows = Kernel(_depth_sub_rows_py)
_DEPTH_SCALE = {np.dtype(np.float32): np.array((1000.0, 2.0 ** 23), np.float32),
                np.dtype(np.float64): np.array((1000.0, 2.0 ** 52), np.float64)}
_u16_none_rows = Kernel(_u16_none_rows_py)


def depth_to_mm_u16(depth_m: np.ndarray, byteorder: str = "=") -> np.ndarray:
    """Depth (m) as uint16 millimetres; 0 marks no return or beyond 65.535 m (the usual convention).

    ``byteorder`` '>' gives big-endian uint16, what ``encode_png`` writes, in the same pass."""
    mm = np.multiply(depth_m, 1000.0)  # in the input's precision, as numbers times a Python float are
    np.rint(mm, out=mm)
    # 0 outside [0, 65535], NaN and +-inf (no return) included, found in one comparison: an IEEE float's
    # bits, read as an unsigned integer, order the floats from +0 up (+inf and NaN above every finite
    # one) and put every negative (sign bit set) above them, so the numbers in [+0, 65535] are exactly
    # the bit patterns <= 65535's (-0 falls out too: it is 0 either way); two comparisons, their
    # conjunction and its negation, four passes over the image, before
    bits = _FLOAT_BITS.get(mm.dtype)
    if bits is not None:
        bad = mm.view(bits[0]) > bits[1]
    else:  # another float type (float16, longdouble): the straightforward mask
        bad = ~((mm >= 0) & (mm <= 65535))
    np.copyto(mm, 0, where=bad)
    return mm.astype(np.dtype(np.uint16).newbyteorder(byteorder))


_FLOAT_BITS = {np.dtype(f): (np.dtype(u), np.array(65535, f).view(u)[()])
               for f, u in ((np.float32, np.uint32), (np.float64, np.uint64))}
"""Float dtype -> (the unsigned integer dtype of its width, 65535.0's bits as that integer): the
native-order floats whose bits ``depth_to_mm_u16`` compares."""
