"""EpisodeStats: returns and lengths of the last 100 episodes, kept by ambulo, not read from rsl-rl.

``metrics.csv``'s mean reward and episode length (and TensorBoard's ``Train/*``) average the last
100 episodes that ended, as rsl-rl-lib's own console report does. ambulo keeps them itself so a
resumed run continues the means where its checkpoint left them (the values travel in the
checkpoint's ``infos``) without writing into the runner's logger.

Sync-free on a GPU: each step's finished episodes go into a ring of ``capacity`` slots with one
scatter (the last ``capacity`` of a step at most, in env order, as a deque would keep them); the
host reads the ring once an iteration, for the means.
"""

from __future__ import annotations

import torch


class EpisodeStats:
    """Running sums of ``num_envs`` episodes and a ring of the last ``capacity`` that ended.

    Shapes: ``rewards`` and ``dones`` are (num_envs,) on ``device``; the ring holds float32
    returns and lengths (steps), slot ``capacity`` is where the steps' other rows are written and
    ignored.
    """

    def __init__(self, num_envs: int, device: torch.device | str, capacity: int = 100):
        self.capacity = capacity
        self._return = torch.zeros(num_envs, dtype=torch.float32, device=device)
        self._length = torch.zeros(num_envs, dtype=torch.float32, device=device)
        self._returns = torch.zeros(capacity + 1, dtype=torch.float32, device=device)
        self._lengths = torch.zeros(capacity + 1, dtype=torch.float32, device=device)
        self._ended = torch.zeros((), dtype=torch.long, device=device)
        """Episodes ended so far (the ring's write position is this modulo ``capacity``)."""

    def step(self, rewards: torch.Tensor, dones: torch.Tensor) -> None:
        """Add one env step: ``rewards`` (N,), ``dones`` (N,) nonzero where an episode ended."""
        self._return += rewards.float()
        self._length += 1.0
        ended = dones > 0
        order = torch.cumsum(ended.long(), 0)  # 1-based rank among this step's finished episodes
        total = order[-1]
        kept = ended & (order > total - self.capacity)
        slot = torch.where(kept, (self._ended + order - 1) % self.capacity, self.capacity)
        self._returns.scatter_(0, slot, self._return)
        self._lengths.scatter_(0, slot, self._length)
        self._ended += total
        self._return.masked_fill_(ended, 0.0)
        self._length.masked_fill_(ended, 0.0)

    def _oldest_first(self, ring: torch.Tensor) -> list[float]:
        ended = int(self._ended)
        if ended <= self.capacity:
            return ring[:ended].tolist()
        return ring[:self.capacity].roll(-(ended % self.capacity)).tolist()

    def returns(self) -> list[float]:
        """Returns of the kept episodes, oldest first."""
        return self._oldest_first(self._returns)

    def lengths(self) -> list[float]:
        """Lengths of the kept episodes in env steps, oldest first."""
        return self._oldest_first(self._lengths)

    def means(self) -> tuple[float | None, float | None]:
        """(mean return, mean length in steps) of the kept episodes; (None, None) before any ended."""
        kept = min(int(self._ended), self.capacity)  # the one host sync
        if kept == 0:
            return None, None
        return float(self._returns[:kept].double().mean()), float(self._lengths[:kept].double().mean())

    def restore(self, returns: list[float], lengths: list[float]) -> None:
        """Continue from a checkpoint's kept episodes (oldest first; the last ``capacity`` count)."""
        returns, lengths = list(returns)[-self.capacity:], list(lengths)[-self.capacity:]
        if len(returns) != len(lengths):
            raise ValueError(f"{len(returns)} episode returns but {len(lengths)} lengths in the checkpoint")
        n = len(returns)
        self._returns[:n] = torch.tensor(returns, dtype=torch.float32)
        self._lengths[:n] = torch.tensor(lengths, dtype=torch.float32)
        self._ended.fill_(n)


__all__ = ["EpisodeStats"]
