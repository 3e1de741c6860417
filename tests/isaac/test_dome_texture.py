"""A Replicator dome light with an HDR ``texture`` lights the pbr tier's images (image-based
lighting), and ``SimulationApp({"renderer": "RayTracedLighting"})`` gives its cameras that tier."""

import cv2
import numpy as np
import pytest
from PIL import Image

from ambulo.isaac import run_script
from ambulo.render import pbr
from ambulo.sim import camera as sim_camera

pytestmark = pytest.mark.skipif(pbr._vulkan_problem() is not None, reason=f"no Vulkan here: {pbr._vulkan_problem()}")

SCRIPT = """
import sys
from pathlib import Path
from isaacsim import SimulationApp
app = SimulationApp({"headless": True, "renderer": "RayTracedLighting"})
import omni.replicator.core as rep
out, hdr = Path(sys.argv[1]), sys.argv[2]
rep.set_global_seed(3)
rep.create.light(light_type="dome", texture=hdr, intensity=1000)
cam = rep.create.camera(position=(0, -6, 4), look_at=(0, 0, 0))
rp = rep.create.render_product(cam, (64, 48))
rep.create.cube(semantics=[("class", "cube")], scale=1.5, position=(0, 0, 0.75))
writer = rep.WriterRegistry.get("BasicWriter")
writer.initialize(output_dir=str(out), rgb=True, instance_segmentation=True, colorize_instance_segmentation=False)
writer.attach(rp)
rep.orchestrator.step()
app.close()
"""


@pytest.fixture(autouse=True)
def _restore_default_renderer():
    yield
    sim_camera.set_default_renderer("raster")


def test_a_brighter_hdr_dome_gives_a_brighter_image_and_the_same_labels(tmp_path):
    script = tmp_path / "dome.py"
    script.write_text(SCRIPT)
    images, ids = {}, {}
    for name, level in (("dim", 0.25), ("bright", 1.0)):
        hdr = tmp_path / f"{name}.hdr"
        assert cv2.imwrite(str(hdr), np.full((32, 64, 3), level, np.float32))
        run_script(script, [str(tmp_path / name), str(hdr)])
        images[name] = np.asarray(Image.open(tmp_path / name / "rgb_0000.png"))[..., :3].astype(float)
        ids[name] = np.asarray(Image.open(tmp_path / name / "instance_segmentation_0000.png"))
    assert np.array_equal(ids["dim"], ids["bright"])
    cube = ids["bright"] == ids["bright"][24, 32]
    assert cube.sum() > 50
    # 4x the environment's radiance: clearly brighter (tone mapping compresses, so not 4x)
    assert images["bright"][cube].mean() > 1.5 * images["dim"][cube].mean() + 5
