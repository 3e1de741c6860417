"""``CameraCfg.renderer``: every tier gives the raster labels; only the colours change."""

import importlib.util

import mujoco
import numpy as np
import pytest

from ambulo.core.semantics import set_semantic_label
from ambulo.engine import CpuEngine
from ambulo.render import pbr
from ambulo.sensors import Camera, CameraCfg

W, H = 64, 48
ANNOTATORS = ("rgb", "depth", "instance_segmentation", "semantic_segmentation", "bounding_box_2d_tight")


def _capture(renderer: str) -> dict:
    spec = mujoco.MjSpec()
    spec.worldbody.add_light(pos=[0, 0, 4], dir=[0.3, 0.2, -1])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[10, 10, 0.1])
    for name, pos in {"/World/a": [0.4, 0.1, 0.3], "/World/b": [-0.5, 0.4, 0.2]}.items():
        body = spec.worldbody.add_body(name=name, pos=pos)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.2, 0.2], rgba=[0.8, 0.3, 0.2, 1])
        set_semantic_label(spec, name, "box")
    camera = Camera(CameraCfg(prim_path="/World/camera", width=W, height=H, renderer=renderer, annotators=ANNOTATORS))
    camera.build(spec)
    camera.initialize(CpuEngine(spec.compile(), 1, num_threads=1))
    camera.set_camera_view(eye=[-2.0, -1.5, 2.0], target=[0.0, 0.2, 0.2])
    frame = camera.capture(0)
    camera.close()
    return frame


@pytest.mark.slow  # Mitsuba's first frame JIT-compiles (~25 s on the shared 2-core machine)
@pytest.mark.skipif(importlib.util.find_spec("mitsuba") is None, reason="the path tier needs mitsuba")
def test_the_path_tier_gives_the_raster_labels_and_its_own_colours():
    raster, traced = _capture("raster"), _capture("path")
    for key in ("depth", "instance_segmentation", "semantic_segmentation", "geom_ids"):
        assert np.array_equal(raster[key], traced[key]), key
    assert np.array_equal(raster["bounding_box_2d_tight"]["box"], traced["bounding_box_2d_tight"]["box"])
    assert traced["rgb"].shape == (H, W, 3) and traced["rgb"].dtype == np.uint8
    boxes = raster["instance_segmentation"] > 0
    # the path tracer drew the boxes where the raster did: reddish there, not the grey floor
    assert (traced["rgb"][boxes, 0].astype(int) - traced["rgb"][boxes, 2]).mean() > 20
    assert np.abs(traced["rgb"].astype(int) - raster["rgb"]).mean() > 2


@pytest.mark.skipif(pbr._vulkan_problem() is not None, reason=f"no Vulkan here: {pbr._vulkan_problem()}")
def test_the_pbr_tier_gives_the_raster_labels_and_its_own_colours():
    raster, lit = _capture("raster"), _capture("pbr")
    for key in ("depth", "instance_segmentation", "semantic_segmentation", "geom_ids"):
        assert np.array_equal(raster[key], lit[key]), key
    for key in ("box", "instance_id", "pixels"):
        assert np.array_equal(raster["bounding_box_2d_tight"][key], lit["bounding_box_2d_tight"][key])
    assert lit["rgb"].shape == raster["rgb"].shape == (H, W, 3)
    assert np.abs(lit["rgb"].astype(int) - raster["rgb"]).mean() > 5  # another renderer drew the colours


def test_an_unknown_renderer_is_refused_in_one_line():
    with pytest.raises(Exception, match="renderer"):
        CameraCfg(prim_path="/World/camera", renderer="rtx")
