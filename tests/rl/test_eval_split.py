"""An evaluation split over the ranks of a data-parallel run (``ambulo.rl.eval_share``): each rank
runs its share of the episodes, the shares' totals merge into the result one process would compute
from the union of the same episodes, identical on every rank."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from ambulo import envs
from ambulo.rl import runs
from ambulo.rl.distributed import Rank
from ambulo.rl.eval_share import eval_share
from ambulo.rl.evaluate import EpisodeRecords, episode_records, summarize
from ambulo.rl.vecenv import RslRlVecEnv
from ports import free_port

WORKER = Path(__file__).with_name("eval_split_worker.py")
WEIGHTS = [1.0, 0.2, 0.0, 0.0]  # a weak balance controller: some episodes fall, others last 5 s
SEED = 12345  # PeriodicEval's default evaluation seed


def records(failed, returns, lengths, metric) -> EpisodeRecords:
    as64 = lambda v: torch.tensor(v, dtype=torch.float64)
    return EpisodeRecords(torch.tensor(failed), torch.zeros(len(failed), dtype=torch.bool), as64(returns),
                          as64(lengths), {"abs_error": as64(metric)})


def test_shares_merge_as_sums_and_counts_not_as_averages():
    """A 1-episode share that fell and a 3-episode share that did not: 1 fall in 4 episodes."""
    one = records([True], [2.0], [10.0], [0.5])
    three = records([False] * 3, [4.0] * 3, [100.0] * 3, [0.1] * 3)
    merged = summarize(one.sums() + three.sums(), envs.spec("cartpole"), step_dt_s=0.02, max_episode_length=250)
    assert merged["episodes"] == 4
    assert merged["fall_rate"] == 0.25  # the average of the shares' rates would be 0.5
    assert merged["mean_return"] == pytest.approx((2.0 + 3 * 4.0) / 4)
    assert merged["mean_episode_length_s"] == pytest.approx((10.0 + 300.0) / 4 * 0.02)
    assert merged["mean_abs_error"] == pytest.approx((0.5 + 3 * 0.1) / 4)
    assert merged["balances"] is False  # 0.25 > 0.05


def test_shares_cover_every_episode_once_with_their_own_seeds():
    assert eval_share(100, SEED, Rank()) == eval_share(100, SEED, Rank(0, 0, 1))
    assert eval_share(100, SEED, Rank()).episodes == 100 and eval_share(100, SEED, Rank()).seed == SEED
    shares = [eval_share(100, SEED, Rank(r, r, 3)) for r in range(3)]
    assert [s.episodes for s in shares] == [34, 33, 33] and [s.first for s in shares] == [0, 34, 67]
    assert shares[0].seed == SEED and len({s.seed for s in shares}) == 3
    with pytest.raises(ValueError, match="cannot be split over 4"):
        eval_share(3, SEED, Rank(0, 0, 4))


@pytest.fixture(scope="module")
def two_ranks(tmp_path_factory):
    """The worker's evaluation of 7 cartpole episodes on 2 gloo ranks (shares of 4 and 3)."""
    out = tmp_path_factory.mktemp("split")
    port = str(free_port())
    procs = [subprocess.Popen(
        [sys.executable, str(WORKER), str(out), "7", json.dumps(WEIGHTS)],
        env={**os.environ, "OMP_NUM_THREADS": "1", "RANK": str(r), "LOCAL_RANK": str(r), "WORLD_SIZE": "2",
             "MASTER_ADDR": "127.0.0.1", "MASTER_PORT": port},
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for r in range(2)]
    for proc in procs:
        output, _ = proc.communicate(timeout=120)
        assert proc.returncode == 0, output[-3000:]
    return out, [json.loads((out / f"result{r}.json").read_text()) for r in range(2)]


def union_of_shares() -> dict:
    """One process: each rank's episodes (its share's worlds and seed), concatenated, averaged."""
    info = {"task": "cartpole", "seed": 0, "device": "cpu", "env_overrides": {}}
    weights = torch.tensor(WEIGHTS)
    parts = []
    for r in range(2):
        share = eval_share(7, SEED, Rank(r, r, 2))
        env = runs.make_env_for_run(info, num_envs=share.episodes, seed=share.seed, play=True, episode_length_s=5.0)
        parts.append(episode_records(env, RslRlVecEnv(env), lambda obs: obs["policy"] @ weights[:, None],
                                     envs.spec("cartpole")))
        env.close()
    failed = torch.cat([p.failed for p in parts]).double()
    return {"episodes": failed.numel(), "fall_rate": failed.mean().item(),
            "mean_return": torch.cat([p.returns for p in parts]).mean().item(),
            "mean_episode_length_s": torch.cat([p.length_steps for p in parts]).mean().item() * 0.02}


def test_every_rank_gets_the_result_of_the_union_of_the_shares(two_ranks):
    _, (zero, one) = two_ranks
    assert zero["result"] == one["result"], "the ranks hold different results: they could decide differently"
    assert [zero["share"]["episodes"], one["share"]["episodes"]] == [4, 3]
    expected = union_of_shares()
    assert 0 < expected["fall_rate"] < 1, "the policy should fail some episodes, not all"
    for result in (zero["result"], zero["result"]["cpu_engine"]):  # the confirmation is split the same way
        assert result["episodes"] == 7
        for key, value in expected.items():
            assert result[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key
    assert zero["reached"]["iteration"] == one["reached"]["iteration"] == 0  # the same decision


def test_only_rank_0_writes(two_ranks):
    out, (zero, _) = two_ranks
    assert not (out / "rank1").exists()
    run = out / "run"
    assert sorted(p.name for p in run.iterdir()) == ["evals.csv", "model_0.pt", "time_to_criterion.json"]
    reached = json.loads((run / "time_to_criterion.json").read_text())
    merged = {k: v for k, v in zero["result"].items() if k != "cpu_engine"}
    assert reached["eval"] == merged and reached["eval_cpu_engine"] == zero["result"]["cpu_engine"]
    assert (run / "evals.csv").read_text().count("\n") == 2  # the header and one row


@pytest.fixture(scope="module")
def cartpole_run(tmp_path_factory):
    from ambulo.rl import train

    return train("cartpole", num_envs=16, max_iterations=2, seed=0, log_root=tmp_path_factory.mktemp("runs"))


def test_ambulo_eval_split_over_processes_is_the_union_of_the_shares(cartpole_run):
    """``ambulo eval --num-gpus 2``'s machinery on CPU processes (gloo): 7 episodes as shares of 4 and 3,
    each what one process evaluates with that share's worlds and seed, merged episode-weighted."""
    from ambulo.rl.eval_gpus import evaluate_split
    from ambulo.rl.evaluate import evaluate

    split = evaluate_split(cartpole_run, processes=2, device="cpu", num_episodes=7, quiet=True)
    shares = [eval_share(7, SEED, Rank(r, r, 2)) for r in range(2)]
    alone = [evaluate(cartpole_run, num_episodes=s.episodes, seed=s.seed, quiet=True) for s in shares]
    assert split["episodes"] == 7 and split["device"] == "cpu x 2"
    for key in ("fall_rate", "mean_return", "mean_episode_length_s"):
        weighted = sum(s.episodes * one[key] for s, one in zip(shares, alone)) / 7
        assert split[key] == pytest.approx(weighted, rel=1e-12), key


@pytest.mark.parametrize("flags, message", [
    (["--num-gpus", "2", "--device", "cpu"], "--num-gpus evaluates on GPUs, but the device is 'cpu': add --device cuda"),
    (["--num-gpus", "2"], "--num-gpus evaluates on GPUs, but the device is 'cpu'"),  # the run's device
    (["--num-gpus", "0"], "--num-gpus: '0' is not a whole number above 0"),
    (["--num-gpus", "64", "--device", "cuda"], "--num-gpus 64 but"),
])
def test_ambulo_eval_refuses_a_bad_num_gpus_in_one_line(cartpole_run, capsys, flags, message):
    from ambulo.cli import main

    try:
        status = main(["eval", str(cartpole_run), *flags])
    except SystemExit as exit:  # argparse's own refusal (--num-gpus 0)
        status = exit.code
    assert status == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
