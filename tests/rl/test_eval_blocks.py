"""Evaluations laid out in blocks (``rl.eval_blocks``): each block summarized alone, the criteria holding
only where they hold in every block; humanoid-walk-robust's blocks are nominal + the 16 transfer corners,
and every place a criterion is judged (``ambulo eval``, ``--eval-every`` and its CPU-engine confirmation,
the shares of several processes) evaluates them."""

import csv
import importlib
import json
from types import SimpleNamespace

import pytest
import torch

from ambulo import envs
from ambulo.envs.cartpole import CartpoleEnv, cartpole_cfg, cartpole_ppo
from ambulo.envs.humanoid_walk_robust import WALKS_ROBUST
from ambulo.envs.transfer import TransferCfg, transfer_corners
from ambulo.rl import periodic_eval
from ambulo.rl.distributed import Rank
from ambulo.rl.eval_blocks import blocks_table, eval_layout
from ambulo.rl.eval_share import eval_share
from ambulo.rl.vecenv import RslRlVecEnv

TASK = envs.TaskSpec(name="blocks-fake", env_cls=envs.RLEnv, cfg_fn=envs.EnvCfg, description="",
                     criteria=(WALKS_ROBUST,))
STEP_DT_S, MAX_STEPS = 0.02, 1000
registry = importlib.import_module("ambulo.envs.registry")  # likewise (ambulo.envs.registry())
evaluate = importlib.import_module("ambulo.rl.evaluate")  # the module (ambulo.rl.evaluate is also its function)


def hand_made(vel_errors: list[float], failed: list[bool]) -> evaluate.EpisodeRecords:
    n = len(vel_errors)
    return evaluate.EpisodeRecords(torch.tensor(failed), torch.zeros(n, dtype=torch.bool),
                                   torch.ones(n, dtype=torch.float64),
                                   torch.tensor([MAX_STEPS / 2 if f else MAX_STEPS for f in failed],
                                                dtype=torch.float64),
                                   {"abs_vel_error_m_s": torch.tensor(vel_errors, dtype=torch.float64)})


def run_on(records: evaluate.EpisodeRecords, names, monkeypatch, merge=None) -> dict:
    """``run_episodes`` with its rollout bypassed: the episodes did what ``records`` says."""
    monkeypatch.setattr(evaluate, "episode_records", lambda *args, **kwargs: records)
    env = SimpleNamespace(num_envs=len(records.failed), step_dt_s=STEP_DT_S, max_episode_length=MAX_STEPS)
    return evaluate.run_episodes(env, None, None, TASK, blocks=names, merge=merge)


# 3 blocks of 2 episodes; block "b" misses the velocity bar alone: (0.25 + 0.19) / 2 = 0.22 > 0.2
VEL = [0.10, 0.20, 0.25, 0.19, 0.05, 0.05]
FELL = [False, False, False, False, True, False]


def test_each_block_is_summarized_alone_with_hand_computed_values(monkeypatch):
    result = run_on(hand_made(VEL, FELL), ("a", "b", "c"), monkeypatch)
    a, b, c = result["blocks"]
    assert [a["name"], b["name"], c["name"]] == ["a", "b", "c"] and a["episodes"] == 2
    assert a["mean_abs_vel_error_m_s"] == pytest.approx(0.15)
    assert b["mean_abs_vel_error_m_s"] == pytest.approx(0.22)
    assert c["mean_abs_vel_error_m_s"] == pytest.approx(0.05) and c["fall_rate"] == 0.5
    assert a["fall_rate"] == b["fall_rate"] == 0.0
    assert c["mean_episode_length_s"] == pytest.approx((500 + 1000) / 2 * STEP_DT_S)
    # the whole pools every episode
    assert result["episodes"] == 6 and result["fall_rate"] == pytest.approx(1 / 6)
    assert result["mean_abs_vel_error_m_s"] == pytest.approx(sum(VEL) / 6)
    assert [a["walks_robust"], b["walks_robust"], c["walks_robust"]] == [True, False, False]
    assert result["blocks_failed"] == ["b", "c"] and result["worst_block"] == "c"  # fall rate 10x its bar


