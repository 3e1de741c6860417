"""The categorical (C51) return distribution: its support and the projection of a target.

A critic outputs logits over ``num_atoms`` returns evenly spaced in ``[v_min, v_max]``. The
target of a sample is the next state's distribution moved by the n-step return and shrunk by
the discount, ``returns + discount * z``, which falls between atoms: ``project`` splits each
atom's probability between the two atoms around its new place, in proportion to closeness
(Bellemare et al. 2017), after clipping to the support.
"""

from __future__ import annotations

import torch


def support(v_min: float, v_max: float, num_atoms: int, device: torch.device | str = "cpu") -> torch.Tensor:
    """(num_atoms,) float32 atom values, v_min .. v_max."""
    return torch.linspace(v_min, v_max, num_atoms, device=device)


def project(next_probs: torch.Tensor, returns: torch.Tensor, discount: torch.Tensor,
            v_min: float, v_max: float) -> torch.Tensor:
    """The target distribution (B, K) on the support of ``next_probs`` (B, K): probabilities of
    the next state's returns, moved to ``returns + discount * z`` (``returns``, ``discount``:
    (B,)) and split between neighbouring atoms. ``v_min``/``v_max`` are host floats (no sync)."""
    num_atoms = next_probs.shape[-1]
    delta = (v_max - v_min) / (num_atoms - 1)
    z = torch.linspace(v_min, v_max, num_atoms, device=next_probs.device, dtype=next_probs.dtype)
    moved = (returns[:, None] + discount[:, None] * z[None, :]).clamp(v_min, v_max)
    place = (moved - v_min) / delta  # fractional atom index in [0, K-1]
    lower = place.floor().clamp(0, num_atoms - 1)
    upper_share = place - lower  # 0 when the place is an atom: all on ``lower``
    lower_idx = lower.long()
    upper_idx = (lower_idx + 1).clamp(max=num_atoms - 1)
    target = torch.zeros_like(next_probs)
    target.scatter_add_(1, lower_idx, next_probs * (1.0 - upper_share))
    target.scatter_add_(1, upper_idx, next_probs * upper_share)
    return target


def expected(probs: torch.Tensor, atoms: torch.Tensor) -> torch.Tensor:
    """Mean return of distributions ``probs`` (..., K) on ``atoms`` (K,)."""
    return (probs * atoms).sum(dim=-1)


__all__ = ["expected", "project", "support"]
