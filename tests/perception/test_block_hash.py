"""The voxel-block hash: keys round-trip, lookups and inserts agree with a Python dict."""

import numpy as np
import pytest
import torch

from ambulo.perception.block_hash import MAX_BLOCK_INDEX, BlockHash, decode, encode


def test_keys_round_trip_including_negative_and_extreme_coordinates():
    coords = torch.tensor([[0, 0, 0], [-1, 2, -3], [MAX_BLOCK_INDEX, -MAX_BLOCK_INDEX, 7], [123, -456, 789]])
    assert torch.equal(decode(encode(coords)), coords)
    assert torch.equal(decode(encode(coords), BlockHash()._shifts), coords)  # the hash's 3-op form
    assert len(set(encode(coords).tolist())) == len(coords)


def test_insert_and_find_match_a_dict():
    rng = np.random.default_rng(0)
    table, reference = BlockHash(), {}
    for _ in range(5):
        coords = torch.from_numpy(rng.integers(-40, 40, (300, 3)))
        slots = table.insert(coords)
        for c, s in zip(coords.tolist(), slots.tolist()):
            reference.setdefault(tuple(c), s)
            assert reference[tuple(c)] == s  # a block keeps its slot
    assert len(table) == len(reference)
    assert sorted(reference.values()) == list(range(len(reference)))  # slots 0..n-1, none lost
    probe = torch.from_numpy(rng.integers(-50, 50, (500, 3)))
    found = table.find(probe).tolist()
    for c, s in zip(probe.tolist(), found):
        assert s == reference.get(tuple(c), -1)
    assert torch.equal(table.slot_coords[torch.tensor(list(reference.values()))],
                       torch.tensor(list(reference.keys())))


def test_out_of_range_coordinates_are_refused():
    with pytest.raises(ValueError, match="key range"):
        BlockHash().insert(torch.tensor([[MAX_BLOCK_INDEX + 1, 0, 0]]))


def test_a_50m_floor_fits_in_sparse_blocks():
    """A 50 m x 50 m floor at 5 cm: two layers of 0.4 m blocks, far less than the dense grid."""
    from ambulo.perception.tsdf import TsdfCfg, TsdfMap

    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05))
    n = int(50 / tsdf.cfg.block_size_m)
    ix, iy, iz = torch.meshgrid(torch.arange(n), torch.arange(n), torch.tensor([-1, 0]), indexing="ij")
    tsdf.hash.insert(torch.stack([ix, iy, iz], -1).reshape(-1, 3))
    tsdf._grow(len(tsdf.hash))
    dense_bytes = (50 / 0.05) ** 2 * (3.0 / 0.05) * (4 + 4 + 3)  # 3 m tall room, same per-voxel storage
    assert tsdf.num_blocks == 2 * n * n
    assert tsdf.memory_bytes() < min(0.3 * dense_bytes, 256 * 2**20)
