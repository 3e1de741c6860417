"""TSDF integration: the projective signed distance at voxels, accuracy against Open3D's
VoxelBlockGrid on identical frames with exact ground truth, and a moved obstacle cleared."""

import numpy as np
import pytest
import torch

from ambulo.perception import RgbdFrame, TsdfCfg, TsdfMap, occupancy_slice
from ambulo.perception.mesh import extract_mesh

from ..conftest import OFFSET, pinhole, shifted


def _plane_frame(depth_m: float, width=64, height=48) -> RgbdFrame:
    """A camera at the origin looking along +z at a wall z = depth_m (world = camera frame)."""
    depth = torch.full((height, width), depth_m, dtype=torch.float32)
    rgb = torch.full((height, width, 3), 200, dtype=torch.uint8)
    return RgbdFrame(depth, rgb, torch.from_numpy(pinhole(width, height, 40.0)), torch.eye(4, dtype=torch.float64))


def test_voxels_on_the_optical_axis_store_the_truncated_distance_to_the_wall():
    cfg = TsdfCfg(voxel_size_m=0.05, truncation_voxels=4)
    tsdf = TsdfMap(cfg)
    tsdf.integrate(_plane_frame(1.0))
    grid = tsdf.dense()
    centres = grid.centres_m()
    on_axis = (centres[..., 0].abs() < 1e-9) & (centres[..., 1].abs() < 1e-9) & (grid.weight > 0)
    z = centres[..., 2][on_axis]
    expected = ((1.0 - z) / cfg.truncation_m).clamp(max=1.0)
    torch.testing.assert_close(grid.tsdf[on_axis].double(), expected, atol=1e-5, rtol=0)
    assert z.max() <= 1.0 + cfg.truncation_m + 1e-6  # nothing behind the band is touched
    # the ray from the camera to the wall is observed free (TsdfCfg.free_space_stride), from the first
    # voxel in front of the camera on
    assert z.min() == pytest.approx(cfg.voxel_size_m) and (grid.tsdf[on_axis & (centres[..., 2] < 0.8)] == 1).all()
    assert (grid.color[on_axis] == 200).all()


def test_weights_average_two_observations():
    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05))
    tsdf.integrate(_plane_frame(1.0))
    tsdf.integrate(_plane_frame(1.1))
    grid = tsdf.dense()
    centres = grid.centres_m()
    voxel = (centres[..., 0].abs() < 1e-9) & (centres[..., 1].abs() < 1e-9) & ((centres[..., 2] - 1.0).abs() < 1e-9)
    assert grid.weight[voxel].item() == 2
    assert grid.tsdf[voxel].item() == pytest.approx((0.0 + 0.1 / 0.2) / 2, abs=1e-5)


def test_integrate_without_a_pose_says_what_is_missing():
    frame = _plane_frame(1.0)
    frame.pose_wc = None
    with pytest.raises(ValueError, match="pose_wc"):
        TsdfMap().integrate(frame)


@pytest.fixture(scope="module")
def noisy_frames(truth):
    from ambulo.perception.reference import orbit_poses, truth_frames

    poses = orbit_poses((0, 0, 0.5), 2.2, 1.0, 16)
    return shifted(truth_frames(truth, poses, pinhole(320, 240, 262.5), 320, 240, noise_seed=0))


def test_mesh_is_at_least_as_accurate_as_open3d_on_identical_frames(noisy_frames, truth):
    """Mean and p95 mesh-to-truth distance no worse than Open3D's VoxelBlockGrid, both at 5 cm,
    truncation 4 voxels, depth up to 5 m, noise 0.002 z^2, meshes from voxels seen twice."""
    from ambulo.perception.reference import open3d_tsdf

    ref = open3d_tsdf(noisy_frames, 0.05, 4.0, 5.0, weight_threshold=1.0)  # Open3D keeps weight > 1
    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05, truncation_voxels=4.0, depth_max_m=5.0))
    for frame in noisy_frames:
        tsdf.integrate(frame)
    mesh = extract_mesh(tsdf.dense(), min_weight=2.0)
    ours = truth.distance(mesh.vertices - OFFSET)
    theirs = truth.distance(ref.vertices - OFFSET)
    assert len(ours) > 0.6 * len(theirs)  # not accurate by leaving surfaces out
    assert ours.mean() <= theirs.mean()
    assert np.percentile(ours, 95) <= np.percentile(theirs, 95)


