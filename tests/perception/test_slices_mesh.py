"""2-D slices, the height / steppability map and meshes of small hand-made scenes."""

import numpy as np
import pytest
import torch

from ambulo.perception import RgbdFrame, TsdfCfg, TsdfMap, height_map, occupancy_slice
from ambulo.perception.mesh import IncrementalMesher, extract_mesh, write_ply
from ambulo.perception.reference import TruthScene, orbit_poses
from ambulo.scenes.indoor import SolidBox

from .conftest import pinhole

STEP = SolidBox("step", (0.6, 0.0, 0.075), (0.3, 0.5, 0.075))
"""A 15 cm step (a stair tread) on the floor."""
POST = SolidBox("post", (-0.6, 0.3, 0.6), (0.1, 0.1, 0.6))
"""A 1.2 m post: an obstacle in the body's height band."""


@pytest.fixture(scope="module")
def step_map():
    truth = TruthScene([STEP, POST], floor_half_m=3.0)
    k = pinhole(160, 120, 131.25)
    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05))
    for pose in orbit_poses((0.0, 0.0, 0.0), 1.8, 1.4, 24):
        depth = truth.depth(k, pose, 160, 120)
        tsdf.integrate(RgbdFrame(torch.from_numpy(depth), None, torch.from_numpy(k), torch.from_numpy(pose)))
    return tsdf


def test_occupancy_slice_marks_the_post_and_not_the_floor(step_map):
    occ = occupancy_slice(step_map.dense(), 0.3, 1.6)
    # the post's four faces are occupied; its inside, 2 voxels from every face, is not free (never seen)
    for face in ((-0.7, 0.3), (-0.5, 0.3), (-0.6, 0.2), (-0.6, 0.4)):
        assert occ.data[occ.cell_of(face)] == 1, face
    assert occ.data[occ.cell_of((-0.6, 0.3))] != 0
    assert occ.data[occ.cell_of((0.0, -1.0))] == 0  # floor only: free in the band
    assert occ.data[occ.cell_of((0.6, 0.0))] == 0  # the step is below the band
    low = occupancy_slice(step_map.dense(), 0.05, 0.3)
    assert low.data[low.cell_of((0.6, 0.0))] == 1


def test_height_map_finds_floor_and_step_tops_and_steppable_cells(step_map):
    hm = height_map(step_map.dense(), max_height_m=0.5, clearance_m=1.6)
    h, ok = hm.height_m, hm.steppable
    assert h.data[h.cell_of((0.6, 0.0))].item() == pytest.approx(0.15, abs=0.015)  # step top
    assert h.data[h.cell_of((0.0, -1.0))].item() == pytest.approx(0.0, abs=0.015)  # floor
    assert ok.data[ok.cell_of((0.6, 0.0))]  # the middle of the tread holds a foot
    assert ok.data[ok.cell_of((0.0, -1.0))]
    assert not ok.data[ok.cell_of((0.3, 0.0))]  # the step's edge is under the foot window
    assert not ok.data[ok.cell_of((-0.6, 0.3))]  # under/at the post


def test_incremental_mesh_equals_the_whole_map_mesh(step_map):
    whole = extract_mesh(step_map.dense())
    step_map.updated[: step_map.num_blocks] = True  # everything changed since "last time"
    parts = IncrementalMesher(step_map).update()
    assert len(parts.faces) == len(whole.faces)
    a = np.unique(np.round(whole.vertices, 4), axis=0)
    b = np.unique(np.round(parts.vertices, 4), axis=0)
    assert a.shape == b.shape and np.abs(a - b).max() < 1e-3


def test_incremental_mesher_remeshes_only_changed_blocks(step_map):
    mesher = IncrementalMesher(step_map)
    step_map.updated[: step_map.num_blocks] = True
    mesher.update()
    before = dict(mesher.blocks)
    assert step_map.clear_updated().numel() == 0
    mesher.update()
    assert all(mesher.blocks[k] is before[k] for k in before)


def test_ply_file_reads_back_in_open3d(step_map, tmp_path):
    import open3d as o3d

    mesh = extract_mesh(step_map.dense())
    path = write_ply(tmp_path / "mesh.ply", mesh)
    back = o3d.io.read_triangle_mesh(str(path))
    assert len(back.vertices) == len(mesh.vertices) and len(back.triangles) == len(mesh.faces)
    np.testing.assert_allclose(np.asarray(back.vertices), mesh.vertices, atol=1e-6)
    assert back.has_vertex_colors()
