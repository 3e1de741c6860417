"""``io.encode_depth_png`` and ``io.encode_ids_png`` (numba's one pass over the pixels) write the bytes of
``encode_png`` of ``depth_to_mm_u16``'s millimetres and of the ids as big-endian uint16."""

import numpy as np
import pytest

from ambulo.replicator import io

needs_numba = pytest.mark.skipif(not io.HAVE_NUMBA, reason="numba is not installed (the data extra)")


def awkward_depth(dtype) -> np.ndarray:
    """(37, 41) depth (m) with every case the millimetres treat apart: no return (NaN, +-inf), behind the
    camera (negative, -0), beyond 65.535 m, exact halves of a millimetre (rounded to even), 65535.5 mm."""
    rng = np.random.default_rng(7)
    depth = (rng.random((37, 41)) * 80 - 5).astype(dtype)
    flat = depth.reshape(-1)
    flat[::7], flat[3::11], flat[5::13], flat[1::17] = np.nan, np.inf, -np.inf, -0.0
    flat[2::19] = (rng.integers(0, 65536, flat[2::19].size) + 0.5) / 1000
    flat[4::23], flat[6::29] = 65.5355, 65.535
    return depth


@needs_numba
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_depth_png_is_encode_png_of_the_millimetres(dtype):
    depth = awkward_depth(dtype)
    want = io.encode_png(io.depth_to_mm_u16(depth, ">"), 1, "sub")
    assert io.encode_depth_png(depth, 1) == want
    one_column = np.ascontiguousarray(depth[:, :1])
    assert io.encode_depth_png(one_column, 1) == io.encode_png(io.depth_to_mm_u16(one_column, ">"), 1, "sub")


@needs_numba
@pytest.mark.parametrize("dtype", [np.int32, np.uint16, np.int64])
def test_ids_png_is_encode_png_of_big_endian_ids(dtype):
    ids = np.random.default_rng(3).integers(0, 65536, (23, 31)).astype(dtype)
    assert io.encode_ids_png(ids, 1) == io.encode_png(ids.astype(">u2"), 1, "none")


def test_without_numba_the_numpy_path_writes_them(monkeypatch):
    monkeypatch.setattr(io, "HAVE_NUMBA", False)
    depth = awkward_depth(np.float32)
    assert io.encode_depth_png(depth, 1) == io.encode_png(io.depth_to_mm_u16(depth, ">"), 1, "sub")