def test_a_box_that_moves_away_is_cleared_from_the_slice_within_5_frames(room):
    """A 0.4 m box in front of the camera for 10 frames, then gone: the occupancy slice at its
    place must be free again within 5 frames (nvblox / voxblox users report seconds)."""
    from ambulo.perception.reference import TruthScene, orbit_poses
    from ambulo.scenes.indoor import SolidBox

    box = SolidBox("box", (0.0, -1.2, 0.2), (0.2, 0.2, 0.2))
    with_box, without_box = TruthScene(room.solids + [box]), TruthScene(room.solids)
    k = pinhole(160, 120, 131.25)
    pose = orbit_poses((0.0, -1.2, 0.2), 1.6, 0.8, 1)[0]
    tsdf = TsdfMap(TsdfCfg())
    seen_at = []
    for i in range(20):
        scene = with_box if i < 10 else without_box
        depth = scene.depth(k, pose, 160, 120)
        tsdf.integrate(RgbdFrame(torch.from_numpy(depth), None, torch.from_numpy(k), torch.from_numpy(pose)))
        occ = occupancy_slice(tsdf.dense(), 0.1, 0.35)
        seen_at.append(occ.data[occ.cell_of((0.0, -1.2))].item())
        if i == 9:  # the box was mapped: its faces occupied (its inside, never seen, is not free)
            iy, ix = occ.cell_of((0.0, -1.2))
            assert (occ.data[iy - 4:iy + 5, ix - 4:ix + 5] == 1).sum() >= 8
    assert seen_at[9] != 0
    cleared = next(i for i in range(10, 20) if seen_at[i] == 0)
    assert cleared - 10 < 5
    assert all(v == 0 for v in seen_at[cleared:])


def test_without_free_space_clearing_the_box_lingers(room):
    """The same scenario with clearing off: plain weighted averaging keeps the box for longer (with
    clearing the first frame without it frees its cell), so the test above checks the clearing rule,
    not a property of any TSDF."""
    from ambulo.perception.reference import TruthScene, orbit_poses
    from ambulo.scenes.indoor import SolidBox

    box = SolidBox("box", (0.0, -1.2, 0.2), (0.2, 0.2, 0.2))
    with_box, without_box = TruthScene(room.solids + [box]), TruthScene(room.solids)
    k = pinhole(160, 120, 131.25)
    pose = orbit_poses((0.0, -1.2, 0.2), 1.6, 0.8, 1)[0]
    tsdf = TsdfMap(TsdfCfg(clear_free_space=False))
    for i in range(11):
        depth = (with_box if i < 10 else without_box).depth(k, pose, 160, 120)
        tsdf.integrate(RgbdFrame(torch.from_numpy(depth), None, torch.from_numpy(k), torch.from_numpy(pose)))
    occ = occupancy_slice(tsdf.dense(), 0.1, 0.35)
    assert occ.data[occ.cell_of((0.0, -1.2))].item() == 1


