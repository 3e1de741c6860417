"""The windowed exact EDT against scipy, and the map's ESDF against the exact EDT of the truth."""

import numpy as np
import pytest
import torch
from scipy import ndimage

from ambulo.perception.esdf import edt, esdf_from_grid

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
    from ambulo.perception.tsdf import TsdfCfg, TsdfMap

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
