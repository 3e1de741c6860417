"""COCO's RLE counts of every instance mask of a batch, found on the device in one pass.

A dataset's COCO masks are run-length encodings in column-major order (``coco.instance_rles``).
On the host that is a pass over each image's ~300,000 ids per frame (the change map, its nonzero,
a sort of the runs): about a third of a disk-mode frame's CPU after the draws. Here the runs of
all the batch's images are found at once where the images are (``rle_counts``), and the host is
left the counts of each kept instance, which pycocotools compresses into the same strings
(``frame_rles``: the same bytes as ``coco.instance_rles``, tested).

Layout of ``rle_counts``' result, for N images of K instances: group ``g = n * K + (k - 1)`` is
instance k of image n; its uncompressed counts (zeros, ones, ..., zeros after its last run) are
``counts[offsets[g]:offsets[g] + lengths[g]]``, every group present (an instance with no pixel:
one count, all zeros).
"""

from __future__ import annotations

import numpy as np
import torch
from pycocotools import mask as mask_utils


def rle_counts(instances: torch.Tensor, num_instances: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(counts int32, offsets int64 (N*K,), lengths int64 (N*K,)) of (N, H, W) instance ids (0:
    background, 1..K objects), on their device; see the module docstring. One host sync (the
    number of runs sizes the arrays)."""
    n, h, w = instances.shape
    k = num_instances
    size = h * w
    dev = instances.device
    by_column = instances.transpose(1, 2).reshape(n, size)  # COCO's pixel order
    change = torch.ones((n, size), dtype=torch.bool, device=dev)
    torch.ne(by_column[:, 1:], by_column[:, :-1], out=change[:, 1:])
    image, start = change.nonzero(as_tuple=True)  # every run of equal ids, in image then pixel order
    ids = by_column[image, start].long()
    # a run ends where the next one of its image starts, or at the image's end
    end = torch.full_like(start, size)
    same_image = image[1:] == image[:-1]
    end[:-1] = torch.where(same_image, start[1:], size)
    keep = ids > 0
    group = image[keep] * k + ids[keep] - 1
    start, end = start[keep], end[keep]
    group, order = torch.sort(group, stable=True)  # runs grouped by instance, in pixel order within one
    start, end = start[order], end[order]
    groups = n * k
    runs = torch.zeros(groups, dtype=torch.int64, device=dev).scatter_add_(0, group, torch.ones_like(group))
    first_run = torch.cumsum(runs, 0) - runs
    offsets = 2 * first_run + torch.arange(groups, device=dev)  # each group before adds its runs and a tail
    lengths = 2 * runs + 1
    counts = torch.empty(int(2 * group.numel() + groups), dtype=torch.int32, device=dev)
    previous_end = torch.zeros_like(end)
    previous_end[1:] = torch.where(group[1:] == group[:-1], end[:-1], 0)
    at = 2 * torch.arange(group.numel(), device=dev) + group
    counts[at] = (start - previous_end).to(torch.int32)
    counts[at + 1] = (end - start).to(torch.int32)
    last_end = torch.zeros(groups, dtype=torch.int64, device=dev)
    has = runs > 0
    last_end[has] = end[(first_run + runs - 1)[has]]
    counts[offsets + 2 * runs] = (size - last_end).to(torch.int32)
    return counts, offsets, lengths


def frame_rles(counts: np.ndarray, offsets: np.ndarray, lengths: np.ndarray, image: int, num_instances: int,
               ids, height: int, width: int) -> list[dict]:
    """Compressed COCO RLEs of instances ``ids`` (1-based) of image ``image`` of ``rle_counts``'
    result (as NumPy): ``coco.instance_rles``' output for the same image and ids."""
    objs = []
    for iid in np.asarray(ids).tolist():
        lo = int(offsets[image * num_instances + iid - 1])
        hi = lo + int(lengths[image * num_instances + iid - 1])
        if counts[hi - 1] == 0:  # pycocotools drops an empty last run
            hi -= 1
        objs.append({"counts": counts[lo:hi], "size": [height, width]})
    return mask_utils.frPyObjects(objs, height, width) if objs else []


__all__ = ["frame_rles", "rle_counts"]