def _reference_single_frame(tsdf: TsdfMap, frame: RgbdFrame, border_px: float = 1.0):
    """Brute force for one frame into an empty map: every voxel of every allocated block projected
    and looked up with ``sample_depth`` (bilinear, nearest across depth edges). Returns the voxels
    projecting at least ``border_px`` inside the image, and their expected weight and tsdf."""
    from ambulo.perception.tsdf.reference import sample_depth

    cfg = tsdf.cfg
    depth = frame.depth_m.float()
    valid = torch.isfinite(depth) & (depth >= cfg.depth_min_m) & (depth <= cfg.depth_max_m)
    depth = torch.where(valid, depth, torch.zeros_like(depth))
    h, w = depth.shape
    centres = tsdf.voxel_index().reshape(-1, 3).double() * cfg.voxel_size_m
    pose_cw = torch.linalg.inv(frame.pose_wc)
    pc = centres @ pose_cw[:3, :3].T + pose_cw[:3, 3]
    k = frame.intrinsics
    z = pc[:, 2]
    u = pc[:, 0] / z.clamp(min=1e-6) * k[0, 0] + k[0, 2]
    v = pc[:, 1] / z.clamp(min=1e-6) * k[1, 1] + k[1, 2]
    d, _, in_image = sample_depth(depth, u.float(), v.float())
    sdf = d.double() - z
    trunc = cfg.truncation_m
    update = in_image & (z > 0) & (d > 0) & (sdf >= -trunc)
    inner = (u >= border_px) & (u <= w - 1 - border_px) & (v >= border_px) & (v <= h - 1 - border_px)
    # a projection within 1e-3 px of a half-pixel tie rounds to either nearest pixel (float32 here and there)
    tie = ((u - u.floor() - 0.5).abs() < 1e-3) | ((v - v.floor() - 0.5).abs() < 1e-3)
    inner &= ~tie
    # behind the surface by more than a voxel the weight drops linearly to 0 at -trunc (TsdfCfg.weight_dropoff)
    dropoff = torch.where(sdf < -cfg.dropoff_m, (sdf + trunc) / (trunc - cfg.dropoff_m), torch.ones_like(sdf))
    return inner | (z <= 0), (update * dropoff).float(), (sdf / trunc).clamp(max=1.0).float()


@pytest.mark.parametrize("depth_max_m", [5.0, 60.0])  # 60 m: blocks deduplicated by sorting, not in a volume
def test_each_voxel_gets_the_brute_force_projective_update(truth, depth_max_m):
    """One noisy frame of the room: every voxel of the allocated blocks holds exactly what a per-voxel
    projection and depth lookup gives (the integration only skips voxels that can not be updated)."""
    from ambulo.perception.reference import orbit_poses, truth_frames

    frame = shifted(truth_frames(truth, orbit_poses((0, 0, 0.5), 2.2, 1.0, 3)[1:2], pinhole(160, 120, 131.25),
                                 160, 120, noise_seed=1))[0]
    frame.depth_m[::7, ::5] = float("nan")  # holes, as a real sensor gives
    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05, depth_max_m=depth_max_m))
    tsdf.integrate(frame)
    # blocks: those the band [d - trunc, d + trunc] of every allocation_stride-th valid pixel touches
    cfg, s = tsdf.cfg, tsdf.cfg.allocation_stride
    d = frame.depth_m[::s, ::s].double()
    keep = torch.isfinite(d) & (d >= cfg.depth_min_m) & (d <= cfg.depth_max_m)
    k = frame.intrinsics
    vs, us = torch.meshgrid(torch.arange(0, 120, s, dtype=torch.float64), torch.arange(0, 160, s, dtype=torch.float64),
                            indexing="ij")
    rays = torch.stack([(us - k[0, 2]) / k[0, 0], (vs - k[1, 2]) / k[1, 1], torch.ones_like(us)], -1)[keep]
    band = torch.cat([rays * (d[keep] + o)[:, None] for o in (-cfg.truncation_m, 0.0, cfg.truncation_m)])
    # ... and those of free space: every free_space_stride-th of those rays at depths 0, step, ... < d - trunc
    carve_rows = (torch.arange(keep.shape[0]) % cfg.free_space_stride == 0)[:, None]
    carve_cols = (torch.arange(keep.shape[1]) % cfg.free_space_stride == 0)[None, :]
    on = (carve_rows & carve_cols)[keep]
    steps = torch.arange(0, 60) * cfg.free_space_step_m
    ahead = steps[None, :] < (d[keep] - cfg.truncation_m)[:, None]
    free = (rays[:, None, :] * steps[None, :, None])[on[:, None] & ahead]
    assert len(free) > 1000
    band = torch.cat([band, free])
    world = band @ frame.pose_wc[:3, :3].T + frame.pose_wc[:3, 3]
    blocks = torch.div(torch.round(world / cfg.voxel_size_m).long(), cfg.block_voxels, rounding_mode="floor")
    assert {tuple(b) for b in blocks.tolist()} == {tuple(b) for b in tsdf.block_coords().tolist()}
    check, weight, expected = _reference_single_frame(tsdf, frame)
    ours_w, ours_t = tsdf.weight[: tsdf.num_blocks].reshape(-1), tsdf.tsdf[: tsdf.num_blocks].reshape(-1)
    assert weight.sum() > 5000
    torch.testing.assert_close(ours_w[check], weight[check], atol=2e-4 / 0.15, rtol=0)
    assert torch.equal(ours_w[check] > 0, weight[check] > 0)
    hit = check & (weight > 0)
    torch.testing.assert_close(ours_t[hit], expected[hit], atol=2e-4, rtol=0)


