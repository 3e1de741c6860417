"""The EDT (Warp kernels and the windowed torch reference) against scipy, and the map's ESDF against
the exact EDT of the truth."""

import numpy as np
import pytest
import torch
from scipy import ndimage

from ambulo.perception import esdf_kernels
from ambulo.perception.esdf import edt, edt_torch, esdf_from_grid

from .conftest import OFFSET, pinhole, shifted


@pytest.mark.parametrize("shape,density,max_cells", [((64, 48), 0.01, 100), ((40, 30, 20), 0.003, 12)])
def test_edt_equals_scipy_within_the_window(shape, density, max_cells):
    rng = np.random.default_rng(1)
    sites = rng.random(shape) < density
    ours = edt(torch.from_numpy(sites), max_cells).numpy()
    exact = ndimage.distance_transform_edt(~sites)
    near = exact <= max_cells
    np.testing.assert_allclose(ours[near], exact[near], atol=1e-5)
    assert np.isinf(ours[~near]).all()


def test_edt_without_sites_is_infinite():
    assert torch.isinf(edt(torch.zeros(5, 6, dtype=torch.bool), 3)).all()


@pytest.fixture(scope="module")
def mapped(room, truth):
    from ambulo.perception.reference import orbit_poses, truth_frames
    from ambulo.perception.tsdf.map import TsdfCfg, TsdfMap

    frames = truth_frames(truth, orbit_poses((0, 0, 0.5), 2.2, 1.0, 16), pinhole(160, 120, 131.25), 160, 120,
                          noise_seed=None)
    tsdf = TsdfMap(TsdfCfg(depth_max_m=5.0))
    for frame in shifted(frames):
        tsdf.integrate(frame)
    return tsdf.dense()


def test_esdf_is_the_exact_edt_of_the_maps_occupancy(mapped):
    esdf = esdf_from_grid(mapped, max_distance_m=1.0)
    exact = ndimage.distance_transform_edt(~mapped.occupied().numpy()) * mapped.voxel_size_m
    seen = esdf.observed.numpy() & (exact < 1.0)
    assert np.abs(esdf.distance_m.numpy()[seen] - exact[seen]).max() <= 1e-5 + 0.5 * mapped.voxel_size_m * 1e-3


def test_observed_free_space_esdf_is_within_half_a_voxel_of_the_true_edt(mapped, room):
    """Against the exact EDT of the true geometry voxelized on the same grid. Misses come from the
    projective TSDF marking a few voxels in an object's shadow as behind a surface."""
    esdf = esdf_from_grid(mapped, max_distance_m=1.0)
    centres = mapped.centres_m().numpy() - OFFSET
    inside = centres[..., 2] <= 0
    for box in room.solids:
        inside |= box.contains(centres.reshape(-1, 3)).reshape(inside.shape)
    exact = ndimage.distance_transform_edt(~inside) * mapped.voxel_size_m
    free_seen = esdf.observed.numpy() & (mapped.tsdf.numpy() > 0) & ~inside & (exact < 1.0)
    err = np.abs(esdf.distance_m.numpy()[free_seen] - exact[free_seen])
    assert free_seen.sum() > 10000
    assert np.median(err) < 1e-4
    assert (err <= 0.5 * mapped.voxel_size_m).mean() >= 0.9  # 91 % at 160x120, 93 % at 320x240


def test_signed_esdf_is_negative_inside(mapped):
    esdf = esdf_from_grid(mapped, max_distance_m=1.0, signed=True)
    occupied = mapped.occupied()
    assert (esdf.distance_m[occupied] < 0).all()
    assert (esdf.distance_m[~occupied & esdf.observed] > 0).all()


def test_edt_is_exact_at_the_window_edge_and_infinite_beyond():
    sites = torch.zeros(30, 30, dtype=torch.bool)
    sites[5, 5] = True
    d = edt(sites, 10)
    assert d[15, 5].item() == 10 and d[5, 15].item() == 10  # exactly max_cells along an axis
    assert d[11, 13].item() == 10  # (6, 8): a 6-8-10 triangle
    assert torch.isinf(d[15, 6]) and torch.isinf(d[16, 5])  # sqrt(101) and 11 cells: beyond


needs_warp = pytest.mark.skipif(not esdf_kernels.available(), reason="warp-lang is not installed")

KERNEL_CASES = [  # shape, site density, max_cells: non-cubic, size-1 axes, no / all sites, windows in and
    # beyond the grid, a non-integer limit
    ((64, 48), 0.01, 100), ((64, 48), 0.002, 7), ((1, 57), 0.05, 10), ((33, 1), 0.1, 3),
    ((40, 30, 20), 0.003, 12), ((23, 17, 41), 0.01, 6.5), ((29, 1, 13), 0.02, 9), ((1, 1, 50), 0.04, 5),
    ((19, 11, 7), 0.05, 1), ((12, 9, 15), 0.0, 8), ((12, 9, 15), 1.0, 8), ((7, 5, 3), 0.2, 1000), ((30,), 0.1, 4),
]


def _scipy_edt(sites: np.ndarray, max_cells: float) -> np.ndarray:
    """The exact EDT as ``edt`` returns it: float32, inf beyond max_cells or without sites."""
    if not sites.any():
        return np.full(sites.shape, np.inf, np.float32)
    exact = ndimage.distance_transform_edt(~sites).astype(np.float32)
    return np.where(exact <= np.float32(max_cells), exact, np.float32(np.inf))


