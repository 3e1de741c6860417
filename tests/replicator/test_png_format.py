"""The dataset format since 2026-11-29 (issue 22, item 6): faster PNG encoding and compact records with
the same decoded pixels and values as before, semantic images only when asked, and folders started by
an older ambulo either resumed consistently or refused in one line naming the fix."""

import dataclasses
import io
import json
import math
import shutil

import numpy as np
import pytest
from PIL import Image

from ambulo import replicator as rep
from ambulo.cli import main
from ambulo.replicator import io as rio
from ambulo.replicator.manifest import MANIFEST, DatasetFolderError, semantic_image
from ambulo.replicator.producer import FrameProducer
from ambulo.replicator.records import journals, read_json, read_records, record_lines
from ambulo.replicator.writers import json_bytes

SEED = 3


def _decode(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)))


def _previous_encoder(image: np.ndarray, monkeypatch) -> bytes:
    """What ambulo wrote before: the Up filter on every row, zlib-ng (else zlib) at level 1."""
    name, compress, level = rio._pick_deflate("zlib-ng")
    with monkeypatch.context() as patch:
        patch.setattr(rio, "_compress", compress)
        patch.setattr(rio, "_level", level)
        return rio.encode_png(image, 1, "up")


@pytest.fixture(scope="module")
def frames():
    """Three rendered frames of the example scene (rgb, depth as written, instance ids as written)."""
    producer = FrameProducer(rep.example_config(160, 120))
    try:
        out = []
        for index in range(3):
            producer.randomize(SEED, index)
            capture = producer.capture()
            out.append({"rgb": capture["rgb"].copy(), "depth": rio.depth_to_mm_u16(capture["depth"], ">"),
                        "instance": capture["instance_segmentation"].astype(">u2")})
        return out
    finally:
        producer.close()


@pytest.mark.parametrize("deflate", ["isal", "zlib-ng", "zlib"])
def test_each_images_pixels_decode_as_the_previous_encoders(frames, deflate, monkeypatch):
    """Each image kind with the row filter the writer uses for it and each deflate: Pillow decodes the
    same pixels as from the previous encoder's file, and they are the image's."""
    pytest.importorskip({"isal": "isal", "zlib-ng": "zlib_ng", "zlib": "zlib"}[deflate])
    name, compress, level = rio._pick_deflate(deflate)
    assert name.startswith(deflate + " ")
    for frame in frames:
        for kind, row_filter in (("rgb", "none"), ("depth", "sub"), ("instance", "none")):
            image = frame[kind]
            before = _decode(_previous_encoder(image, monkeypatch))
            monkeypatch.setattr(rio, "_compress", compress)
            monkeypatch.setattr(rio, "_level", level)
            now = _decode(rio.encode_png(image, 1, row_filter))
            assert now.dtype == before.dtype and np.array_equal(now, before), (kind, deflate)
            assert np.array_equal(now, image.astype(now.dtype)), (kind, deflate)


def test_records_read_back_as_the_standard_librarys_json():
    record = {"frame": 3, "bbox": [211.0, 99.0, 22.0, 16.0], "x": [0.1 + 0.2, 1e-300, -2.5e17, 1 / 3],
              "prim_path": "/World/objects/box_0", "pose_xy_yaw": {"0": [2.9995553083180515, -1.32]}, "ok": True}
    assert json.loads(json_bytes(record)) == read_json(json_bytes(record)) == json.loads(json.dumps(record)) == record
    for odd in (float("nan"), float("inf"), None):  # json's NaN / Infinity / null, as before
        text = json_bytes({**record, "odd": odd})
        for back in (json.loads(text)["odd"], read_json(text)["odd"]):
            assert (math.isnan(back) if odd != odd else back == odd), text


def _semantic_config(config: rep.DatasetConfig) -> rep.DatasetConfig:
    camera = dataclasses.replace(config.camera, annotators=(*config.camera.annotators, "semantic_segmentation"))
    return dataclasses.replace(config, camera=camera)


def _make(config, out, frames):
    rep.generate(config, out, num_frames=frames, seed=SEED, show_progress=False)


def test_semantic_images_only_when_asked_and_derivable_from_the_instance_image(tmp_path):
    default, asked = tmp_path / "default", tmp_path / "asked"
    _make(rep.example_config(160, 120), default, 2)
    _make(_semantic_config(rep.example_config(160, 120)), asked, 2)
    assert not (default / "semantic").exists() and (default / "instance" / "000001.png").is_file()
    for index in range(2):
        written = np.asarray(Image.open(asked / "semantic" / f"{index:06d}.png"))
        assert written.any()  # objects of some category are in view
        assert np.array_equal(semantic_image(asked, index), written)
        assert np.array_equal(semantic_image(default, index), written)  # the same frame, from its instances


def _as_an_older_ambulo_wrote_it(out):
    """dataset.json as ambulo wrote it before 2026-11-29: the deflate in the fingerprint, no categories;
    and a file per frame record (frames/NNNNNN.json) instead of the journals."""
    for index, line in record_lines(out / "frames").items():
        (out / "frames" / f"{index:06d}.json").write_bytes(line)
    for journal in journals(out / "frames"):
        journal.unlink()
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["fingerprint"]["png_deflate"] = "zlib-ng 2.3.3"
    del manifest["instance_categories"]
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2))


def test_an_older_default_dataset_is_refused_in_one_line_naming_the_annotator_and_resumed_with_it(tmp_path,
                                                                                                  capsys):
    older = _semantic_config(rep.example_config(160, 120))  # the old default annotators had semantic images
    out = tmp_path / "older"
    _make(older, out, 2)
    _as_an_older_ambulo_wrote_it(out)
    status = main(["generate", "--width", "160", "--height", "120", "--quiet", "--seed", str(SEED),
                   "--frames", "3", "--out", str(out)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(lines) == 1, lines
    assert "annotators" in lines[0] and "add 'semantic_segmentation' to the camera's annotators" in lines[0]
    assert 2 not in read_records(out / "frames")
    with pytest.raises(DatasetFolderError, match="semantic_segmentation"):
        _make(rep.example_config(160, 120), out, 3)
    # with the annotator the older dataset is resumed: another deflate decides no pixel
    _make(older, out, 3)
    straight = tmp_path / "straight"
    _make(older, straight, 3)
    for sub in ("rgb", "depth", "instance", "semantic"):
        a = np.asarray(Image.open(out / sub / "000002.png"))
        assert np.array_equal(a, np.asarray(Image.open(straight / sub / "000002.png"))), sub
    resumed = read_records(out / "frames")
    assert sorted(resumed) == [0, 1, 2] and (out / "frames" / "000001.json").is_file()  # the older records count
    assert resumed[2]["annotations"] == read_records(straight / "frames")[2]["annotations"]
    assert (out / "annotations.json").read_bytes() == (straight / "annotations.json").read_bytes()
    shutil.rmtree(straight)
