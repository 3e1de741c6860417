"""Row selectors: which worlds a write touches, as indices on the CPU and masks on a GPU.

Resets, pushes and command changes touch a few worlds per step. On the CPU, finding them
(``mask.nonzero()``) is free, and drawing random values for those rows only is the cheap
path. On a GPU, finding them would wait for the device, so the whole (N,) bool mask is the
selector and values are drawn for every row and written with ``torch.where``. Code written
against ``select_rows`` / ``num_rows`` / ``put_rows`` runs on both.

A selector ``rows`` is None (every world), a long tensor of world indices, or an (N,) bool mask.
"""

from __future__ import annotations

import torch


def select_rows(mask: torch.Tensor) -> torch.Tensor | None:
    """The selector of the worlds where ``mask`` (N,) holds: indices on the CPU (None if there
    are none, so callers skip the work), the mask itself elsewhere."""
    if mask.device.type != "cpu":
        return mask
    ids = mask.nonzero().squeeze(-1)
    return ids if ids.numel() else None


def num_rows(rows: torch.Tensor | None, num_worlds: int) -> int:
    """How many rows values for ``rows`` have: one per index, or N for None and masks."""
    if rows is None or rows.dtype == torch.bool:
        return num_worlds
    return rows.numel()


def take_rows(values: torch.Tensor, rows: torch.Tensor | None) -> torch.Tensor:
    """The rows of (N, ...) ``values`` that a write for ``rows`` takes (all of them for a mask)."""
    if rows is None or rows.dtype == torch.bool:
        return values
    return values[rows]


def put_rows(dst: torch.Tensor, cols, value: torch.Tensor, rows: torch.Tensor | None) -> None:
    """``dst[rows, cols] = value``: None writes every row; indices take one value row each; an
    (N,) bool mask takes N value rows and writes the masked ones with ``torch.where``. Values
    take ``dst``'s dtype (float64 on the CPU engine, float32 on the GPU one)."""
    if isinstance(value, torch.Tensor):
        value = value.to(dst.dtype)
    if rows is None:
        dst[:, cols] = value
    elif rows.dtype == torch.bool:
        old = dst[:, cols]
        mask = rows.reshape(-1, *([1] * (old.dim() - 1)))
        dst[:, cols] = torch.where(mask, value.to(old.dtype), old)
    elif isinstance(cols, torch.Tensor):
        dst[rows.reshape(-1, 1), cols] = value
    else:
        dst[rows, cols] = value


def fill_rows(buf: torch.Tensor, rows: torch.Tensor | None, value) -> None:
    """Set the rows of ``buf`` selected by ``rows`` to ``value``."""
    if rows is None:
        buf.fill_(value)
    elif rows.dtype == torch.bool:
        buf.masked_fill_(rows.reshape(-1, *([1] * (buf.dim() - 1))), value)
    else:
        buf[rows] = value


__all__ = ["fill_rows", "num_rows", "put_rows", "select_rows", "take_rows"]
