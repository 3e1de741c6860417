"""One rank of ``test_eval_split``: a ``PeriodicEval`` of cartpole split over 2 CPU processes (gloo).

Run as ``python eval_split_worker.py OUT NUM_EPISODES WEIGHTS_JSON`` with torchrun's variables (RANK,
WORLD_SIZE, MASTER_ADDR, MASTER_PORT) set. The policy is linear in the observations (``WEIGHTS``:
some episodes fall, some do not); the runner is a stand-in with what ``PeriodicEval`` uses. The
evaluation env is declared another engine than the CPU one and the criterion always holds, so the
CPU-engine confirmation runs too, split the same way. Rank 0's run folder is OUT/run, the other
rank's OUT/rank<r>, which must stay absent. Each rank writes its result to OUT/result<r>.json.
"""

import dataclasses
import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import torch

from ambulo import envs
from ambulo.envs.registry import Criterion
from ambulo.rl import distributed, periodic_eval

INFO = {"task": "cartpole", "seed": 0, "device": "cpu", "env_overrides": {}}


class LinearPolicy(torch.nn.Module):
    """Actions = observations @ weights, as rsl-rl's inference policy takes TensorDict observations."""

    obs_groups = ["policy"]

    def __init__(self, weights: list[float]):
        super().__init__()
        self.net = torch.nn.Linear(len(weights), 1, bias=False)
        with torch.no_grad():
            self.net.weight.copy_(torch.tensor([weights]))

    def forward(self, obs) -> torch.Tensor:
        return self.net(obs["policy"])

    def as_jit(self) -> torch.nn.Module:  # CpuPolicy's copy
        return self.net


def main(out: Path, num_episodes: int, weights: list[float]) -> None:
    rank = distributed.current()
    distributed.init_cpu_group(rank)
    periodic_eval.is_cpu_engine = lambda env: False  # "a GPU run": the CPU engine confirms
    policy = LinearPolicy(weights)
    runner = SimpleNamespace(save=lambda path: Path(path).write_bytes(b"checkpoint"),
                             get_inference_policy=lambda device: policy,
                             alg=SimpleNamespace(train_mode=lambda: None), logger=SimpleNamespace(writer=None))
    run_dir = out / ("run" if rank.is_main else f"rank{rank.rank}")
    if rank.is_main:
        run_dir.mkdir()
    evaluation = periodic_eval.PeriodicEval(INFO, run_dir, every=1, started_s=time.monotonic(),
                                            steps_per_iteration=64, num_episodes=num_episodes, rank=rank)
    always = Criterion("balances", max_values={"fall_rate": 1.0})
    evaluation.task = dataclasses.replace(envs.spec("cartpole"), criteria=(always,))
    result = evaluation(runner, 0)
    evaluation.close()
    (out / f"result{rank.rank}.json").write_text(json.dumps(
        {"result": result, "share": dataclasses.asdict(evaluation.share), "reached": evaluation.reached}))
    torch.distributed.destroy_process_group()


if __name__ == "__main__":
    main(Path(sys.argv[1]), int(sys.argv[2]), json.loads(sys.argv[3]))
