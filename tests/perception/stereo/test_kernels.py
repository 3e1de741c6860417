"""The Warp aggregation of the semi-global matcher (``ambulo.perception.stereo.kernels``) against the
torch one (``stereo.sgm.aggregate``), on the CPU: integer costs make both exact, so they must agree
to the bit. The CUDA kernel (a block of lanes per line) runs here too, as cooperative CPU fibers
(``wp.config.enable_cpu_blocks``), so its exchange between lanes is checked without a GPU."""

import numpy as np
import pytest
import torch

from ambulo.perception.stereo import kernels
from ambulo.perception.stereo.sgm import SgmCfg, aggregate, sgm_disparity

if not kernels.available():
    pytest.skip("warp-lang is not installed", allow_module_level=True)


def random_cost(shape: tuple[int, int, int], seed: int) -> torch.Tensor:
    """(D, H, W) integer costs 0 .. 64 in float32, as census costs are."""
    return torch.randint(0, 65, shape, generator=torch.Generator().manual_seed(seed)).to(torch.float32)


@pytest.fixture
def cpu_blocks(monkeypatch):
    """Run launches with more than one lane per block on the CPU (Warp's cooperative fibers)."""
    monkeypatch.setattr(kernels.wp.config, "enable_cpu_blocks", True)


CASES = [  # (D, H, W), p1, p2: non-square, penalties other than the defaults (7, 86)
    ((16, 23, 41), 3, 20),
    ((33, 37, 29), 11, 40),
    ((64, 20, 57), 5, 120),
]


@pytest.mark.parametrize("paths", [4, 8])
@pytest.mark.parametrize("shape,p1,p2", CASES)
def test_cpu_kernel_equals_the_torch_aggregation_to_the_bit(paths, shape, p1, p2):
    cost = random_cost(shape, seed=shape[0])
    cfg = SgmCfg(num_disparities=shape[0], p1=p1, p2=p2, paths=paths)
    got = kernels.aggregate_warp(cost, cfg)
    assert got.shape == shape and got.dtype == torch.float32 and got.is_contiguous()
    assert torch.equal(got, aggregate(cost, cfg))


@pytest.mark.parametrize("threads", [1, 2])
def test_one_or_two_cpu_threads_give_the_same_sum(threads):
    """One launch over every path, or the two mirrored halves from two threads into two outputs."""
    cost, cfg = random_cost((16, 19, 31), seed=5), SgmCfg(num_disparities=16, p1=4, p2=30)
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        got = kernels.aggregate_warp(cost, cfg)
    finally:
        torch.set_num_threads(before)
    assert torch.equal(got, aggregate(cost, cfg))


@pytest.mark.parametrize("paths", [4, 8])
@pytest.mark.parametrize("lanes", [4, 32])
def test_the_cuda_kernel_run_as_cpu_fibers_equals_the_torch_aggregation(cpu_blocks, paths, lanes):
    """4 lanes: several disparities per lane, neighbours in other lanes; 32 lanes > D = 16 or 29:
    idle lanes in the block minimum."""
    for shape, p1, p2 in [((16, 21, 34), 3, 20), ((29, 17, 12), 9, 55)]:
        cost = random_cost(shape, seed=shape[1])
        cfg = SgmCfg(num_disparities=shape[0], p1=p1, p2=p2, paths=paths)
        assert torch.equal(kernels.aggregate_warp(cost, cfg, lanes=lanes), aggregate(cost, cfg)), shape


@pytest.mark.parametrize("shape", [(8, 1, 13), (8, 11, 1), (2, 1, 1), (1, 5, 6)])
@pytest.mark.parametrize("lanes", [None, 4])
def test_degenerate_shapes_equal_the_torch_aggregation(cpu_blocks, shape, lanes):
    """A single row or column (every diagonal line one pixel long), one pixel, one disparity."""
    cost = random_cost(shape, seed=7)
    cfg = SgmCfg(num_disparities=2, p1=3, p2=20)  # only the paths and penalties are read
    assert torch.equal(kernels.aggregate_warp(cost, cfg, lanes=lanes), aggregate(cost, cfg))


