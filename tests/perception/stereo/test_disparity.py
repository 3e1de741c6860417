"""Stereo depth (optional part of issue 13): SGBM on the Middlebury 2014 Motorcycle pair that
scikit-image ships with its ground-truth disparity (Scharstein et al., GCPR 2014)."""

import numpy as np
import pytest
import torch

from ambulo.perception.stereo.sgbm_opencv import disparity_to_depth, sgbm_disparity


def test_sgbm_matches_the_middlebury_ground_truth():
    data = pytest.importorskip("skimage.data")
    left, right, truth = data.stereo_motorcycle()
    disparity = sgbm_disparity(left, right)
    known = np.isfinite(truth)
    both = known & np.isfinite(disparity)
    error = np.abs(disparity[both] - truth[both])
    assert both.sum() / known.sum() > 0.8  # density
    assert (error > 2.0).mean() < 0.08  # Middlebury's "bad 2.0" metric: 5.9 % here
    assert np.median(error) < 0.3


def test_disparity_to_depth_is_f_times_baseline_over_disparity():
    disparity = np.array([[10.0, np.nan, 40.0, -1.0]], np.float32)
    depth = disparity_to_depth(disparity, focal_px=500.0, baseline_m=0.1)
    np.testing.assert_allclose(depth, [[5.0, 0.0, 1.25, 0.0]])


# --- the torch semi-global matcher (ambulo.perception.stereo.sgm), on the CPU here ---------------

def motorcycle_scores(disparity: np.ndarray, truth: np.ndarray) -> tuple[float, float, float]:
    """(density, bad 2.0, median |error| px) of a disparity against the ground truth, over the
    pixels with a true disparity (Middlebury's metrics, without its occlusion masks)."""
    known = np.isfinite(truth)
    both = known & np.isfinite(disparity)
    error = np.abs(disparity[both] - truth[both])
    return both.sum() / known.sum(), (error > 2.0).mean(), float(np.median(error))