def test_a_frame_without_valid_depth_changes_nothing():
    """A covered lens (no depth, NaN holes, readings beyond range) into an empty and a mapped map."""
    blank = _plane_frame(1.0)
    blank.depth_m[:] = 0.0
    blank.depth_m[::3] = float("nan")
    blank.depth_m[1::5] = 50.0  # beyond depth_max_m
    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05))
    tsdf.integrate(blank)
    assert tsdf.num_blocks == 0
    tsdf.integrate(_plane_frame(1.0))
    before = tsdf.tsdf.clone(), tsdf.weight.clone()
    tsdf.integrate(blank)
    assert torch.equal(tsdf.tsdf, before[0]) and torch.equal(tsdf.weight, before[1])


def _integrate_both(frames, cfg, **warp_options):
    """The same frames through the fused Warp kernels and through the torch reference ops."""
    maps = {"warp": TsdfMap(cfg, backend="warp", **warp_options), "torch": TsdfMap(cfg, backend="torch")}
    for frame in frames:
        for tsdf in maps.values():
            tsdf.integrate(frame)
    return maps["warp"], maps["torch"]


@pytest.mark.parametrize("cfg", [TsdfCfg(), TsdfCfg(weight_ref_depth_m=1.5, max_weight=3.0, truncation_voxels=3.0),
                                 TsdfCfg(clear_free_space=False, depth_min_m=0.5, depth_max_m=3.0),
                                 TsdfCfg(depth_max_m=60.0)],
                         ids=["default", "weighted-saturating", "no-clearing-short-range", "sorted-allocation"])
def test_warp_kernels_give_the_torch_reference_result(truth, room, cfg):
    """Block allocation (the kernel's hash lookup and keys; at 60 m the sort-based fallback), the blocks
    selected for clearing, and the per-voxel update (projection, bilinear-unless-edge depth, truncation,
    free-space clearing, running averages, saturation, colour) of the Warp path equal the torch path's
    to float32 rounding: noisy frames with holes and random colour, then a box that appears and goes."""
    pytest.importorskip("warp", reason="warp-lang is not installed")
    _assert_warp_equals_torch(truth, room, cfg)


def test_block_marking_split_over_two_threads_gives_the_torch_reference_result(truth, room, monkeypatch):
    """The CPU's race-free split of ``mark_band_blocks`` (row ranges on 2 threads, each with its own
    stamp volume, key list and counters; blocks new to both ranges merged): the same map as torch."""
    pytest.importorskip("warp", reason="warp-lang is not installed")
    from ambulo.perception.tsdf import launches

    monkeypatch.setattr(launches, "PARTS", 2)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        ours = _assert_warp_equals_torch(truth, room, TsdfCfg())
    finally:
        torch.set_num_threads(threads)
    assert ours._launches.parts == 2


def test_the_frame_as_one_captured_graph_gives_the_torch_reference_result(truth, room):
    """``tsdf.graph``: the frame captured once and replayed (Warp's CPU capture here; a CUDA graph on the
    GPU), every count kept on the device, new keys merged into the hash by kernels. A capacity of 8
    blocks makes early frames overflow: each is skipped whole, the storage grows and the frame is
    replayed, and the map still equals the torch reference's."""
    pytest.importorskip("warp", reason="warp-lang is not installed")
    ours = _assert_warp_equals_torch(truth, room, TsdfCfg(), graph=True, capacity=8)
    assert ours._graph._graph is not None and ours.hash.capacity >= ours.num_blocks > 8


