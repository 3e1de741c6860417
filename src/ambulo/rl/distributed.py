"""Data-parallel PPO over several processes: ``torchrun --nproc-per-node G -m ambulo.cli train ...``.

rsl-rl-lib's runner does the learning side: with ``WORLD_SIZE`` > 1 it averages the gradients
of every rank's mini-batches (all-reduce), syncs the adaptive learning rate and starts every
rank from rank 0's weights. What ambulo adds here: each rank gets its own device (``cuda:<local
rank>``) and engine, and its own seed (the run's seed + rank) so the ranks collect different
experience; only rank 0 writes the run folder (run.json, checkpoints, metrics, TensorBoard,
evaluations); a decision taken on rank 0 (the periodic evaluation met the criterion) reaches every
rank at the same iteration, so all of them stop together. On CPUs the ranks talk over gloo
(rsl-rl-lib's own set-up is NCCL-only, so ambulo opens the gloo group, builds the runner as one
process (``single_process_view``) and hands the group to its algorithm, ``ppo.AmbuloPPO``):
several CPU processes, each with its own MuJoCo batch, are a way to use a many-core machine too, and how CI tests this path without GPUs. NCCL's NVLink
multicast (NVLS) is turned off unless the user set ``NCCL_NVLS_ENABLE``: it needs a fabric
manager the lent multi-GPU machines do not run.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class Rank:
    rank: int = 0
    local_rank: int = 0
    world_size: int = 1

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1


def current() -> Rank:
    """This process's place among torchrun's processes (rank 0 of 1 without torchrun)."""
    return Rank(int(os.getenv("RANK", "0")), int(os.getenv("LOCAL_RANK", "0")), int(os.getenv("WORLD_SIZE", "1")))


def rank_device(device: str, rank: Rank) -> str:
    """``cuda`` / ``cuda:k`` -> ``cuda:<local rank>`` when distributed (one GPU per process)."""
    if rank.distributed and device.startswith("cuda"):
        os.environ.setdefault("NCCL_NVLS_ENABLE", "0")
        return f"cuda:{rank.local_rank}"
    return device


def init_cpu_group(rank: Rank) -> None:
    """The gloo process group CPU ranks share (torchrun sets MASTER_ADDR/PORT)."""
    if rank.distributed and not torch.distributed.is_initialized():
        torch.distributed.init_process_group(backend="gloo", rank=rank.rank, world_size=rank.world_size)


def cpu_group_cfg() -> dict[str, int] | None:
    """rsl-rl-lib's ``multi_gpu_cfg`` for this process's gloo group (``init_cpu_group``), or None."""
    if not (torch.distributed.is_available() and torch.distributed.is_initialized()
            and torch.distributed.get_backend() == "gloo"):
        return None
    rank = current()
    return {"global_rank": rank.rank, "local_rank": rank.local_rank, "world_size": rank.world_size}


@contextlib.contextmanager
def single_process_view() -> Iterator[None]:
    """While entered, ``WORLD_SIZE`` reads 1: rsl-rl-lib's runner, built inside, leaves the
    process group to ambulo (its own set-up, from ``WORLD_SIZE``, is NCCL on CUDA only)."""
    saved = os.environ.get("WORLD_SIZE")
    os.environ["WORLD_SIZE"] = "1"
    try:
        yield
    finally:
        if saved is None:
            del os.environ["WORLD_SIZE"]
        else:
            os.environ["WORLD_SIZE"] = saved


def leave_group() -> None:
    """Close the process group once every rank has finished training (a barrier, then
    ``destroy_process_group``). Left to interpreter exit, a rank whose peer had already gone tore down
    gloo's pairs in a destructor and aborted ("terminate called without an active exception", exit
    -6, a 2-rank CPU run of 2 iterations in CI), failing a run that had finished. Call it only where
    every rank arrives: after a run that did not raise."""
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        torch.distributed.barrier()
        torch.distributed.destroy_process_group()


def agree(flag: bool, rank: Rank, device: str) -> bool:
    """Rank 0's ``flag`` on every rank (a broadcast; every rank must call it at the same point)."""
    if not rank.distributed:
        return flag
    value = torch.tensor([1 if flag else 0], dtype=torch.int32, device=device)
    torch.distributed.broadcast(value, src=0)
    return bool(value.item())


__all__ = ["Rank", "agree", "cpu_group_cfg", "current", "init_cpu_group", "leave_group", "rank_device",
           "single_process_view"]
