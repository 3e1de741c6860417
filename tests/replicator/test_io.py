"""The PNG encoder (ISA-L or zlib deflate) and the run-based COCO RLEs agree with the reference readers/encoders."""

import io
import os

import imageio.v3 as iio
import numpy as np
import pytest
from PIL import Image
from pycocotools import mask as mask_utils

from ambulo.replicator import io as rio
from ambulo.replicator.coco import instance_rles


@pytest.fixture(params=["isal", "zlib-ng", "zlib"])
def deflate_kind(request, monkeypatch):
    """Each deflate: ISA-L (the default when installed), zlib-ng and zlib (AMBULO_PNG_DEFLATE=...)."""
    pytest.importorskip({"zlib-ng": "zlib_ng", "zlib": "zlib", "isal": "isal"}[request.param])
    name, compress, level = rio._pick_deflate(request.param)
    assert name.startswith(request.param + " ")
    monkeypatch.setattr(rio, "_compress", compress)
    monkeypatch.setattr(rio, "_level", level)
    return request.param


def test_isal_is_the_default_deflate_when_installed():
    pytest.importorskip("isal")
    assert rio._pick_deflate("")[0].startswith("isal ")
    assert rio._pick_deflate("zlib")[0].startswith("zlib ")
    if not os.environ.get("AMBULO_PNG_DEFLATE"):
        assert rio.PNG_DEFLATE.startswith("isal ")


def test_every_chunk_carries_zlibs_crc32():
    """The chunk checksums come from zlib-ng's CRC-32 when installed: the same function as zlib's."""
    import struct
    import zlib

    png = rio.encode_png(np.random.default_rng(4).integers(0, 2**16, (40, 50), dtype=np.uint16), 1)
    at, kinds = 8, []
    while at < len(png):
        (size,) = struct.unpack(">I", png[at:at + 4])
        kind, data = png[at + 4:at + 8], png[at + 8:at + 8 + size]
        (crc,) = struct.unpack(">I", png[at + 8 + size:at + 12 + size])
        assert crc == zlib.crc32(kind + data), kind
        kinds.append(kind)
        at += 12 + size
    assert kinds == [b"IHDR", b"IDAT", b"IEND"]


def test_an_unknown_deflate_is_refused():
    with pytest.raises(ValueError, match="AMBULO_PNG_DEFLATE"):
        rio._pick_deflate("zstd")


@pytest.mark.parametrize("row_filter", sorted(rio.ROW_FILTERS))
def test_png_round_trips_through_pillow_and_imageio_at_every_level(deflate_kind, row_filter):
    rng = np.random.default_rng(1)
    smooth = np.cumsum(rng.integers(0, 3, (48, 64)), axis=1).astype(np.uint16) * 40  # like depth
    images = [rng.integers(0, 256, (31, 17, 3), dtype=np.uint8), rng.integers(0, 256, (5, 6, 4), dtype=np.uint8),
              rng.integers(0, 256, (9, 1), dtype=np.uint8), smooth, np.zeros((1, 1), np.uint16)]
    for level in range(10):
        for image in images:
            png = rio.encode_png(image, level, row_filter)
            for decoded in (np.asarray(Image.open(io.BytesIO(png))), iio.imread(png, extension=".png")):
                assert decoded.dtype == image.dtype and np.array_equal(decoded, image), (deflate_kind, level)


def test_every_deflate_is_about_the_same_size(deflate_kind):
    data = np.cumsum(np.random.default_rng(0).integers(0, 4, 200_000)).astype(np.uint16).tobytes()
    assert len(rio.deflate(data, 1)) < 1.3 * len(__import__("zlib").compress(data, 1))


def test_instance_rles_equal_pycocotools_encode():
    rng = np.random.default_rng(2)
    for trial in range(30):
        h, w = rng.integers(1, 40, 2)
        instances = rng.integers(0, 5, (h, w)) * (rng.random((h, w)) < 0.8)
        instances = np.repeat(instances, 2, axis=1) if trial % 2 else instances  # longer runs
        if trial % 3 == 0:
            instances[0, 0], instances[-1, -1] = 1, 1  # runs touching the first and last pixel
        ids = np.array([1, 2, 3, 4, 7])  # 7 is absent: an empty mask
        masks = np.asfortranarray(np.stack([instances == i for i in ids], axis=-1).astype(np.uint8))
        expected = mask_utils.encode(masks)
        got = instance_rles(instances.astype(np.int32), ids)
        assert [r["counts"] for r in got] == [r["counts"] for r in expected]
        assert [list(r["size"]) for r in got] == [list(r["size"]) for r in expected]
