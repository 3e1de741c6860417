"""A terrain task's evaluation, tile kind by tile kind (``rl.eval_kinds``): each kind's episodes summarized
alone from the episodes it ran (env ``i`` on kind ``i % K``), reported and never judged (the criteria stay
pooled), merged kind by kind over processes; a task without terrain has no ``by_kind``."""

import csv
import importlib
import json
from types import SimpleNamespace

import pytest
import torch

from ambulo import envs
from ambulo.envs.humanoid_walk import WALKS
from ambulo.rl import periodic_eval, train
from ambulo.rl.eval_kinds import kinds_cell, kinds_from_text, kinds_table, tile_kinds
from ambulo.rl.periodic_eval import EVAL_COLUMNS
from ambulo.scenes.terrain import TerrainCfg
from script_loader import ROOT, load_script

TASK = envs.TaskSpec(name="kinds-fake", env_cls=envs.RLEnv, cfg_fn=envs.EnvCfg, description="", criteria=(WALKS,))
STEP_DT_S, MAX_STEPS = 0.02, 1000
KINDS = ("flat", "stairs_up", "stairs_down")
evaluate = importlib.import_module("ambulo.rl.evaluate")  # the module (ambulo.rl.evaluate is also its function)

# 20 episodes on 3 kinds (i % 3: 7, 7, 6 episodes); the one fall is on stairs_up (episode 4): pooled
# 1 / 20 = 0.05 meets WALKS' bar, stairs_up's 1 / 7 does not
VEL = [0.10, 0.30, 0.05, 0.12, 0.25, 0.08, 0.11, 0.28, 0.06, 0.09,
       0.35, 0.07, 0.10, 0.22, 0.04, 0.13, 0.31, 0.05, 0.12, 0.27]
FELL = [i == 4 for i in range(20)]
RETURNS = [float(i) for i in range(20)]


def records(vel=VEL, fell=FELL, returns=RETURNS) -> evaluate.EpisodeRecords:
    n = len(vel)
    return evaluate.EpisodeRecords(torch.tensor(fell), torch.zeros(n, dtype=torch.bool),
                                   torch.tensor(returns[:n], dtype=torch.float64),
                                   torch.tensor([MAX_STEPS / 4 if f else MAX_STEPS for f in fell], dtype=torch.float64),
                                   {"abs_vel_error_m_s": torch.tensor(vel, dtype=torch.float64)})


def run_on(recs: evaluate.EpisodeRecords, monkeypatch, *, terrain: bool = True, merge=None) -> dict:
    """``run_episodes`` with its rollout bypassed: the episodes did what ``recs`` says, env ``i`` on kind
    ``i % 3`` as the terrain curriculum lays them out (``terrain``: the env has tile kinds)."""
    monkeypatch.setattr(evaluate, "episode_records", lambda *args, **kwargs: recs)
    n = len(recs.failed)
    env = SimpleNamespace(num_envs=n, step_dt_s=STEP_DT_S, max_episode_length=MAX_STEPS)
    if terrain:
        env.tile_kinds = lambda: (KINDS, torch.arange(n) % len(KINDS))
    return evaluate.run_episodes(env, None, None, TASK, merge=merge)


def test_each_kind_is_summarized_from_its_own_episodes(monkeypatch):
    by_kind = run_on(records(), monkeypatch)["by_kind"]
    assert list(by_kind) == list(KINDS)
    for k, name in enumerate(KINDS):
        rows = range(k, 20, 3)  # env i is on kind i % 3
        kind = by_kind[name]
        assert kind["episodes"] == len(rows)
        assert kind["mean_abs_vel_error_m_s"] == pytest.approx(sum(VEL[i] for i in rows) / len(rows))
        assert kind["fall_rate"] == pytest.approx(sum(FELL[i] for i in rows) / len(rows))
        assert kind["mean_return"] == pytest.approx(sum(RETURNS[i] for i in rows) / len(rows))
        steps = [MAX_STEPS / 4 if FELL[i] else MAX_STEPS for i in rows]
        assert kind["mean_episode_length_s"] == pytest.approx(sum(steps) / len(rows) * STEP_DT_S)
    assert by_kind["stairs_up"]["fall_rate"] == pytest.approx(1 / 7) and by_kind["flat"]["fall_rate"] == 0.0


def test_the_kinds_pool_back_to_the_whole(monkeypatch):
    """The episode-weighted means of the kinds are the pooled figures."""
    result = run_on(records(), monkeypatch)
    kinds = result["by_kind"].values()
    assert sum(k["episodes"] for k in kinds) == result["episodes"] == 20
    for key in ("fall_rate", "mean_abs_vel_error_m_s", "mean_return", "mean_episode_length_s"):
        pooled = sum(k[key] * k["episodes"] for k in kinds) / result["episodes"]
        assert pooled == pytest.approx(result[key]), key


