"""``isaacgym.gymtorch`` under ``ambulo run``: Gym tensors to torch tensors and back.

``wrap_tensor`` returns the very buffer ``acquire_*_tensor`` handed out (the same storage every
call, so views a script slices from it see each ``refresh_*``); ``unwrap_tensor`` wraps any torch
tensor for the ``set_*_tensor`` calls.
"""

from __future__ import annotations

import torch

from .tensors import GymTensor


def wrap_tensor(gym_tensor: GymTensor, offsets=None, counts=None) -> torch.Tensor:
    """The torch tensor behind ``gym_tensor``; with ``counts`` (a shape), a view of that shape
    starting at element ``offsets`` (Isaac's flat-buffer form)."""
    tensor = gym_tensor.tensor
    if counts is None:
        return tensor
    start = int(offsets[0]) if offsets is not None else 0
    shape = tuple(int(c) for c in counts)
    size = 1
    for c in shape:
        size *= c
    return tensor.view(-1)[start:start + size].view(shape)


def unwrap_tensor(tensor: torch.Tensor) -> GymTensor:
    return GymTensor(tensor)


__all__ = ["unwrap_tensor", "wrap_tensor"]