def test_the_criterion_fails_when_exactly_one_block_fails(monkeypatch):
    """Block b alone misses the bar; pooled over the blocks the velocity error passes (0.14 <= 0.2): the
    pooled judgement would call it robust."""
    fell = [False] * 6
    result = run_on(hand_made(VEL, fell), ("a", "b", "c"), monkeypatch)
    assert result["mean_abs_vel_error_m_s"] == pytest.approx(0.14) and result["fall_rate"] == 0.0
    assert WALKS_ROBUST.holds(result)  # the bars on the pooled numbers hold ...
    assert result["walks_robust"] is False  # ... the criterion does not
    assert result["blocks_failed"] == ["b"] and result["worst_block"] == "b"
    fixed = list(VEL)
    fixed[2] = 0.15  # block b: (0.15 + 0.19) / 2 = 0.17
    result = run_on(hand_made(fixed, fell), ("a", "b", "c"), monkeypatch)
    assert result["walks_robust"] is True and result["blocks_failed"] == []
    assert result["worst_block"] == "b"  # the nearest to its bar: 0.17 / 0.2
    table = blocks_table(result)
    assert "* b " in table and "3 of 3 blocks pass" in table


def test_blocks_merge_block_by_block_over_processes(monkeypatch):
    """A merge that adds another process's share (here: the same episodes again) reaches each block."""
    result = run_on(hand_made(VEL, FELL), ("a", "b", "c"), monkeypatch, merge=lambda sums: sums + sums)
    assert [b["episodes"] for b in result["blocks"]] == [4, 4, 4] and result["episodes"] == 12
    assert result["blocks"][1]["mean_abs_vel_error_m_s"] == pytest.approx(0.22)


def test_shares_split_every_block():
    shares = [eval_share(340, 7, Rank(r, r, 3), blocks=17) for r in range(3)]  # 20 a block: 7 + 7 + 6
    assert [s.episodes for s in shares] == [7 * 17, 7 * 17, 6 * 17] and [s.first for s in shares] == [0, 7, 14]
    with pytest.raises(ValueError, match="give at least 51"):
        eval_share(34, 7, Rank(0, 0, 3), blocks=17)
    with pytest.raises(ValueError, match="multiple of 17"):
        eval_share(100, 7, Rank(), blocks=17)


def test_robust_layout_is_nominal_and_the_corners_and_says_what_to_pass():
    robust = envs.spec("humanoid-walk-robust")
    layout = eval_layout(robust)
    corners = transfer_corners()
    assert layout.num_episodes == 17 * 20 and layout.names == ("nominal", *corners)
    assert layout.env_overrides == {"transfer_blocks": (TransferCfg(), *corners.values())}
    assert eval_layout(robust, 34).num_episodes == 34
    with pytest.raises(ValueError, match=r"^humanoid-walk-robust's evaluation episode count is 100: .*"
                                         r"pass a multiple of 17 \(default 340"):
        eval_layout(robust, 100)
    assert eval_layout(envs.spec("humanoid-walk")).names == ()  # humanoid-walk: as before, 100 episodes
    assert eval_layout(envs.spec("humanoid-walk")).num_episodes == 100


def test_each_named_block_of_a_robust_evaluation_runs_under_its_corner():
    """A tiny real evaluation: 17 worlds, one a block, 5 policy steps."""
    robust = envs.spec("humanoid-walk-robust")
    layout = eval_layout(robust, 17)
    env = envs.make("humanoid-walk-robust", num_envs=17, seed=0, num_threads=1, play=True, episode_length_s=0.1,
                    **layout.env_overrides)
    result = evaluate.run_episodes(env, RslRlVecEnv(env), lambda obs: torch.zeros(17, env.num_actions), robust,
                                   blocks=layout.run_blocks)
    conditions = {"nominal": TransferCfg(), **transfer_corners()}
    assert [b["name"] for b in result["blocks"]] == list(conditions)
    assert [cfg for _, cfg in env.transfer.blocks] == list(conditions.values())
    kp = env.transfer.factors["kp_scale"][:, 0].tolist()
    expected = [1.0 if name == "nominal" else conditions[name].kp_scale_range[0] for name in conditions]
    assert kp[1:] == pytest.approx(expected[1:]) and all(k != k for k in kp[:1])  # nominal: no draw (NaN)
    assert result["walks_robust"] == all(b["walks_robust"] for b in result["blocks"])
    env.close()


BLOCKS_TASK = "cartpole-in-blocks"
CHEAT = envs.Criterion("upright_or_not", max_values={"fall_rate": 1.0})  # always holds: it is confirmed


