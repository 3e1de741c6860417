"""A face seen at a grazing angle keeps its cell in the occupancy (``slices.surface_voxels``): the
projective sdf overstates the distance to it by 1 / cos(incidence) on both sides of the surface, so the
threshold test (sdf < half a voxel) alone put the face a voxel behind where it is (door jambs, walls
seen along them: the navigator's forearms brushed them), while the zero crossing interpolated between
two voxel centres is where the surface is."""

import pytest
import torch

from ambulo.perception.slices import surface_voxels

TRUNC_VOX = 4.0
"""Truncation in voxels (``TsdfCfg.truncation_voxels``)."""


def _row(surface_x_vox: float, stretch: float) -> tuple[torch.Tensor, torch.Tensor]:
    """(tsdf normalised by the truncation, weight) of 6 voxels along x (centres 0..5 voxels) in front of a
    solid that fills x > ``surface_x_vox``, as a projective TSDF sees it at an incidence with
    1 / cos = ``stretch``; shape (6, 1, 1)."""
    x = torch.arange(6, dtype=torch.float32)
    sdf_vox = ((surface_x_vox - x) * stretch).clamp(-TRUNC_VOX, TRUNC_VOX)
    return (sdf_vox / TRUNC_VOX).reshape(6, 1, 1), torch.ones(6, 1, 1)


def _occupied_free(surface_x_vox: float, stretch: float) -> tuple[list[bool], list[bool]]:
    tsdf, weight = _row(surface_x_vox, stretch)
    occ, free = surface_voxels(tsdf, weight, truncation_m=TRUNC_VOX * 0.05, voxel_size_m=0.05)
    return occ.flatten().tolist(), free.flatten().tolist()


@pytest.mark.parametrize("stretch", [1.0, 1.6, 2.5, 3.5])
def test_the_cell_that_holds_a_face_is_occupied_at_any_incidence(stretch):
    # the face at 2.3 voxels lies in voxel 2's cell (1.5-2.5): head on its sdf there is 0.3 voxel, at a
    # grazing view 0.3 * stretch (0.75 at 2.5: "free" by the threshold alone)
    occ, free = _occupied_free(2.3, stretch)
    assert occ[2] and not free[2], (stretch, occ, free)
    assert not any(occ[:2]) and all(free[:2])  # the free space in front stays free


@pytest.mark.parametrize("stretch", [1.0, 2.5, 3.5])
def test_the_cell_in_front_of_a_face_stays_free_at_any_incidence(stretch):
    # the face at 2.7 voxels lies in voxel 3's cell: voxel 2 (0.7 voxel in front) is free whatever the angle
    occ, free = _occupied_free(2.7, stretch)
    assert free[2] and not occ[2], (stretch, occ, free)
    assert occ[3]
