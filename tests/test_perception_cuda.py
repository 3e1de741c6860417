"""CPU/GPU parity of ``ambulo.perception``'s mapping: the same frames through the CPU map (torch
reference backend) and the CUDA map (Warp kernels) give the same TSDF; the ESDF and the box ray
caster agree across devices. Skipped without a CUDA device (the lead runs them on the GPU machine;
this file sits outside tests/perception because that folder needs Open3D, which the GPU machine
lacks)."""

import dataclasses

import numpy as np
import pytest
import torch

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")


def _frames(count: int, width: int = 160, height: int = 120):
    from ambulo.perception.box_raycast import raycast_frames
    from ambulo.perception.reference import orbit_poses
    from ambulo.scenes.indoor import IndoorSceneCfg, build_indoor_scene

    scene = build_indoor_scene(IndoorSceneCfg(with_robot=False, num_moving_boxes=0))
    f = 525.0 * width / 640
    k = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1.0]])
    frames = raycast_frames(scene.solids, orbit_poses((0, 0, 0.5), 2.2, 1.0, count), k, width, height, noise_seed=1)
    gen = torch.Generator().manual_seed(0)
    for i, frame in enumerate(frames):
        frame.pose_wc[:3, 3] += torch.tensor([0.013, 0.021, 0.017], dtype=torch.float64)
        frame.depth_m[i::7, ::5] = float("nan")  # holes, as a real sensor has
        frame.rgb = torch.randint(0, 256, frame.rgb.shape, dtype=torch.uint8, generator=gen)
    return frames


@pytest.mark.parametrize("capacity,cfg", [(1024, {}), (8, {}), (1024, {"depth_max_m": 60.0})],
                         ids=["graph", "graph-growing", "eager-sorted-allocation"])
def test_cuda_tsdf_equals_the_cpu_reference(capacity, cfg):
    """The CUDA frame as one captured graph (capacity 8: early frames overflow, are skipped whole, the
    storage grows and they are replayed), and the eager launches where the depth range is too deep for
    the dense volume, against the CPU torch reference."""
    pytest.importorskip("warp")
    from ambulo.perception.tsdf.map import TsdfCfg, TsdfMap

    cpu = TsdfMap(TsdfCfg(**cfg), backend="torch")
    gpu = TsdfMap(TsdfCfg(**cfg), device="cuda", capacity=capacity)
    for frame in _frames(8):
        cpu.integrate(frame)
        gpu.integrate(type(frame)(frame.depth_m.cuda(), frame.rgb.cuda(), frame.intrinsics, frame.pose_wc,
                                  frame.time_s))
    a, b = cpu.dense(), gpu.dense()
    assert gpu.backend == "warp" and torch.equal(a.origin_index, b.origin_index.cpu())
    assert (a.weight > 0).sum() > 5000
    assert cpu.num_blocks == gpu.num_blocks and torch.equal(cpu.block_coords(), gpu.block_coords().cpu())
    if cfg:  # the eager path's torch allocation on CUDA: float rounding moved 1 voxel of ~1 M once
        differ = ((b.weight.cpu() - a.weight).abs() > 1e-4) | ((b.tsdf.cpu() - a.tsdf).abs() > 1e-4)
        assert differ.sum() <= 1e-5 * differ.numel()
        return
    torch.testing.assert_close(b.weight.cpu(), a.weight, atol=1e-4, rtol=0)
    torch.testing.assert_close(b.tsdf.cpu(), a.tsdf, atol=1e-4, rtol=0)
    assert (b.color.cpu().int() - a.color.int()).abs().max() <= 1
    # the fused CUDA ESDF of the map: the same values as the CPU's general path
    from ambulo.perception.esdf import esdf_from_grid

    on_gpu = dataclasses.replace(a, tsdf=a.tsdf.cuda(), weight=a.weight.cuda(), color=a.color.cuda())
    e_cpu, e_gpu = esdf_from_grid(a, 1.0), esdf_from_grid(on_gpu, 1.0)
    assert torch.equal(e_gpu.observed.cpu(), e_cpu.observed) and (e_cpu.distance_m < 1.0).sum() > 1000
    assert torch.equal(e_gpu.distance_m.cpu(), e_cpu.distance_m)


def test_cuda_esdf_equals_the_cpu_esdf():
    from ambulo.perception.esdf import edt

    gen = torch.Generator().manual_seed(0)
    sites = torch.rand((70, 45, 23), generator=gen) < 0.01
    from ambulo.perception.esdf_kernels import exact_edt

    for max_cells in (3, 12, 40):
        cpu = edt(sites, max_cells)
        assert torch.equal(edt(sites.cuda(), max_cells).cpu(), cpu)  # the window layout
        assert torch.equal(exact_edt(sites.cuda(), max_cells, window=False).cpu(), cpu)  # a thread per line


def test_cuda_box_raycast_equals_the_cpu_one():
    from ambulo.perception.box_raycast import box_depth
    from ambulo.perception.reference import orbit_poses
    from ambulo.scenes.indoor import IndoorSceneCfg, build_indoor_scene

    scene = build_indoor_scene(IndoorSceneCfg(with_robot=False, num_moving_boxes=0))
    k = np.array([[131.25, 0, 79.5], [0, 131.25, 59.5], [0, 0, 1.0]])
    pose = orbit_poses((0, 0, 0.5), 2.2, 1.0, 1)[0]
    cpu = box_depth(scene.solids, k, pose, 160, 120)
    torch.testing.assert_close(box_depth(scene.solids, k, pose, 160, 120, device="cuda").cpu(), cpu, atol=1e-5, rtol=0)