def test_kinds_are_reported_not_judged(monkeypatch):
    """stairs_up falls 1 in 7 (WALKS asks <= 5 %); pooled 1 in 20 meets it: the criterion holds, and the
    result is the one without terrain plus ``by_kind``."""
    with_kinds = run_on(records(), monkeypatch)
    without = run_on(records(), monkeypatch, terrain=False)
    assert with_kinds["walks"] is True and with_kinds["fall_rate"] == pytest.approx(0.05)
    assert not WALKS.holds(with_kinds["by_kind"]["stairs_up"])
    assert all("walks" not in k and "criteria" not in k for k in with_kinds["by_kind"].values())
    assert {k: v for k, v in with_kinds.items() if k != "by_kind"} == without
    worse = records(fell=[i == 4 or i == 7 for i in range(20)])  # two falls: 0.1 pooled
    assert run_on(worse, monkeypatch)["walks"] is False


def test_a_task_without_terrain_has_no_by_kind(monkeypatch):
    result = run_on(records(), monkeypatch, terrain=False)
    assert list(result) == ["task", "episodes", "episode_length_s", "fall_rate", "success_rate", "mean_return",
                            "mean_episode_length_s", "mean_abs_vel_error_m_s", "criteria", "walks"]
    assert kinds_cell(result) == "" and kinds_from_text("") == {}


def test_kinds_merge_kind_by_kind_over_processes_and_an_empty_kind_is_left_out(monkeypatch):
    """A merge that adds another process's share (the same episodes again) reaches each kind, the empty
    one too (every rank makes the same collectives); a kind no process ran is not reported."""
    merged = []

    def twice(sums):
        merged.append(sums.episodes)
        return sums + sums

    result = run_on(records(), monkeypatch, merge=twice)
    assert [k["episodes"] for k in result["by_kind"].values()] == [14, 14, 12] and result["episodes"] == 40
    assert result["by_kind"]["stairs_up"]["fall_rate"] == pytest.approx(1 / 7)
    merged.clear()
    two = run_on(records(VEL[:2], FELL[:2]), monkeypatch, merge=twice)  # 2 episodes, 3 kinds
    assert merged == [2.0, 1.0, 1.0, 0.0]  # the whole, then every kind
    assert list(two["by_kind"]) == ["flat", "stairs_up"]


def test_the_evals_csv_cell_and_the_table(monkeypatch):
    result = run_on(records(), monkeypatch)
    cell = kinds_cell(result)
    read = kinds_from_text(cell)
    assert list(read) == list(KINDS)
    for name, (fall_rate, vel_error) in read.items():
        kind = result["by_kind"][name]
        assert fall_rate == round(kind["fall_rate"], 3) and vel_error == round(kind["mean_abs_vel_error_m_s"], 4)
    assert "," not in cell  # one CSV cell, unquoted readers see it whole
    lines = kinds_table(result["by_kind"]).splitlines()
    assert lines[0].split() == ["tile", "kind", "episodes", "fall_rate", "episode_length_s", "abs_vel_error_m_s"]
    assert lines[2].split()[:3] == ["stairs_up", "7", f"{1 / 7:.3f}"] and "not judged" in lines[-1]


# -- real terrain envs, tiny: a humanoid-rough run of one PPO iteration (an untrained policy) ---------------

@pytest.fixture(scope="module")
def rough_run(tmp_path_factory):
    """humanoid-rough on 7 worlds, one PPO iteration of 4 steps, evaluated every iteration (100 episodes
    of 0.1 s instead of the task's 20 s)."""
    patch = pytest.MonkeyPatch()
    patch.setattr(periodic_eval, "eval_episode_length_s", lambda task, seconds: 0.1)
    try:
        return train("humanoid-rough", num_envs=7, max_iterations=1, seed=0, log_root=tmp_path_factory.mktemp("runs"),
                     eval_every=1, ppo_overrides={"num_steps_per_env": 4, "num_mini_batches": 1},
                     env_overrides={"num_threads": 1})
    finally:
        patch.undo()