@needs_warp
@pytest.mark.parametrize("shape,density,max_cells", KERNEL_CASES)
def test_kernel_edt_is_scipys_exact_edt_and_the_torch_reference(shape, density, max_cells):
    sites = np.random.default_rng(sum(shape) + int(density * 1e4)).random(shape) < density
    ours = esdf_kernels.exact_edt(torch.from_numpy(sites), max_cells)
    assert ours.dtype == torch.float32 and ours.shape == shape
    # bit for bit: squared distances are integers, and both round their square roots correctly
    # (the kernel's float32 sqrt is IEEE; edt_torch rounds a float64 sqrt, whatever the CPU)
    np.testing.assert_array_equal(ours.numpy(), _scipy_edt(sites, max_cells))
    np.testing.assert_array_equal(ours.numpy(), edt_torch(torch.from_numpy(sites), max_cells).numpy())


def test_edt_torch_rounds_square_roots_correctly_whatever_the_cpus_float32_sqrt(monkeypatch):
    """Some CPUs' vectorized float32 sqrt in torch is 1 ulp off (sqrt(34): 5.8309522, not
    5.8309517). edt_torch must not depend on it: made 1 ulp high here, the result is unchanged."""
    sqrt = torch.Tensor.sqrt

    def one_ulp_high(t: torch.Tensor) -> torch.Tensor:
        root = sqrt(t)
        return torch.nextafter(root, torch.full_like(root, float("inf"))) if t.dtype == torch.float32 else root

    sites = np.random.default_rng(5).random((40, 30, 20)) < 0.003
    monkeypatch.setattr(torch.Tensor, "sqrt", one_ulp_high)
    ours = edt_torch(torch.from_numpy(sites), 12).numpy()
    np.testing.assert_array_equal(ours, _scipy_edt(sites, 12))
    assert ours[np.isfinite(ours)].max() > 5  # non-trivial roots were taken


@needs_warp
@pytest.mark.parametrize("shape,density,max_cells", [KERNEL_CASES[i] for i in (0, 3, 5, 6, 9, 12)])
def test_kernel_edt_in_the_cuda_layout_is_exact(shape, density, max_cells):
    """CUDA's launch layout (a thread per line, the scratch k-major), run on the CPU."""
    sites = np.random.default_rng(sum(shape) + int(density * 1e4)).random(shape) < density
    ours = esdf_kernels.exact_edt(torch.from_numpy(sites), max_cells, thread_per_line=True)
    np.testing.assert_array_equal(ours.numpy(), _scipy_edt(sites, max_cells))


@needs_warp
@pytest.mark.parametrize("shape,density,max_cells", KERNEL_CASES)
def test_kernel_edt_in_the_window_layout_is_exact(shape, density, max_cells):
    """CUDA's default layout (a thread per cell searching its window along each axis), run on the CPU."""
    sites = np.random.default_rng(sum(shape) + int(density * 1e4)).random(shape) < density
    ours = esdf_kernels.exact_edt(torch.from_numpy(sites), max_cells, window=True)
    np.testing.assert_array_equal(ours.numpy(), _scipy_edt(sites, max_cells))


@needs_warp
def test_kernel_edt_is_the_same_split_over_threads():
    """CPU launches split the lines into one range per torch thread; uneven ranges change nothing."""
    sites = torch.from_numpy(np.random.default_rng(3).random((37, 29, 23)) < 0.01)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        one = esdf_kernels.exact_edt(sites, 10)
        torch.set_num_threads(3)
        three = esdf_kernels.exact_edt(sites, 10)
    finally:
        torch.set_num_threads(threads)
    assert torch.equal(one, three)
    np.testing.assert_array_equal(one.numpy(), _scipy_edt(sites.numpy(), 10))


@needs_warp
def test_edt_runs_the_kernels_when_warp_is_there(monkeypatch):
    calls = []
    monkeypatch.setattr(esdf_kernels, "exact_edt", lambda sites, max_cells: calls.append(sites.shape) or "kernel")
    assert edt(torch.zeros(4, 5, dtype=torch.bool), 3) == "kernel" and calls == [(4, 5)]
    assert torch.isinf(edt(torch.zeros(2, 2, 2, 2, dtype=torch.bool), 3)).all()  # 4-D: the torch path


@needs_warp
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_kernel_edt_on_cuda_is_exact():
    sites = torch.from_numpy(np.random.default_rng(4).random((45, 38, 27)) < 0.01)
    for max_cells in (5, 40):
        np.testing.assert_array_equal(esdf_kernels.exact_edt(sites.cuda(), max_cells).cpu().numpy(),
                                      _scipy_edt(sites.numpy(), max_cells))


@needs_warp
def test_the_fused_cuda_esdf_gives_the_general_paths_values(mapped):
    """``esdf_kernels.occupancy_esdf`` (CUDA's fused path: masks in one pass, clamp and unit in the last
    window pass), run on the CPU: bit-equal to ``esdf_from_grid``'s general path."""
    general = esdf_from_grid(mapped, max_distance_m=1.0)
    max_cells = int(round(1.0 / mapped.voxel_size_m))
    dist, observed = esdf_kernels.occupancy_esdf(mapped.tsdf, mapped.weight, 1.0, max_cells, mapped.voxel_size_m)
    assert torch.equal(observed, general.observed)
    assert torch.equal(dist, general.distance_m) and (dist < 1.0).sum() > 1000
