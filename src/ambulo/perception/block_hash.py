"""A hash of voxel blocks in plain torch: the same code on the CPU and on CUDA.

nvblox and Open3D (ASH, Dong et al. TPAMI 2023) allocate a map in blocks of 8^3 voxels found
through a GPU hash table, so memory follows the observed surface rather than the bounding box
(a 50 m x 50 m floor at 5 cm is ~16k blocks of 0.4 m, not a dense 1000 x 1000 x 60 grid). Here
the table is a *sorted* array of 64-bit block keys: lookup is ``torch.searchsorted`` (a batched
binary search, one kernel on either device) and insertion merges the new keys with one sort, so
there is no per-key Python and no custom kernel. A block's storage slot never moves.
"""

from __future__ import annotations

import torch

_BITS = 20
_OFFSET = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1
MAX_BLOCK_INDEX = _OFFSET - 1
"""Largest |block coordinate| a key holds (2^19 blocks of 0.4 m: 200 km either way)."""


def raise_out_of_range() -> None:
    raise ValueError(f"block coordinates beyond +-{MAX_BLOCK_INDEX}: the map would span more than "
                     "the key range; check the poses and depth units (metres)")


def encode(coords: torch.Tensor) -> torch.Tensor:
    """(N, 3) int64 block coordinates -> (N,) int64 keys (20 bits per axis, offset to be >= 0)."""
    c = coords.to(torch.int64) + _OFFSET
    return (c[:, 0] << (2 * _BITS)) | (c[:, 1] << _BITS) | c[:, 2]


def decode(keys: torch.Tensor, shifts: torch.Tensor | None = None) -> torch.Tensor:
    """(N,) keys -> (N, 3) int64 block coordinates (inverse of ``encode``). ``shifts``: the (3,) int64
    bit offsets of the axes on the keys' device (``BlockHash`` keeps one: 3 ops instead of 8)."""
    if shifts is None:
        return torch.stack([(keys >> (2 * _BITS)) & _MASK, (keys >> _BITS) & _MASK, keys & _MASK], -1) - _OFFSET
    return ((keys[:, None] >> shifts) & _MASK) - _OFFSET


class BlockHash:
    """Block coordinates -> storage slots; slots are handed out 0, 1, 2, ... in insertion order."""

    def __init__(self, device: torch.device | str = "cpu"):
        self.device = torch.device(device)
        self._keys = torch.empty(0, dtype=torch.int64, device=self.device)
        """(n,) int64 sorted keys of the allocated blocks."""
        self._slots = torch.empty(0, dtype=torch.int64, device=self.device)
        """(n,) int64 slot of ``_keys[i]``."""
        self.slot_coords = torch.empty((0, 3), dtype=torch.int64, device=self.device)
        """(n, 3) int64 block coordinates by slot."""
        self._shifts = torch.tensor([2 * _BITS, _BITS, 0], dtype=torch.int64, device=self.device)
        """(3,) int64 bit offset of each axis in a key (``decode``)."""

    def __len__(self) -> int:
        return int(self._keys.numel())

    @property
    def keys(self) -> torch.Tensor:
        """(n,) int64 sorted keys of the allocated blocks (read only: a kernel's binary search)."""
        return self._keys

    @property
    def key_slots(self) -> torch.Tensor:
        """(n,) int64 slot of ``keys[i]``."""
        return self._slots

    def find(self, coords: torch.Tensor) -> torch.Tensor:
        """(N,) int64 slots of the (N, 3) block coordinates; -1 where a block is not allocated."""
        keys = encode(coords)
        if len(self) == 0:
            return torch.full_like(keys, -1)
        idx = torch.searchsorted(self._keys, keys).clamp_(max=len(self) - 1)
        hit = self._keys[idx] == keys
        return torch.where(hit, self._slots[idx], torch.full_like(keys, -1))

    def insert(self, coords: torch.Tensor) -> torch.Tensor:
        """Allocate the blocks of (N, 3) coordinates not yet in the table; return all N slots."""
        if (coords.abs() > MAX_BLOCK_INDEX).any():
            raise_out_of_range()
        slots = self.find(coords)
        missing = slots < 0
        if missing.any():
            self.append(torch.unique(encode(coords[missing])))
            slots = self.find(coords)
        return slots

    def append(self, new_keys: torch.Tensor) -> None:
        """Allocate the blocks of (m,) sorted, distinct keys none of which is in the table: slots
        len(self), ..., len(self) + m - 1 in key order (what ``insert`` hands out for them)."""
        start = len(self)
        new_slots = torch.arange(start, start + new_keys.numel(), device=self.device)
        self._keys, order = torch.sort(torch.cat([self._keys, new_keys]))
        self._slots = torch.cat([self._slots, new_slots])[order]
        self.slot_coords = torch.cat([self.slot_coords, decode(new_keys, self._shifts)])


__all__ = ["MAX_BLOCK_INDEX", "BlockHash", "decode", "encode", "raise_out_of_range"]
