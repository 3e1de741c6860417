"""The voxel-block hash: keys round-trip, lookups and inserts agree with a Python dict."""

import numpy as np
import pytest
import torch

from ambulo.perception.tsdf.block_hash import MAX_BLOCK_INDEX, BlockHash, decode, encode


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
    from ambulo.perception.tsdf.map import TsdfCfg, TsdfMap

    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05))
    n = int(50 / tsdf.cfg.block_size_m)
    ix, iy, iz = torch.meshgrid(torch.arange(n), torch.arange(n), torch.tensor([-1, 0]), indexing="ij")
    tsdf.hash.insert(torch.stack([ix, iy, iz], -1).reshape(-1, 3))
    tsdf._grow(len(tsdf.hash))
    dense_bytes = (50 / 0.05) ** 2 * (3.0 / 0.05) * (4 + 4 + 3)  # 3 m tall room, same per-voxel storage
    assert tsdf.num_blocks == 2 * n * n
    assert tsdf.memory_bytes() < min(0.3 * dense_bytes, 256 * 2**20)


@pytest.mark.parametrize("on_host", [True, False], ids=["numpy-merge", "torch-merge"])
def test_many_growths_keep_the_table_sorted_and_its_buffers_in_place(on_host):
    """Inserts that outgrow the capacity again and again (both merges: the CPU's numpy one and the
    devices' torch one, run here on the CPU): keys stay sorted, every block keeps its slot, and the
    buffers a kernel binds are replaced only when the capacity doubles."""
    rng = np.random.default_rng(1)
    table, reference = BlockHash(capacity=4), {}
    table._on_host = on_host
    bound, replaced = (table.key_buffer, table.key_slot_buffer, table.slot_coord_buffer), 0
    for step in range(80):
        coords = torch.from_numpy(rng.integers(-25, 25, (int(rng.integers(1, 40)), 3)))
        capacity = table.capacity
        if step % 3:
            slots = table.insert(coords)
        else:  # unsorted new keys, sorted by the table
            new = torch.unique(encode(coords))
            new = new[table.find(decode(new)) < 0]
            table.append(new[torch.from_numpy(rng.permutation(len(new)))], presorted=False)
            slots = table.find(coords)
        for c, s in zip(coords.tolist(), slots.tolist()):
            assert reference.setdefault(tuple(c), s) == s
        now = (table.key_buffer, table.key_slot_buffer, table.slot_coord_buffer)
        if table.capacity == capacity:
            assert all(a is b for a, b in zip(now, bound))  # updated in place
        else:
            assert table.capacity >= 2 * capacity and all(a is not b for a, b in zip(now, bound))
            replaced += 1
        bound = now
        keys = table.keys
        assert len(keys) == len(reference) and bool((keys[1:] > keys[:-1]).all())
    assert 5 <= replaced <= 10 and table.capacity < 2 * len(table)  # 4 -> 8 -> ... geometric, not per insert
    assert sorted(table.key_slots.tolist()) == list(range(len(table)))
    assert torch.equal(table.key_slots, table.find(decode(table.keys)))
    expected = torch.tensor(sorted(reference, key=reference.get))
    assert torch.equal(table.slot_coords, expected)  # coordinates by slot
    probe = torch.from_numpy(rng.integers(-30, 30, (500, 3)))
    assert table.find(probe).tolist() == [reference.get(tuple(c), -1) for c in probe.tolist()]
