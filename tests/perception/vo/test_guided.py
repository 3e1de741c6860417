"""Guided matching (``vo.guided``, ``VoCfg.match_window_px``): the window's pairs and nearest two
are exact, a window over the whole image gives the brute-force matches, and the odometry tracks
with it, falling back on the whole local map when the prediction is off by more than the window."""

import numpy as np
import pytest
import torch

from ambulo.perception.vo.config import VoCfg
from ambulo.perception.vo.features import OrbFeatures
from ambulo.perception.vo.guided import best_two, hamming, window_pairs
from ambulo.perception.vo.odometry import RgbdOdometry

K = np.array([[200.0, 0, 80], [0, 200.0, 60], [0, 0, 1]])


@pytest.mark.parametrize("window_px", [3.0, 16.0, 45.0])
def test_window_pairs_are_every_pair_within_the_window(window_px):
    rng = np.random.default_rng(1)
    query = rng.uniform(0, 1, (300, 2)) * [320, 240]
    proj = rng.uniform(-0.1, 1.1, (900, 2)) * [320, 240]
    proj[::37] = np.nan  # behind the camera
    q, m = window_pairs(query, proj, window_px)
    dist = np.linalg.norm(query[:, None] - proj[None], axis=-1)
    assert set(zip(q.tolist(), m.tolist(), strict=True)) == {tuple(p) for p in np.argwhere(dist <= window_px).tolist()}
    assert len(q) == len(set(zip(q.tolist(), m.tolist(), strict=True)))  # no pair twice
    assert np.all(np.diff(q) >= 0)  # grouped by keypoint


def test_best_two_are_each_keypoints_nearest_two():
    rng = np.random.default_rng(2)
    a, b = rng.integers(0, 256, (40, 32), dtype=np.uint8), rng.integers(0, 256, (50, 32), dtype=np.uint8)
    q, m = window_pairs(rng.uniform(0, 100, (40, 2)), rng.uniform(0, 100, (50, 2)), 12.0)
    dist = hamming(a[q], b[m])
    bits = np.unpackbits(a[:, None] ^ b[None], axis=-1).sum(-1)  # (40, 50) by hand
    np.testing.assert_array_equal(dist, bits[q, m])
    queries, best, second = best_two(q, dist)
    for k, i in enumerate(queries):
        mine = np.sort(dist[q == i])
        assert dist[best[k]] == mine[0] and q[best[k]] == i
        assert second[k] == (mine[1] if len(mine) > 1 else np.inf)
    assert set(queries.tolist()) == set(q.tolist())


def test_a_window_over_the_whole_image_matches_as_brute_force():
    rng = np.random.default_rng(3)
    features = OrbFeatures(VoCfg(), torch.as_tensor(K))
    base = rng.integers(0, 256, (600, 32), dtype=np.uint8)
    query = base[:400].copy()
    flips = rng.integers(0, 32, (400, 6))  # a few bits of each query byte-flipped: near, not equal
    query[np.arange(400)[:, None], flips] ^= 0x11
    pix = torch.from_numpy(rng.uniform(0, 160, (400, 2)))
    proj = torch.from_numpy(rng.uniform(0, 160, (600, 2)))
    brute = features.match(torch.from_numpy(query), torch.from_numpy(base))
    windowed = features.match_window(torch.from_numpy(query), pix, torch.from_numpy(base), proj, 1e4)
    assert len(brute) > 300
    assert sorted(map(tuple, brute.tolist())) == sorted(map(tuple, windowed.tolist()))


def _strip(offset_px: int):
    """A 160 x 120 view of a random texture 2 m away, ``offset_px`` along it (the camera moved
    ``offset_px`` * 2 m / 200 px in x)."""
    texture = np.random.default_rng(0).integers(0, 255, (120, 400, 3), dtype=np.uint8)
    return np.ascontiguousarray(texture[:, offset_px:offset_px + 160]), np.full((120, 160), 2.0, np.float32)


def _step(dx_m):
    out = np.eye(4)
    out[0, 3] = dx_m
    return out


@pytest.mark.parametrize("prior_error_m", [0.0, 0.3])
def test_guided_tracking_and_its_fallback(prior_error_m):
    """Right prior: every frame is matched in the window, never against the whole map. A prior 0.3 m
    off (30 px, twice the window): the frame is matched against the whole local map and tracked."""
    vo = RgbdOdometry(K, VoCfg(match_window_px=16.0))
    brute = []
    vo.features.match = lambda *a, _match=vo.features.match: brute.append(1) or _match(*a)
    assert vo.track(*_strip(0)).tracked
    for k in range(1, 8):
        result = vo.track(*_strip(6 * k), motion_cam=_step(0.06 + prior_error_m))
        assert result.tracked
        np.testing.assert_allclose(result.pose_wc[:3, 3], [0.06 * k, 0, 0], atol=2e-3)
    assert len(brute) == (0 if prior_error_m == 0 else 7)


def test_kornia_window_matches_as_match_snn_over_the_whole_image_and_keeps_to_the_window():
    from ambulo.perception.vo.config import kornia_vo_cfg
    from ambulo.perception.vo.features import KorniaFeatures

    features = KorniaFeatures(kornia_vo_cfg(), torch.as_tensor(K), torch.device("cpu"))
    gen = torch.Generator().manual_seed(4)
    base = torch.rand(300, 128, generator=gen)
    query = base[:200] + 0.05 * torch.rand(200, 128, generator=gen)
    pix, proj = torch.rand(200, 2, generator=gen) * 160, torch.rand(300, 2, generator=gen) * 160
    whole = features.match_window(query, pix, base, proj, 1e4)
    assert len(whole) > 150
    assert sorted(map(tuple, whole.tolist())) == sorted(map(tuple, features.match(query, base).tolist()))
    near = features.match_window(query, pix, base, proj, 20.0)
    assert len(near) and ((pix[near[:, 0]] - proj[near[:, 1]]).norm(dim=1) <= 20.0).all()
