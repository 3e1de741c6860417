"""``head_camera_vo_cfg``: ORB for a small, low-contrast view (the navigator's 320x240 head camera)."""

import numpy as np
import pytest
import torch

from ambulo.perception.vo.config import VoCfg, head_camera_vo_cfg
from ambulo.perception.vo.features import OrbFeatures
from ambulo.utils.checks import InvalidValueError


def _faint_wall(seed: int = 0) -> np.ndarray:
    """(240, 320, 3) uint8: a grey wall with blobs 4 px wide only +-5 levels from it (a painted wall
    under a head lamp: the apartments' walls read a contrast of ~5 levels)."""
    rng = np.random.default_rng(seed)
    blobs = rng.choice([-5, 0, 5], size=(60, 80)).repeat(4, 0).repeat(4, 1)
    return np.repeat((100 + blobs).astype(np.uint8)[..., None], 3, -1)


def test_the_head_camera_preset_finds_corners_on_a_faint_wall_the_default_misses():
    k = torch.tensor([[262.5, 0, 159.5], [0, 262.5, 119.5], [0, 0, 1]], dtype=torch.float64)
    rgb, depth = _faint_wall(), np.full((240, 320), 1.5, np.float32)
    default = OrbFeatures(VoCfg(), k).detect(rgb, depth)
    head = OrbFeatures(head_camera_vo_cfg(), k).detect(rgb, depth)
    assert len(default.pixels) < 25 <= 200 < len(head.pixels)  # 25: VoCfg.min_inliers
    # the 15 px border: keypoints reach closer to the image edge than ORB's 31 px default allows
    u, v = head.pixels[:, 0], head.pixels[:, 1]
    assert float(u.min()) < 31 and float(v.min()) < 31 and float(u.max()) > 320 - 32


def test_an_orb_border_narrower_than_its_patch_is_refused():
    with pytest.raises(InvalidValueError, match="orb_edge_px"):
        VoCfg(orb_patch_px=31, orb_edge_px=15)