def test_lines_cover_every_pixel_once_per_direction():
    """``num_lines`` and the kernels' line numbering: a zero-penalty, all-ones cost gives every pixel
    L = 1 per path, so the sum is the number of paths through it: all of them, once each."""
    cost = torch.ones((3, 9, 14))
    for paths in (4, 8):
        total = kernels.aggregate_warp(cost, SgmCfg(num_disparities=3, p1=0, p2=0, paths=paths))
        assert torch.equal(total, torch.full_like(cost, float(paths)))
    assert kernels.num_lines(1, -1, 9, 14) == 9 + 14 - 1
    assert [kernels.num_lines(dy, dx, 9, 14) for dy, dx in kernels.directions(4)] == [9, 14, 9, 14]


def test_sgm_disparity_is_the_same_with_either_aggregation():
    data = pytest.importorskip("skimage.data")
    left, right, _ = data.stereo_motorcycle()
    left, right = torch.from_numpy(left[150:270, 250:430]), torch.from_numpy(right[150:270, 250:430])
    by = {agg: sgm_disparity(left, right, SgmCfg(aggregation=agg)).numpy() for agg in ("warp", "torch")}
    assert np.isnan(by["warp"]).mean() < 0.5  # a crop with texture: most pixels matched
    np.testing.assert_array_equal(np.isnan(by["warp"]), np.isnan(by["torch"]))
    np.testing.assert_array_equal(by["warp"], by["torch"])  # nan == nan here


def test_auto_aggregation_takes_warp_on_the_cpu_and_cuda():
    from ambulo.perception.stereo.sgm import resolve_aggregation

    assert resolve_aggregation("auto", torch.device("cpu")) == "warp"
    assert resolve_aggregation("auto", torch.device("cuda", 0)) == "warp"
    assert resolve_aggregation("auto", torch.device("meta")) == "torch"
    assert resolve_aggregation("torch", torch.device("cpu")) == "torch"


def test_a_bad_aggregation_setting_is_refused_in_one_line_naming_it_and_the_fix():
    from ambulo.utils.checks import InvalidValueError

    with pytest.raises(InvalidValueError) as err:
        SgmCfg(aggregation="cuda")
    message = str(err.value)
    assert "\n" not in message and "SgmCfg.aggregation" in message and "'cuda'" in message
    assert "pass 'auto', 'torch' or 'warp'" in message


@pytest.mark.parametrize("cost,named", [
    (torch.zeros((4, 5, 6), dtype=torch.float64), "torch.float64 (4, 5, 6)"),
    (torch.zeros((5, 6)), "torch.float32 (5, 6)"),
    (np.zeros((4, 5, 6), np.float32), "ndarray"),
])
def test_a_bad_cost_is_refused_in_one_line(cost, named):
    with pytest.raises(ValueError) as err:
        kernels.aggregate_warp(cost, SgmCfg())
    message = str(err.value)
    assert "\n" not in message and "(D, H, W) float32" in message and named in message


def test_without_warp_auto_falls_back_to_torch_and_warp_is_refused(monkeypatch):
    from ambulo.perception.stereo.sgm import resolve_aggregation

    monkeypatch.setattr(kernels, "wp", None)  # as if warp-lang were not installed
    assert resolve_aggregation("auto", torch.device("cpu")) == "torch"
    with pytest.raises(ImportError, match="aggregation='torch'"):
        resolve_aggregation("warp", torch.device("cpu"))
    gen = torch.Generator().manual_seed(8)
    right = (torch.rand((20, 40), generator=gen) * 256).to(torch.uint8)
    left = torch.cat([right[:, :3], right[:, :-3]], 1)
    assert sgm_disparity(left, right, SgmCfg(num_disparities=8)).isfinite().any()
