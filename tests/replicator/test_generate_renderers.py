"""``ambulo generate --renderer pbr`` writes the same annotations as raster for the same seed (read
back with pycocotools), with other colours: labels come from the raster id pass in every tier."""

import contextlib
import io
import subprocess

import numpy as np
import pytest
from PIL import Image
from pycocotools.coco import COCO

from ambulo.render import pbr

pytestmark = [
    pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning"),
    pytest.mark.slow,  # two `ambulo generate` processes, ~1 min; tests/render/test_pbr.py checks labels in-process
    pytest.mark.skipif(pbr._vulkan_problem() is not None, reason=f"no Vulkan here: {pbr._vulkan_problem()}"),
]

FRAMES = 3


def _coco(out):
    with contextlib.redirect_stdout(io.StringIO()):
        return COCO(str(out / "annotations.json"))


def test_generate_with_pbr_writes_the_raster_annotations_and_other_colours(tmp_path, gen):
    outs = {}
    for renderer in ("raster", "pbr"):
        out = tmp_path / renderer
        run = subprocess.run(gen.argv(out, FRAMES, "--workers", "1", "--renderer", renderer),
                             env=gen.env(), capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr
        outs[renderer] = out
    raster, lit = _coco(outs["raster"]), _coco(outs["pbr"])
    assert sorted(raster.getImgIds()) == sorted(lit.getImgIds()) and len(raster.getImgIds()) == FRAMES
    assert raster.loadCats(raster.getCatIds()) == lit.loadCats(lit.getCatIds())
    assert len(raster.getAnnIds()) > 0
    for image_id in raster.getImgIds():
        ours = sorted(raster.loadAnns(raster.getAnnIds(imgIds=[image_id])), key=lambda a: a["id"])
        theirs = sorted(lit.loadAnns(lit.getAnnIds(imgIds=[image_id])), key=lambda a: a["id"])
        assert ours == theirs, image_id  # boxes, RLE masks, areas, categories, ids: all equal
        for a in ours:  # and the masks decode to the same pixels
            assert np.array_equal(raster.annToMask(a), lit.annToMask(a))
    for name in ("instance", "depth"):
        files = sorted((outs["raster"] / name).glob("*.png"))
        assert len(files) == FRAMES, name
        for f in files:  # the same pixels (the deflate promises no more than that)
            assert np.array_equal(np.asarray(Image.open(f)), np.asarray(Image.open(outs["pbr"] / name / f.name))), f
    differences = []
    for f in sorted((outs["raster"] / "rgb").glob("*.png")):
        a = np.asarray(Image.open(f), int)
        b = np.asarray(Image.open(outs["pbr"] / "rgb" / f.name), int)
        assert a.shape == b.shape
        differences.append(np.abs(a - b).mean())
    assert len(differences) == FRAMES and min(differences) > 5  # another renderer drew the colours