def test_ambulo_eval_of_a_terrain_run_reports_and_prints_each_kind(rough_run, capsys):
    result = evaluate.evaluate(rough_run, num_episodes=21, episode_length_s=0.1, quiet=False)
    names = TerrainCfg().kinds
    by_kind = result["by_kind"]
    assert list(by_kind) == list(names) and [k["episodes"] for k in by_kind.values()] == [3] * 7
    for key in ("fall_rate", "mean_abs_vel_error_m_s", "mean_abs_yaw_rate_error_rad_s", "mean_return"):
        assert sum(k[key] * 3 for k in by_kind.values()) / 21 == pytest.approx(result[key]), key
    (criterion,) = envs.spec("humanoid-rough").criteria
    assert result[criterion.name] == criterion.holds(result)  # judged on the pooled episodes
    assert json.loads((rough_run / "eval.json").read_text())["by_kind"] == by_kind
    out = capsys.readouterr().out
    printed = json.loads(out[out.index("{"):out.index("tile kind")])
    assert "by_kind" not in printed and printed["episodes"] == 21  # the JSON as before, the table after it
    for name, kind in by_kind.items():
        assert f"\n{name} " in out and f"{kind['mean_abs_vel_error_m_s']:.3f}" in out


def test_the_periodic_evaluation_writes_a_readable_by_kind_column(rough_run):
    (row,) = csv.DictReader(open(rough_run / "evals.csv"))
    assert list(row) == list(EVAL_COLUMNS) and row["eval_engine"] == "training"
    kinds = kinds_from_text(row["by_kind"])
    assert list(kinds) == ["flat", "rough", "slope_up", "slope_down", "stairs_up", "stairs_down", "stepping_stones"]
    counts = [15, 15, 14, 14, 14, 14, 14]  # 100 episodes, env i on kind i % 7
    pooled_fall = sum(n * fall for n, (fall, _) in zip(counts, kinds.values())) / 100
    assert pooled_fall == pytest.approx(float(row["fall_rate"]), abs=2e-3)  # cells of 3 decimals
    pooled_err = sum(n * err for n, (_, err) in zip(counts, kinds.values())) / 100
    metrics = {k: float(v) for k, v in (p.split("=") for p in row["metrics"].split())}
    assert pooled_err == pytest.approx(metrics["mean_abs_vel_error_m_s"], abs=2e-4)
    plot = load_script(ROOT / "scripts" / "plot_eval_curves.py")
    assert len(plot.read_evals(rough_run / "evals.csv")) == 1  # today's reader reads it
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(rough_run))
    events.Reload()
    (stones,) = events.Scalars("eval_by_kind/stepping_stones/fall_rate")
    assert stones.step == 0 and stones.value == pytest.approx(kinds["stepping_stones"][0], abs=1e-3)
    assert "eval_by_kind/flat/mean_abs_vel_error_m_s" in events.Tags()["scalars"]


def test_every_terrain_task_has_tile_kinds_and_others_do_not():
    stairs = envs.make("humanoid-footsteps-stairs", num_envs=5, seed=0, num_threads=1, play=True)
    names, kind = tile_kinds(stairs)
    assert names == ("flat", "stairs_up", "stairs_down") and kind.tolist() == [0, 1, 2, 0, 1]
    # each env's robot starts on its kind's column of the hardest row
    assert torch.equal(stairs.tiles.origins_w, torch.as_tensor(stairs.terrain.tile_centers_w[-1][kind.numpy()],
                                                                dtype=torch.float32))
    stairs.close()
    walk = envs.make("humanoid-walk", num_envs=2, seed=0, num_threads=1)
    assert tile_kinds(walk) is None
    walk.close()


def test_an_evaluation_split_over_processes_merges_each_kind(rough_run):
    """``ambulo eval --num-gpus 2``'s machinery on 2 CPU processes (gloo): 14 episodes, 7 a process, each
    kind's 2 episodes one on each."""
    from ambulo.rl.eval_gpus import evaluate_split

    split = evaluate_split(rough_run, processes=2, device="cpu", num_episodes=14, episode_length_s=0.1, quiet=True)
    assert split["episodes"] == 14 and [k["episodes"] for k in split["by_kind"].values()] == [2] * 7
    pooled = sum(k["mean_abs_vel_error_m_s"] * 2 for k in split["by_kind"].values()) / 14
    assert pooled == pytest.approx(split["mean_abs_vel_error_m_s"])


def test_the_training_console_names_the_kind_with_the_most_falls(monkeypatch):
    result = run_on(records(), monkeypatch)
    stairs = sum(VEL[i] for i in range(1, 20, 3)) / 7
    line = periodic_eval.summary(result, 0, 60.0)
    assert line.endswith(f"; most falls on stairs_up tiles (fall rate 0.14, abs_vel_error_m_s {stairs:.3f})")
    assert "most falls" not in periodic_eval.summary(run_on(records(), monkeypatch, terrain=False), 0, 60.0)
