"""A hash of voxel blocks in plain torch: the same code on the CPU and on CUDA.

nvblox and Open3D (ASH, Dong et al. TPAMI 2023) allocate a map in blocks of 8^3 voxels found
through a GPU hash table, so memory follows the observed surface rather than the bounding box
(a 50 m x 50 m floor at 5 cm is ~16k blocks of 0.4 m, not a dense 1000 x 1000 x 60 grid). Here
the table is a *sorted* array of 64-bit block keys: lookup is ``torch.searchsorted`` (a batched
binary search, one kernel on either device) and insertion merges the new keys with one sort, so
there is no per-key Python and no custom kernel. A block's storage slot never moves. The arrays are
capacity buffers updated in place, so a Warp launch that binds them keeps its views while blocks are
added (``BlockHash``).
"""

from __future__ import annotations

import numpy as np
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
    """Block coordinates -> storage slots; slots are handed out 0, 1, 2, ... in insertion order.

    The table lives in capacity buffers updated in place (the first ``len(self)`` entries valid), so the
    tensor objects that ``TsdfMap``'s recorded Warp launches bind stay the same while blocks are added:
    a launch re-views them (``wp.from_torch``, ~15 us each on CUDA) only when the capacity doubles, not in
    every frame that adds blocks. ``keys``, ``key_slots`` and ``slot_coords`` are views of the valid part."""

    def __init__(self, device: torch.device | str = "cpu", capacity: int = 1024):
        self.device = torch.device(device)
        self._n = 0
        """Allocated blocks: the valid length of the buffers (a host int: no device read)."""
        self._shifts = torch.tensor([2 * _BITS, _BITS, 0], dtype=torch.int64, device=self.device)
        """(3,) int64 bit offset of each axis in a key (``decode``)."""
        self._shifts_host = np.array([2 * _BITS, _BITS, 0], dtype=np.int64)
        self._on_host = self.device.type == "cpu"
        """Whether ``append`` merges in numpy (CPU) or in torch ops (a device: no host read)."""
        self._alloc(max(1, capacity))

    def _alloc(self, capacity: int) -> None:
        """(Re)allocate the buffers at ``capacity`` entries, keeping the valid ones."""
        n = self._n
        keys = torch.empty(capacity, dtype=torch.int64, device=self.device)
        # entries from n on hold their own index: the slots of keys appended there (``append``)
        slots = torch.arange(capacity, dtype=torch.int64, device=self.device)
        coords = torch.zeros((capacity, 3), dtype=torch.int64, device=self.device)
        if n:
            keys[:n] = self._key_buf[:n]
            slots[:n] = self._slot_buf[:n]
            coords[:n] = self._coord_buf[:n]
        self._key_buf = keys
        """(capacity,) int64: the allocated blocks' keys, sorted, in the first n entries."""
        self._slot_buf = slots
        """(capacity,) int64: the slot of ``_key_buf[i]`` for i < n; i itself for i >= n."""
        self._coord_buf = coords
        """(capacity, 3) int64: block coordinates by slot, the first n rows."""
        self._order_buf = torch.empty(capacity, dtype=torch.int64, device=self.device)
        """(capacity,) int64 scratch: where ``append``'s sort puts each merged key from (device merge)."""
        self._host = (keys.numpy(), slots.numpy(), coords.numpy()) if self._on_host else None
        """The CPU buffers as numpy views (``_merge_numpy``)."""
        self._scratch = (self._order_buf.numpy(), np.empty(capacity, dtype=bool)) if self._on_host else None
        """CPU scratch of ``_merge_numpy``: (capacity,) int64 moved entries, (capacity,) bool old entries."""

    def __len__(self) -> int:
        return self._n

    @property
    def capacity(self) -> int:
        """Entries of the buffers (doubled when an ``append`` needs more)."""
        return int(self._key_buf.shape[0])

    @property
    def keys(self) -> torch.Tensor:
        """(n,) int64 sorted keys of the allocated blocks (a view of ``key_buffer``)."""
        return self._key_buf[: self._n]

    @property
    def key_slots(self) -> torch.Tensor:
        """(n,) int64 slot of ``keys[i]``."""
        return self._slot_buf[: self._n]

    @property
    def slot_coords(self) -> torch.Tensor:
        """(n, 3) int64 block coordinates by slot."""
        return self._coord_buf[: self._n]

    @property
    def key_buffer(self) -> torch.Tensor:
        """(capacity,) int64 sorted keys in the first ``len(self)`` entries: the same tensor object until
        the capacity grows (what a recorded kernel launch binds; read only)."""
        return self._key_buf

    @property
    def key_slot_buffer(self) -> torch.Tensor:
        """(capacity,) int64 slot of ``key_buffer[i]``, i < ``len(self)`` (same object until it grows)."""
        return self._slot_buf

    @property
    def slot_coord_buffer(self) -> torch.Tensor:
        """(capacity, 3) int64 block coordinates by slot, the first ``len(self)`` rows (same object until
        it grows)."""
        return self._coord_buf

    def reserve(self, capacity: int) -> None:
        """Grow the buffers to at least ``capacity`` entries (new tensor objects)."""
        if capacity > self.capacity:
            self._alloc(capacity)

    def set_length(self, n: int) -> None:
        """``n`` entries are valid: the buffers were merged on the device (``tsdf.graph``), which keeps the
        invariants ``append`` keeps (sorted keys, slot entries from n on their own index)."""
        self._n = n

    def find(self, coords: torch.Tensor) -> torch.Tensor:
        """(N,) int64 slots of the (N, 3) block coordinates; -1 where a block is not allocated."""
        keys = encode(coords)
        if len(self) == 0:
            return torch.full_like(keys, -1)
        table = self.keys
        idx = torch.searchsorted(table, keys).clamp_(max=len(self) - 1)
        hit = table[idx] == keys
        return torch.where(hit, self.key_slots[idx], torch.full_like(keys, -1))

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

    def append(self, new_keys: torch.Tensor, presorted: bool = True) -> None:
        """Allocate the blocks of (m,) distinct keys none of which is in the table, sorted unless
        ``presorted`` is False (then sorted here: in numpy on the CPU, ~1 us where torch.sort took 3-25 us):
        slots len(self), ..., len(self) + m - 1 in key order (what ``insert`` hands out for them), merged
        into the buffers in place (no host read: m is the tensor's length)."""
        n, m = self._n, int(new_keys.numel())
        if m == 0:
            return
        total = n + m
        if total > self.capacity:  # geometric growth: a few reallocations over a map's life
            self._alloc(max(total, 2 * self.capacity))
        if self._on_host:
            new = new_keys.numpy()
            self._merge_numpy(new if presorted else np.sort(new), n, total)
        else:
            self._merge_torch(new_keys if presorted else torch.sort(new_keys).values, n, total)
        self._n = total

    def _merge_torch(self, new_keys: torch.Tensor, n: int, total: int) -> None:
        """``append`` on a device, 7 torch ops: one sort of old and new keys together into the key buffer
        (a merge of the two sorted runs would be fewer element moves but more ops; a sort's time is the
        device's), the slots gathered in that order from the slot buffer (whose entries from n on are
        their own index, i.e. the new keys' slots: the buffer already reads ``cat([slots, new slots])``)
        through a temporary (a gather can not write the buffer it reads), the new keys decoded in place."""
        keys, slots, order = self._key_buf[:total], self._slot_buf[:total], self._order_buf[:total]
        torch.sort(torch.cat([self._key_buf[:n], new_keys]), out=(keys, order))
        slots.copy_(slots.take(order))
        rows = self._coord_buf[n:total]
        torch.bitwise_right_shift(new_keys[:, None], self._shifts, out=rows)
        rows.bitwise_and_(_MASK).sub_(_OFFSET)

    def _merge_numpy(self, new_keys: np.ndarray, n: int, total: int) -> None:
        """``append`` on the CPU, in numpy on the buffers' memory: a merge that moves only the entries
        from the first new key's place on, O(n) (torch.sort of the merged keys is O(n log n): 150 us at
        16k blocks, where this takes ~20 us), ~1 us per call where a torch op costs ~3 us. Its temporaries
        are the scratch buffers: a fresh array over 128 KiB (16k keys) is new pages from the OS each time,
        and their faults took longer (~27 us per copy at 16k) than the merge itself."""
        kb, sb, cb = self._host
        moved, is_old = self._scratch
        m = total - n
        dest = np.searchsorted(kb[:n], new_keys)  # new key j goes before old key dest[j] ...
        lo = int(dest[0])  # (the smallest new key: nothing before it moves)
        dest += np.arange(-lo, m - lo)  # ... so at dest[j] + j of the merged array; here from lo on
        old = is_old[: total - lo]
        old.fill(True)
        old[dest] = False  # where the old entries from lo on go, in order
        for buf, new in ((kb, new_keys), (sb, np.arange(n, total))):
            np.copyto(moved[: n - lo], buf[lo:n])
            buf[lo:total][dest] = new
            buf[lo:total][old] = moved[: n - lo]
        rows = cb[n:total]
        np.right_shift(new_keys[:, None], self._shifts_host, out=rows)
        np.bitwise_and(rows, _MASK, out=rows)
        np.subtract(rows, _OFFSET, out=rows)


__all__ = ["MAX_BLOCK_INDEX", "BlockHash", "decode", "encode", "raise_out_of_range"]
