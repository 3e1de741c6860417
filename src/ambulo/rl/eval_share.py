"""An evaluation split over the ranks of a data-parallel run (or ``ambulo eval --num-gpus N``).

``run_episodes`` evaluates one episode per world. With W processes, rank r runs its share of the
``num_episodes``: a contiguous block of ``num_episodes // W`` worlds (the first
``num_episodes % W`` ranks one more) on its own device, and the episodes' totals
(``evaluate.EpisodeSums``: counts and sums, never means) are gathered and added in rank order, so
every rank computes the same merged result from the same numbers, bit for bit, and takes the
same decisions on it (the criteria, the CPU-engine confirmation, stopping). An evaluation laid out
in blocks (``eval_blocks``: humanoid-walk-robust's corners) splits each block so: every rank runs
its part of every block, and the blocks' totals merge block by block.

Seeds: rank 0's share draws from the evaluation seed itself (one process: the episodes ``ambulo
eval`` runs for that seed, unchanged); rank r > 0 from a seed derived from (seed, r) by NumPy's
``SeedSequence``, so no two shares draw the same stream and repeat each other's episodes. A
W-rank evaluation of N episodes therefore runs other episodes than one process's N (the same
task, policy and counts: an equally valid sample, not the identical one).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from .distributed import Rank

if TYPE_CHECKING:  # evaluate imports this module
    from .evaluate import EpisodeSums


@dataclass(frozen=True)
class EvalShare:
    """One rank's part of an evaluation."""

    episodes: int
    """Worlds (one episode each) this rank runs."""
    first: int
    """Index of its first episode among all (ranks hold contiguous blocks, rank order); of a
    blocked evaluation, among each block's."""
    seed: int
    """Seed of its env (its episodes' commands and resets)."""


def share_seed(seed: int, rank: int) -> int:
    """The evaluation seed of ``rank``'s share: ``seed`` for rank 0, a derived 31-bit seed otherwise
    (31 bits: any seed consumer, NumPy's legacy ``RandomState`` included, takes it)."""
    if rank == 0:
        return seed
    return int(np.random.SeedSequence([seed, rank]).generate_state(1)[0] >> 1)


def eval_share(num_episodes: int, seed: int, rank: Rank, *, blocks: int = 1) -> EvalShare:
    """``rank``'s share of ``num_episodes`` (see the module doc); ValueError when a rank would get none.
    ``blocks`` > 1: the episodes are that many equal blocks (``eval_blocks``) and each block is
    shared out so: the rank's env holds its part of every block, as ``blocks`` equal blocks again
    (``first``: its first episode's index within a block)."""
    if num_episodes % blocks:
        raise ValueError(f"{num_episodes} evaluation episodes do not split into {blocks} equal blocks: "
                         f"give a multiple of {blocks}")
    per_block = num_episodes // blocks
    if per_block < rank.world_size:
        blocked = f" ({blocks} blocks of {per_block})" if blocks > 1 else ""
        raise ValueError(f"{num_episodes} evaluation episodes{blocked} cannot be split over {rank.world_size} "
                         f"processes: give at least {rank.world_size * blocks}")
    base, extra = divmod(per_block, rank.world_size)
    episodes = base + (rank.rank < extra)
    first = rank.rank * base + min(rank.rank, extra)
    return EvalShare(episodes * blocks, first, share_seed(seed, rank.rank))


def merge_over_ranks(sums: EpisodeSums, rank: Rank, device: str | torch.device) -> EpisodeSums:
    """The totals of every rank's share, on every rank: gathered (over the process group, tensors on
    ``device``: the rank's GPU under NCCL) and added in rank order, so all ranks hold the same
    floats. Every rank must call it at the same point. One process: ``sums`` unchanged."""
    if not rank.distributed:
        return sums
    mine = sums.to_tensor().to(device)
    parts = [torch.empty_like(mine) for _ in range(rank.world_size)]
    torch.distributed.all_gather(parts, mine)
    total = sums.like(parts[0])
    for part in parts[1:]:  # EpisodeSums' own addition (float64), in rank order
        total = total + sums.like(part)
    return total


__all__ = ["EvalShare", "eval_share", "merge_over_ranks", "share_seed"]
