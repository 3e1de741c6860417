"""A frame's tight boxes, pixel counts and COCO RLE strings in one compiled pass (numba), NumPy without it.

What ``FrameProducer._finish`` needs of the instance image, each instance's tight box, its pixel
count and its COCO mask, used to take ~20 NumPy calls (``coco.InstanceRuns``: the column runs, a
stable sort by id, ``runs_tight_boxes``, ``instance_rles``' gaps and ``frPyObjects``' string
compression): 0.2-0.45 ms of CPU a 320x240 frame, a twentieth of an annotated frame. With numba (the
``data`` extra) ``_masks_kernel`` does all of it in one loop over the pixels and one over the runs.
Without numba the NumPy path (``coco.InstanceRuns``) gives the same arrays and bytes (tested).

The kernel is compiled on first use and cached (``compiled``); ``FrameProducer`` loads it while it
builds its scene (``warm_up``), not in the first frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ambulo.utils.compiled import HAVE_NUMBA, Kernel

from .coco import InstanceRuns, instance_rles, runs_tight_boxes


@dataclass(frozen=True, slots=True)
class InstanceMasks:
    """What one (H, W) instance image gives the annotators: ``boxes`` (K, 4) int64 [x_min, y_min, x_max,
    y_max] inclusive pixels (-1 where invisible), ``pixels`` (K,) int64 visible pixel counts, and
    ``rles(ids)``: the COCO RLEs (``{"size": [H, W], "counts": bytes}``, ``mask_utils.encode``'s bytes)
    of the instances ``ids`` (1..K), in that order."""

    boxes: np.ndarray
    pixels: np.ndarray
    height: int
    width: int
    _chars: np.ndarray | None = None
    """(C,) uint8 every instance's RLE string, side by side (numba path)."""
    _offsets: np.ndarray | None = None
    """(K + 2,) int64 where id i's string starts in ``_chars`` (id 0, the background, has an empty one)."""
    _runs: InstanceRuns | None = None
    """The NumPy path's column runs, read by ``instance_rles``."""

    def rles(self, ids) -> list[dict]:
        if self._runs is not None:
            return instance_rles(None, np.asarray(ids, np.int64), runs=self._runs)
        size = [self.height, self.width]
        chars, offsets = self._chars, self._offsets.tolist()
        return [{"size": size, "counts": chars[offsets[i]:offsets[i + 1]].tobytes()}
                for i in np.asarray(ids, np.int64).tolist()]


def instance_masks(instances: np.ndarray, num_instances: int) -> InstanceMasks:
    """``InstanceMasks`` of (H, W) integer ``instances`` (ids 0..K, 0 = background): numba's one pass
    when installed, else the NumPy column runs."""
    if HAVE_NUMBA:
        return numba_masks(instances, num_instances)
    return numpy_masks(instances, num_instances)


def numpy_masks(instances: np.ndarray, num_instances: int) -> InstanceMasks:
    runs = InstanceRuns.of(instances)
    boxes, pixels = runs_tight_boxes(runs, num_instances)
    return InstanceMasks(boxes, pixels, runs.height, runs.width, _runs=runs)


def numba_masks(instances: np.ndarray, num_instances: int) -> InstanceMasks:
    h, w = instances.shape
    if h == 0 or w == 0:
        raise ValueError(f"an instance image needs pixels, got shape {instances.shape}")
    # ids outside 0..K (which would index past the kernel's tables) raise ValueError
    boxes, pixels, chars, offsets = _masks_kernel(np.ascontiguousarray(instances), int(num_instances))
    return InstanceMasks(boxes, pixels, h, w, _chars=chars, _offsets=offsets)


def warm_up() -> None:
    """Compile the kernel, or load it from the cache (~0.2 s, and ~0.3-0.5 s to import numba), now rather
    than in the first frame: ``FrameProducer`` calls it while it builds its scene. The first process on
    a machine to need it compiles it (~2-3 s) and writes the cache; processes started together may each
    compile once."""
    if HAVE_NUMBA:
        numba_masks(np.zeros((2, 2), np.int32), 1)


def _masks(instances, num_instances):
    """The kernel (``_masks_kernel`` compiles it): ((K, 4) boxes, (K,) pixels, (C,) uint8 RLE strings of ids
    0..K side by side (the background's empty), (K + 2,) their offsets).

    Pass 1 finds where each run of equal ids starts in column-major order (COCO's). Pass 2 walks the runs: each id's pixels and box (a run that wraps onto the next column
    covers every row), and its counts, the gaps between its runs and their lengths, which pass 3
    writes as pycocotools' ``rleToString`` does (each count but the first two minus the one two
    before, in 5-bit groups, 48 added). The empty zeros-run after an id's last run is dropped, as
    ``mask_utils.encode`` never writes one.
    """
    h, w = instances.shape
    n = h * w
    k = num_instances
    # pass 1 in row order (the image as stored: a third of the time of a walk down the columns): a
    # column-major run starts where a pixel differs from the one above it, and at the top of a
    # column that differs from the bottom of the column before; rows come in ascending order, so a
    # counting sort by column puts the starts in column-major order
    found_r = np.empty(n, np.int64)
    found_c = np.empty(n, np.int64)
    per_column = np.zeros(w, np.int64)
    found = 1
    found_r[0], found_c[0], per_column[0] = 0, 0, 1
    for c in range(1, w):
        if instances[0, c] != instances[h - 1, c - 1]:
            found_r[found], found_c[found] = 0, c
            found += 1
            per_column[c] += 1
    for r in range(1, h):
        for c in range(w):
            if instances[r, c] != instances[r - 1, c]:
                found_r[found], found_c[found] = r, c
                found += 1
                per_column[c] += 1
    at_column = np.empty(w, np.int64)
    total = 0
    for c in range(w):
        at_column[c] = total
        total += per_column[c]
    runs = found
    starts = np.empty(runs + 1, np.int64)
    ids = np.empty(runs, np.int64)
    bad = 0
    for j in range(runs):
        r, c = found_r[j], found_c[j]
        q = at_column[c]
        at_column[c] = q + 1
        starts[q] = c * h + r
        v = instances[r, c]  # every pixel is in a run: checking the runs' ids checks the image's
        if v < 0 or v > k:
            bad += 1
            v = 0
        ids[q] = v
    starts[runs] = n
    if bad:
        raise ValueError("instance ids must be in 0..num_instances")
    # pass 2: per id, its runs in image order (a counting sort by id), pixels and box
    n_runs = np.zeros(k + 1, np.int64)
    for j in range(runs):
        n_runs[ids[j]] += 1
    first = np.zeros(k + 2, np.int64)
    for i in range(k + 1):
        first[i + 1] = first[i] + n_runs[i]
    fill = first[:k + 1].copy()
    order = np.empty(runs, np.int64)
    for j in range(runs):
        v = ids[j]
        order[fill[v]] = j
        fill[v] += 1
    boxes = np.full((k, 4), -1, np.int64)
    pixels = np.zeros(k, np.int64)
    for i in range(1, k + 1):
        x0, y0, x1, y1 = w, h, -1, -1
        for t in range(first[i], first[i + 1]):
            j = order[t]
            s, e = starts[j], starts[j + 1]
            pixels[i - 1] += e - s
            c0, r0 = s // h, s % h
            c1, r1 = (e - 1) // h, (e - 1) % h
            if c1 > c0:
                r0, r1 = 0, h - 1
            x0, y0, x1, y1 = min(x0, c0), min(y0, r0), max(x1, c1), max(y1, r1)
        if x1 >= 0:
            boxes[i - 1, 0], boxes[i - 1, 1], boxes[i - 1, 2], boxes[i - 1, 3] = x0, y0, x1, y1
    # pass 3: each id's counts (zeros, ones, ..., zeros), compressed; at most 2 runs + 1 counts of
    # at most 6 characters each (a count < 2^30)
    chars = np.empty(6 * (2 * runs + k + 1), np.uint8)
    offsets = np.zeros(k + 2, np.int64)
    at = 0
    counts = np.empty(2 * runs + 1, np.int64)
    for i in range(1, k + 1):  # not the background's (id 0): no annotation reads it
        m = 0
        end = 0
        for t in range(first[i], first[i + 1]):
            j = order[t]
            s, e = starts[j], starts[j + 1]
            counts[m] = s - end
            counts[m + 1] = e - s
            m += 2
            end = e
        if n - end > 0 or m == 0:
            counts[m] = n - end
            m += 1
        for q in range(m):
            x = counts[q]
            if q > 2:
                x -= counts[q - 2]
            more = True
            while more:
                c = x & 0x1F
                x >>= 5
                more = (x != -1) if (c & 0x10) else (x != 0)
                if more:
                    c |= 0x20
                chars[at] = c + 48
                at += 1
        offsets[i + 1] = at
    return boxes, pixels, chars[:at], offsets


_masks_kernel = Kernel(_masks)