@pytest.fixture(scope="module")
def blocked_gpu_like_run(tmp_path_factory):
    """cartpole with a 2-block evaluation (a weaker motor in both), trained 2 iterations with --eval-every 1
    --stop-at-criterion, its evaluation env declared another engine so the CPU engine confirms."""
    blocks = envs.EvalBlocks(names=("left", "right"), env_overrides={"max_force_n": 15.0}, episodes_per_block=3)
    envs.register(envs.TaskSpec(name=BLOCKS_TASK, env_cls=CartpoleEnv, cfg_fn=cartpole_cfg, ppo_cfg_fn=cartpole_ppo,
                                    description="", criteria=(CHEAT,), eval_blocks_fn=lambda: blocks))
    seen = []
    real = periodic_eval.run_episodes

    def recording(env, vec_env, policy, task, **kwargs):
        seen.append((env.cfg.engine, env.num_envs, env.cfg.max_force_n, kwargs["blocks"]))
        return real(env, vec_env, policy, task, **kwargs)

    patch = pytest.MonkeyPatch()
    patch.setattr(periodic_eval, "run_episodes", recording)
    patch.setattr(periodic_eval, "is_cpu_engine", lambda env: False)
    root = tmp_path_factory.mktemp("runs")
    try:
        from ambulo.rl import train

        train(BLOCKS_TASK, num_envs=16, max_iterations=3, seed=0, log_root=root, eval_every=1,
              stop_at_criterion=True)
    finally:
        patch.undo()
        registry._REGISTRY.pop(BLOCKS_TASK)
    return next(root.glob(f"{BLOCKS_TASK}/*")), seen


def test_periodic_evaluation_and_its_cpu_confirmation_run_the_blocks(blocked_gpu_like_run):
    run, seen = blocked_gpu_like_run
    assert [s[1:] for s in seen] == [(6, 15.0, ("left", "right"))] * 2  # the evaluation, then the confirmation
    assert seen[1][0] == "mujoco"
    reached = json.loads((run / "time_to_criterion.json").read_text())
    for result in (reached["eval"], reached["eval_cpu_engine"]):
        assert [b["name"] for b in result["blocks"]] == ["left", "right"]
        assert [b["episodes"] for b in result["blocks"]] == [3, 3] and result["upright_or_not"]
    (row,) = csv.DictReader(open(run / "evals.csv"))
    for cell, result in ((row["worst_block"], reached["eval"]), (row["cpu_engine_worst_block"], reached["eval_cpu_engine"])):
        name, numbers = periodic_eval.worst_block_from_text(cell)
        worst = next(b for b in result["blocks"] if b["name"] == name == result["worst_block"])
        assert numbers["fall_rate"] == round(worst["fall_rate"], 4) and numbers["blocks_failed"] == 0


@pytest.fixture(scope="module")
def robust_run(tmp_path_factory):
    """A humanoid-walk-robust run of one tiny PPO iteration (its policy barely differs from the initial one)."""
    from ambulo.rl import train

    return train("humanoid-walk-robust", num_envs=8, max_iterations=1, seed=0, log_root=tmp_path_factory.mktemp("runs"),
                 ppo_overrides={"num_steps_per_env": 4, "num_mini_batches": 1}, env_overrides={"num_threads": 1})


def test_ambulo_eval_judges_the_robust_task_in_its_blocks_and_prints_them(robust_run, capsys):
    from ambulo.rl.evaluate import evaluate as run_eval

    result = run_eval(robust_run, num_episodes=17, episode_length_s=0.1, quiet=False)
    assert [b["name"] for b in result["blocks"]] == ["nominal", *transfer_corners()]
    assert result["walks_robust"] == all(b["walks_robust"] for b in result["blocks"])
    assert json.loads((robust_run / "eval.json").read_text())["blocks"] == result["blocks"]
    out = capsys.readouterr().out
    assert f"* {result['worst_block']} " in out and "gains1.2_lat20ms_com+3+3+3cm" in out
    with pytest.raises(ValueError, match="pass a multiple of 17"):
        run_eval(robust_run, num_episodes=20, quiet=True)


def test_an_evaluation_split_over_processes_merges_each_block(robust_run):
    """``ambulo eval --num-gpus 2``'s machinery on 2 CPU processes (gloo): 34 episodes, each block's 2 as 1 + 1."""
    from ambulo.rl.eval_gpus import evaluate_split

    split = evaluate_split(robust_run, processes=2, device="cpu", num_episodes=34, episode_length_s=0.1, quiet=True)
    assert split["device"] == "cpu x 2" and split["episodes"] == 34
    assert [b["episodes"] for b in split["blocks"]] == [2] * 17
    assert [b["name"] for b in split["blocks"]] == ["nominal", *transfer_corners()]