def _assert_warp_equals_torch(truth, room, cfg, **warp_options):
    from ambulo.perception.reference import TruthScene, orbit_poses, truth_frames
    from ambulo.scenes.indoor import SolidBox

    k = pinhole(160, 120, 131.25)
    frames = shifted(truth_frames(truth, orbit_poses((0, 0, 0.5), 2.2, 1.0, 6), k, 160, 120, noise_seed=2))
    gen = torch.Generator().manual_seed(0)
    for i, frame in enumerate(frames):
        frame.depth_m[i::7, ::5] = float("nan")
        frame.depth_m[::11, i::13] = float("inf")
        frame.rgb = torch.randint(0, 256, frame.rgb.shape, dtype=torch.uint8, generator=gen)
    box = SolidBox("box", (0.0, -1.2, 0.2), (0.2, 0.2, 0.2))
    pose = torch.from_numpy(orbit_poses((0.0, -1.2, 0.2), 1.6, 0.8, 1)[0])
    for i, scene in enumerate([TruthScene(room.solids + [box])] * 3 + [TruthScene(room.solids)] * 3):
        depth = torch.from_numpy(scene.depth(k, pose.numpy(), 160, 120))
        frames.append(RgbdFrame(depth, None if i % 2 else frames[i].rgb, torch.from_numpy(k), pose))
    ours, ref = _integrate_both(frames, cfg, **warp_options)
    n = ref.num_blocks
    assert ours.num_blocks == n and torch.equal(ours.block_coords(), ref.block_coords())
    assert (ref.weight[:n] > 0).sum() > 20000
    # weights to 1e-4: behind the surface an observation weighs (sdf + trunc) / (trunc - voxel) (the drop-off),
    # which scales the paths' float32 rounding of sdf (their tsdf agree to 1e-5 of trunc) by 1 / 0.15 m
    torch.testing.assert_close(ours.weight[:n], ref.weight[:n], atol=1e-4, rtol=0)
    torch.testing.assert_close(ours.tsdf[:n], ref.tsdf[:n], atol=1e-5, rtol=0)
    assert (ours.color[:n].int() - ref.color[:n].int()).abs().max() <= 1
    assert torch.equal(ours.updated[:n], ref.updated[:n]) and torch.equal(ours.has_surface[:n], ref.has_surface[:n])
    return ours


def test_frames_that_add_blocks_keep_the_recorded_launches_views(truth, monkeypatch):
    """The hash and the storage are capacity buffers updated in place: once the launches are recorded,
    a frame that adds blocks re-views (``wp.from_torch``) no tensor unless a capacity grew."""
    pytest.importorskip("warp", reason="warp-lang is not installed")
    from ambulo.perception.reference import orbit_poses, truth_frames
    from ambulo.perception.tsdf import launches

    frames = shifted(truth_frames(truth, orbit_poses((0, 0, 0.5), 2.2, 1.0, 12), pinhole(80, 60, 65.6), 80, 60,
                                  noise_seed=3))
    for frame in frames:
        frame.rgb = None  # a frame's own colour tensor is another object each frame
    tsdf = TsdfMap(TsdfCfg(), capacity=1 << 14, backend="warp")
    for _ in range(2):  # records the launches (the selection from the second frame on: none before)
        tsdf.integrate(frames[0])
    views = []
    view = launches._view
    monkeypatch.setattr(launches, "_view", lambda t: views.append(t) or view(t))
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # one voxel launch (more threads record a launch per block range as blocks come)
    try:
        added = 0
        for frame in frames[1:]:
            before = tsdf.num_blocks
            tsdf.integrate(frame)
            added += tsdf.num_blocks > before
    finally:
        torch.set_num_threads(threads)
    assert added >= 5 and tsdf.hash.capacity == 1 << 14 and views == []
