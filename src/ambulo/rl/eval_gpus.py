"""``ambulo eval RUN --num-gpus N``: one evaluation split over N processes, one GPU each.

Process r evaluates its share of the episodes on ``cuda:r`` (``eval_share``: its worlds and seed
stream) and the shares' totals are merged over NCCL as in a data-parallel run's periodic
evaluation (``eval_share.merge_over_ranks``: the one merge); rank 0 prints the result and writes
``eval.json``. The processes are spawned here (no torchrun needed). ``device="cpu"`` runs the same
over gloo: how the tests check it without GPUs. For a seed, N processes run the episodes a
data-parallel run of N ranks evaluates (``--eval-every``): its ``evals.csv`` numbers are what
``ambulo eval RUN --checkpoint model_<it>.pt --num-gpus N`` prints.
"""

from __future__ import annotations

import json
import os
import socket
from typing import Any

import torch

from .distributed import Rank


def check_num_gpus(num_gpus: int, device: str, what: str = "evaluates") -> None:
    """ValueError in one line unless ``num_gpus`` processes can each have one GPU of ``device``;
    ``what`` the command does with them, for the message ("evaluates", "trains")."""
    if num_gpus < 1:
        raise ValueError(f"--num-gpus {num_gpus}: give 1 or more")
    if not device.startswith("cuda"):
        raise ValueError(f"--num-gpus {what} on GPUs, but the device is {device!r}: add --device cuda")
    if device not in ("cuda", "cuda:0"):
        raise ValueError(f"--num-gpus uses GPUs 0..N-1, one per process: give --device cuda, not {device!r}")
    visible = torch.cuda.device_count()
    if num_gpus > visible:
        raise ValueError(f"--num-gpus {num_gpus} but {visible} GPU{'s' * (visible != 1)} visible "
                         "(CUDA_VISIBLE_DEVICES picks them)")


def evaluate_split(run: str | os.PathLike, *, processes: int, device: str = "cuda", **kwargs: Any) -> dict:
    """``evaluate(run, **kwargs)`` as ``processes`` processes (see the module doc); rank 0's result
    (``eval.json``, as one process writes it). ``device``: ``cuda`` (process r on ``cuda:r``,
    NCCL) or ``cpu`` (gloo)."""
    if processes == 1:  # nothing to split: this process, as `ambulo eval --device cuda`
        from .evaluate import evaluate

        return evaluate(run, device=device, **kwargs)
    with socket.socket() as s:  # a free port for the process group's rendezvous
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    torch.multiprocessing.spawn(_one_process, args=(processes, port, str(run), device, kwargs), nprocs=processes,
                                join=True)
    from . import runs

    run_dir, _ = runs.resolve_policy(run, kwargs.get("checkpoint"), kwargs.get("log_root", "runs"))
    return json.loads((run_dir / "eval.json").read_text())


def _one_process(index: int, processes: int, port: int, run: str, device: str, kwargs: dict) -> None:
    from .evaluate import evaluate

    cuda = device.startswith("cuda")
    if cuda:
        torch.cuda.set_device(index)
        os.environ.setdefault("NCCL_NVLS_ENABLE", "0")  # as distributed.rank_device: no fabric manager
    torch.distributed.init_process_group("nccl" if cuda else "gloo", init_method=f"tcp://127.0.0.1:{port}",
                                         rank=index, world_size=processes)
    try:
        evaluate(run, device=f"cuda:{index}" if cuda else "cpu", rank=Rank(index, index, processes), **kwargs)
    finally:
        torch.distributed.destroy_process_group()


__all__ = ["check_num_gpus", "evaluate_split"]
