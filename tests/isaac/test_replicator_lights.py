"""Replicator lights with distributions: temperature tints, lights created in a trigger redraw every
frame (outside one, once per run); the lights-and-materials tutorial runs unchanged."""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ambulo.isaac import IsaacNameError, run_script
from ambulo.isaac.replicator.nodes import blackbody_rgb

LIGHTS = Path(__file__).resolve().parents[2] / "examples" / "isaac" / "replicator_lights_materials.py"


def test_blackbody_colour_matches_the_planckian_table():
    # Mitchell Charity's blackbody sRGB table (CIE 1964 10-degree): 2000 K #ff8912, 10000 K #c9d9ff
    assert np.allclose(blackbody_rgb(2000), np.array([255, 137, 18]) / 255, atol=6 / 255)
    assert np.allclose(blackbody_rgb(10000), np.array([201, 218, 255]) / 255, atol=6 / 255)
    assert np.allclose(blackbody_rgb(6500), 1.0, atol=0.03)  # daylight is white


SCRIPT = """
import sys
import omni.replicator.core as rep
out, where = sys.argv[1:3]
cam = rep.create.camera(position=(0, 0, 5), look_at=(0, 0, 0))
rp = rep.create.render_product(cam, (32, 32))
rep.create.plane(scale=20)

def warm_or_cold():
    return rep.create.light(light_type="Sphere", intensity=1000, position=(0, 0, 3),
                            temperature=rep.distribution.uniform(2000, 10000)).node

rep.randomizer.register(warm_or_cold)
if where == "outside":
    rep.randomizer.warm_or_cold()
with rep.trigger.on_frame(num_frames=4):
    if where == "inside":
        rep.randomizer.warm_or_cold()
writer = rep.WriterRegistry.get("BasicWriter")
writer.initialize(output_dir=out, rgb=True)
writer.attach([rp])
rep.orchestrator.run()
"""


def fitted_temperature(rgb: np.ndarray) -> tuple[float, float]:
    """The temperature whose tint, scaled, best explains ``rgb`` (3,): (K, residual / |rgb|)."""
    best = (0.0, np.inf)
    for kelvin in np.arange(1500, 12001, 50):
        tint = blackbody_rgb(kelvin)
        residual = float(np.linalg.norm(tint * (tint @ rgb) / (tint @ tint) - rgb) / np.linalg.norm(rgb))
        if residual < best[1]:
            best = (float(kelvin), residual)
    return best


@pytest.mark.parametrize("where", ["inside", "outside"])
def test_a_light_created_in_a_trigger_draws_its_temperature_every_frame(tmp_path, where):
    script = tmp_path / "lights.py"
    script.write_text(SCRIPT)
    out = tmp_path / where
    run_script(script, [str(out), where])
    fits = []
    for i in range(4):
        rgb = np.array(Image.open(out / f"rgb_{i:04d}.png"))[..., :3].reshape(-1, 3).astype(float) / 255
        kelvin, residual = fitted_temperature(np.median(rgb, 0))
        assert residual < 0.02 and 2000 - 300 <= kelvin <= 10000 + 300  # the floor is lit in a blackbody's tint
        fits.append(kelvin)
    if where == "inside":
        assert np.ptp(fits) > 1000  # a new temperature every frame
    else:
        assert np.ptp(fits) == 0  # drawn once per run


def test_a_light_refuses_a_scale_in_one_line(tmp_path):
    script = tmp_path / "scaled.py"
    script.write_text("import omni.replicator.core as rep\nrep.create.light(light_type='Sphere', scale=50)\n")
    with pytest.raises(IsaacNameError, match=r"create.light\(scale=...\).*points.*drop scale") as err:
        run_script(script)
    assert "\n" not in str(err.value)


def test_the_lights_and_materials_tutorial_writes_labelled_scattered_shapes(tmp_path):
    out = tmp_path / "out"
    run_script(LIGHTS, ["--output_dir", str(out), "--num_frames", "2", "--resolution", "96", "96"])
    for i in range(2):
        labels = json.loads((out / f"semantic_segmentation_labels_{i:04d}.json").read_text())
        classes = {v["class"] for v in labels.values()}
        assert {"floor", "cube", "sphere", "torus"} <= classes
        depth = np.load(out / f"distance_to_camera_{i:04d}.npy")
        assert depth.shape == (96, 96) and np.isfinite(depth[48:]).all()
        # the camera (0, -7, 5) is 8.6 m from the floor's centre, seen at the image centre
        assert 7.0 < depth[48, 48] < 8.7
    first, second = (np.array(Image.open(out / f"rgb_{i:04d}.png")) for i in range(2))
    assert np.abs(first.astype(int) - second.astype(int)).mean() > 1  # lights, materials and places redrawn
