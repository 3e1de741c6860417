"""The tutorial script draws the boxes pycocotools reads back onto a frame."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from script_loader import load_script

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "replicator_dataset.py"


@pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning")
def test_example_draws_boxes_on_frame_zero(dataset):
    example = load_script(EXAMPLE)
    out = example.draw_boxes(dataset)
    drawn = np.asarray(Image.open(out).convert("RGB"))
    original = np.asarray(Image.open(dataset / "rgb" / "000000.png"))
    assert drawn.shape == original.shape
    changed = np.any(drawn != original, axis=-1)
    assert changed.sum() > 50  # box and mask outlines were drawn