@pytest.fixture
def one_torch_thread():
    """The matcher's path scans are thousands of small ops; on a shared machine a second torch
    thread waits for a core at every one (34 s instead of 4.6 s on the dev VM under load)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_sgm_matches_the_middlebury_ground_truth_as_well_as_sgbm(one_torch_thread):
    data = pytest.importorskip("skimage.data")
    from ambulo.perception.stereo.sgm import sgm_disparity

    left, right, truth = data.stereo_motorcycle()
    ours = motorcycle_scores(sgm_disparity(torch.from_numpy(left), torch.from_numpy(right)).numpy(), truth)
    sgbm = motorcycle_scores(sgbm_disparity(left, right), truth)
    assert ours[0] > 0.88  # density: 90.3 % (SGBM 87.0 %)
    assert ours[1] < 0.06  # bad 2.0: 5.05 % (SGBM 5.87 %)
    assert ours[1] < 1.5 * sgbm[1]
    assert ours[2] < 0.2  # median error: 0.139 px (SGBM 0.180 px)


def random_image(shape: tuple[int, ...], generator: torch.Generator) -> torch.Tensor:
    return (torch.rand(shape, generator=generator) * 256).to(torch.uint8)


def test_sgm_recovers_an_integer_shift_of_random_texture():
    from ambulo.perception.stereo.sgm import SgmCfg, sgm_disparity

    gen = torch.Generator().manual_seed(0)
    right = random_image((60, 120), gen)
    left = torch.cat([random_image((60, 7), gen), right[:, :-7]], 1)  # left[:, x] = right[:, x - 7]
    disparity = sgm_disparity(left, right, SgmCfg(num_disparities=16))[:, 7:]
    assert torch.isfinite(disparity).float().mean() > 0.98  # 99.1 %
    error = (disparity - 7.0).abs()
    assert error.nanmean() < 0.05  # 0.036 px
    assert error.nan_to_num(0.0).max() < 0.5  # 0.41 px


@pytest.mark.parametrize("shift_px", [9.5, 9.25])
def test_sgm_recovers_a_sub_pixel_shift(shift_px):
    from ambulo.perception.stereo.sgm import SgmCfg, sgm_disparity

    gen = torch.Generator().manual_seed(1)
    texture = torch.nn.functional.avg_pool1d(torch.rand((60, 1, 200), generator=gen), 3, 1, 1)[:, 0]
    x = torch.arange(120, dtype=torch.float64)

    def sample(at: torch.Tensor) -> torch.Tensor:
        """Texture linearly interpolated at columns ``at``, as uint8."""
        i = at.floor().long()
        f = (at - i).float()
        return ((texture[:, i] * (1 - f) + texture[:, i + 1] * f) * 255).round().to(torch.uint8)

    left, right = sample(x + 40), sample(x + 40 + shift_px)  # left[x] = right[x - shift]
    disparity = sgm_disparity(left, right, SgmCfg(num_disparities=16))[:, 16:]
    assert torch.isfinite(disparity).float().mean() > 0.99
    # median error 9.5: -0.003 px; 9.25: -0.13 px (the estimate leans to the integer: pixel locking)
    assert abs(float((disparity - shift_px).nanmedian())) < 0.2


def test_sgm_leaves_occluded_pixels_out():
    """A textured square at 12 px disparity before a background at 4 px: in the left image the 8 px
    of background left of the square are hidden from the right camera."""
    from ambulo.perception.stereo.sgm import SgmCfg, sgm_disparity

    gen = torch.Generator().manual_seed(2)
    background, square = random_image((60, 136), gen), random_image((60, 136), gen)
    x, y = torch.arange(120), torch.arange(60)[:, None]
    rows = (y >= 20) & (y < 40)
    in_left, in_right = rows & (x >= 50) & (x < 80), rows & (x >= 38) & (x < 68)
    left = torch.where(in_left, square[:, :120], background[:, :120])
    right = torch.where(in_right, square[:, 12:132], background[:, 4:124])
    truth = torch.where(in_left, 12.0, 4.0)
    disparity = sgm_disparity(left, right, SgmCfg(num_disparities=16))
    hidden = rows & (x >= 42) & (x < 50)
    assert disparity[hidden].isnan().float().mean() > 0.6  # 74 % (18 % without the left-right check)
    valid = disparity.isfinite() & (x >= 4)
    assert ((disparity - truth).abs()[valid] > 1).float().mean() < 0.005  # 0.27 %
    away = ~((x >= 40) & (x < 84) & (y >= 16) & (y < 44)) & (x >= 8)
    assert disparity[away].isfinite().all()
    assert (disparity - truth)[away].abs().max() < 0.5  # 0.33 px


def reference_path_costs(cost: np.ndarray, p1: int, p2: int, directions) -> np.ndarray:
    """Hirschmüller's recurrence pixel by pixel: the sum over ``directions`` (dy, dx) of
    L(p, d) = C(p, d) + min(L(q, d), L(q, d +- 1) + p1, min L(q) + p2) - min L(q), q = p - (dy, dx)."""
    d_count, h, w = cost.shape
    total = np.zeros_like(cost)
    for dy, dx in directions:
        path = np.zeros_like(cost)
        for y in range(h) if dy >= 0 else reversed(range(h)):
            for x in range(w) if dx >= 0 else reversed(range(w)):
                qy, qx = y - dy, x - dx
                if not (0 <= qy < h and 0 <= qx < w):
                    path[:, y, x] = cost[:, y, x]
                    continue
                prev = path[:, qy, qx]
                for d in range(d_count):
                    options = [prev[d], prev.min() + p2]
                    options += [prev[d - 1] + p1] if d > 0 else []
                    options += [prev[d + 1] + p1] if d < d_count - 1 else []
                    path[d, y, x] = cost[d, y, x] + min(options) - prev.min()
        total += path
    return total


@pytest.mark.parametrize("paths", [4, 8])
def test_aggregation_equals_the_pixel_by_pixel_recurrence(paths):
    from ambulo.perception.stereo.sgm import SgmCfg, aggregate

    cost = torch.randint(0, 40, (6, 7, 9), generator=torch.Generator().manual_seed(3)).float()
    straight = [(0, 1), (0, -1), (1, 0), (-1, 0)]
    diagonal = [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    expected = reference_path_costs(cost.numpy(), 3, 20, straight + (diagonal if paths == 8 else []))
    got = aggregate(cost, SgmCfg(p1=3, p2=20, paths=paths))
    np.testing.assert_array_equal(got.numpy(), expected)  # integer costs: exact in float32


def test_winner_gets_a_sub_pixel_v_fit_unless_another_disparity_costs_nearly_as_little():
    from ambulo.perception.stereo.sgm import SgmCfg, select_disparity

    curve = torch.tensor([9.0, 6.0, 2.0, 4.0, 9.0, 9.0, 9.0, 9.0])
    rival = curve.clone()
    rival[6] = 2.05  # within 5 % of the winner's 2, and 4 px away
    volume = torch.stack([curve, rival], 1)[:, :, None].expand(8, 2, 12)  # (D, H, W)
    disparity = select_disparity(volume, SgmCfg(num_disparities=8, median_size=0))
    # a V through (1, 6), (2, 2), (3, 4) with slopes of 4 px^-1 either side has its tip at 2.25
    np.testing.assert_array_equal(disparity[0, 2:].numpy(), 2.25)
    assert disparity[0, :2].isnan().all()  # x < 2: the match would lie left of the right image
    assert disparity[1].isnan().all()
    assert select_disparity(volume, SgmCfg(num_disparities=8, median_size=0, uniqueness_ratio=0.0))[1, 2:].eq(2.25).all()


def test_census_hamming_cost_counts_differing_bits():
    from ambulo.perception.stereo.sgm import census, census_cost, grey_levels, popcount

    assert grey_levels(torch.tensor([[[10, 20, 30]]], dtype=torch.uint8)).item() == 299 * 10 + 587 * 20 + 114 * 30

    values = torch.tensor([0, 1, 0b1011, (1 << 62) - 1, 0x5A5A5A5A5A5A5A5A >> 1])
    assert popcount(values).tolist() == [bin(v).count("1") for v in values.tolist()]
    grey = torch.tensor([[5.0, 1.0, 9.0], [2.0, 4.0, 7.0], [3.0, 4.0, 0.0]])
    # centre 4: bits in row order, centre skipped: 5 1 9 2 | 7 3 4 0 -> darker: 0 1 0 1 | 0 1 0 1
    assert int(census(grey, 3, 3)[1, 1]) == 0b10101010
    left = torch.tensor([[0b0110, 0b1111, 0b0001]])
    right = torch.tensor([[0b0000, 0b0101, 0b1000]])
    cost = census_cost(left, right, 2)
    # d = 0: |left[x] ^ right[x]|; d = 1: |left[x] ^ right[x - 1]|, nothing at x = 0
    np.testing.assert_array_equal(cost[:, 0].numpy(), [[2, 2, 2], [64, 4, 1]])


def test_stereo_frame_gives_the_mapper_depth():
    from ambulo.perception.stereo.sgm import disparity_to_depth as depth_of
    from ambulo.perception.stereo.sgm import stereo_frame

    disparity = torch.tensor([[10.0, float("nan"), 40.0, -1.0]])
    np.testing.assert_allclose(depth_of(disparity, 500.0, 0.1).numpy(),
                               disparity_to_depth(disparity.numpy(), 500.0, 0.1))
    gen = torch.Generator().manual_seed(4)
    right = random_image((40, 80, 3), gen)
    left = torch.cat([random_image((40, 5, 3), gen), right[:, :-5]], 1)
    k = torch.tensor([[400.0, 0, 40], [0, 400.0, 20], [0, 0, 1]], dtype=torch.float64)
    frame = stereo_frame(left, right, k, baseline_m=0.05)
    assert frame.rgb is left and frame.intrinsics.dtype == torch.float64
    seen = frame.depth_m[:, 10:] > 0
    assert seen.float().mean() > 0.95
    np.testing.assert_allclose(frame.depth_m[:, 10:][seen].median(), 400.0 * 0.05 / 5, rtol=0.02)


@pytest.mark.parametrize("field,value,named", [
    ("num_disparities", 0, "num_disparities"), ("paths", 5, "pass 4 or 8"), ("p1", -1, "p1"),
    ("p2", 3, "p2"), ("uniqueness_ratio", float("nan"), "uniqueness_ratio"), ("max_lr_diff_px", -2, "max_lr_diff_px"),
    ("median_size", 4, "odd"), ("num_disparities", 16.5, "whole number")])
def test_a_bad_sgm_setting_is_refused_in_one_line_naming_it_and_the_fix(field, value, named):
    from ambulo.perception.stereo.sgm import SgmCfg
    from ambulo.utils.checks import InvalidValueError

    with pytest.raises(InvalidValueError) as err:
        SgmCfg(**{field: value})
    message = str(err.value)
    assert "\n" not in message and f"SgmCfg.{field}" in message and named in message and "pass" in message
