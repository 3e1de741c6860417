"""A crashed training run resumes from its last complete checkpoint in the same folder."""

import csv

import pytest
import torch

from ambulo.rl import train
from ambulo.rl.runs import checkpoints
from ambulo.rl.vecenv import RslRlVecEnv
from ambulo.utils.atomic import TMP_MARK


def test_resume_after_interruption(tmp_path, monkeypatch):
    fast = {"save_interval": 1, "num_steps_per_env": 8}
    step = RslRlVecEnv.step
    calls = {"n": 0}

    def crashing_step(self, actions):
        calls["n"] += 1
        if calls["n"] > 8 * 3 + 4:  # in the middle of iteration 3
            raise KeyboardInterrupt("simulated crash")
        return step(self, actions)

    monkeypatch.setattr(RslRlVecEnv, "step", crashing_step)
    with pytest.raises(KeyboardInterrupt):
        train("cartpole", num_envs=16, max_iterations=6, log_root=tmp_path, ppo_overrides=fast)
    run_dir = next((tmp_path / "cartpole").iterdir())
    assert [it for it, _ in checkpoints(run_dir)] == [0, 1, 2]
    assert not list(run_dir.glob(f"*{TMP_MARK}*"))  # writes are atomic: no leftovers
    saved = torch.load(run_dir / "model_2.pt", weights_only=False)
    assert saved["iter"] == 2

    monkeypatch.setattr(RslRlVecEnv, "step", step)
    resumed = train("cartpole", resume=True, log_root=tmp_path)
    assert resumed == run_dir
    assert [it for it, _ in checkpoints(run_dir)] == [0, 1, 2, 3, 4, 5]
    iterations = [int(r["iteration"]) for r in csv.DictReader(open(run_dir / "metrics.csv"))]
    assert iterations == [0, 1, 2, 3, 4, 5]
    # the resumed run started from model_2's weights, not from scratch: its first update
    # (model_3) is closer to model_2 than a fresh initialization is
    w2 = saved["actor_state_dict"]
    w3 = torch.load(run_dir / "model_3.pt", weights_only=False)["actor_state_dict"]
    w0 = torch.load(run_dir / "model_0.pt", weights_only=False)["actor_state_dict"]
    key = next(k for k in w2 if k.endswith("weight"))
    assert (w3[key] - w2[key]).abs().max() < (w3[key] - w0[key]).abs().max()
