"""metrics.csv's ``terrain_level`` column: the mean level of a terrain curriculum (then each tile
kind's, ``terrain_level_<kind>``), written once an iteration by PPO and the off-policy runner, absent for every other task (their files keep their
layout byte for byte), and kept safe across resumes (``rl.metrics``' rule: a resume keeps every
recorded column and adds the run's own, earlier rows empty there)."""

import csv
from types import SimpleNamespace

import pytest
import torch

import ambulo.envs as envs
from ambulo.envs.terrain_ground import TerrainGround
from ambulo.rl import train
from ambulo.rl.interrupt import StopRequest
from ambulo.rl.metrics import COLUMNS, TERRAIN_LEVEL, MetricsCsv
from ambulo.rl.progress import TrainingProgress

BASE_HEADER = ",".join(COLUMNS)
KINDS = ("flat", "rough", "slope_up", "slope_down", "stairs_up", "stairs_down", "stepping_stones")
LEVEL_COLUMNS = (TERRAIN_LEVEL, *(f"{TERRAIN_LEVEL}_{kind}" for kind in KINDS))
"""humanoid-rough's: the mean level, then each tile kind's."""
# 3 levels of 4 m tiles; 0.1 s episodes (5 policy steps) end inside an iteration, so the curriculum
# moves robots from their first level (the hardest) before the first row is written
SMALL = {"terrain.num_levels": 3, "terrain.tile_size_m": 4.0, "terrain.platform_size_m": 1.0,
         "terrain.border_m": 1.0, "num_threads": 1, "episode_length_s": 0.1, "curriculum.init_level": 2}
TINY_SAC = {"num_steps_per_env": 4, "actor_hidden_dims": (16,), "critic_hidden_dims": (16,), "batch_size": 16,
            "num_atoms": 11, "updates_per_step": 1}


def _table(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _progress(run_dir, env, start=0):
    """A ``TrainingProgress`` over a stand-in runner holding ``env`` as the runners do (``runner.env.env``)."""
    runner = SimpleNamespace(device="cpu", env=SimpleNamespace(env=env))
    return TrainingProgress(runner, run_dir, start=start, total=10, episodes=SimpleNamespace(means=lambda: (2.0, 50)),
                            verbose=True, step_dt_s=0.02, steps_per_iteration=64, stop=StopRequest())


# -- the CSV and its resume rule -------------------------------------------------------------------


def test_a_task_without_a_curriculum_writes_the_same_bytes_as_before(tmp_path):
    path = tmp_path / "metrics.csv"
    MetricsCsv(path).append(0, 64, 1.0, 0.5, 0.01, 0.02, 1.0)
    assert path.read_bytes() == (f"{BASE_HEADER}\r\n0,64,1.0000,0.500,2133,0.010,0.020,1.0000\r\n").encode()
    # through TrainingProgress: an env without the hook (cartpole's) and one whose levels are fixed
    for i, env in enumerate((SimpleNamespace(), SimpleNamespace(mean_terrain_level=lambda: None))):
        run_dir = tmp_path / str(i)
        run_dir.mkdir()
        progress = _progress(run_dir, env)
        progress.iteration_done(0, 0.5, 0.5, 1.0)
        progress.close()
        assert (run_dir / "metrics.csv").read_text().splitlines()[0] == BASE_HEADER


def test_training_progress_writes_the_envs_level_each_iteration(tmp_path):
    levels = iter([1.5, 1.25, float("nan")])
    env = SimpleNamespace(mean_terrain_level=lambda: torch.tensor(next(levels)))
    progress = _progress(tmp_path, env)  # its first call (at construction) decides the column
    for it in range(2):
        progress.iteration_done(it, 0.5, 0.5, 1.0)
    progress.close()
    assert (tmp_path / "metrics.csv").read_text().splitlines()[0] == f"{BASE_HEADER},{TERRAIN_LEVEL}"
    assert [r[TERRAIN_LEVEL] for r in _table(tmp_path / "metrics.csv")] == ["1.2500", ""]  # nan: empty


def test_resuming_an_old_file_adds_the_column_and_keeps_its_rows(tmp_path):
    path = tmp_path / "metrics.csv"
    old = MetricsCsv(path)  # a run from before the column existed
    for it in range(5):
        old.append(it, 64, 1.0 + it, 0.5, 0.01, 0.02, 1.0)
    with open(path, "a") as f:
        f.write("5,3")  # a kill cut iteration 5's row short
    progress = _progress(tmp_path, SimpleNamespace(mean_terrain_level=lambda: torch.tensor(2.0)), start=3)
    progress.iteration_done(3, 0.01, 0.02, 1.0)
    progress.close()
    table = _table(path)
    assert tuple(table[0]) == (*COLUMNS, TERRAIN_LEVEL)
    assert [r["iteration"] for r in table] == ["0", "1", "2", "3"]
    assert [r["mean_reward"] for r in table[:3]] == ["1.0000", "2.0000", "3.0000"]  # recorded values kept
    assert [r[TERRAIN_LEVEL] for r in table] == ["", "", "", "2.0000"]  # not recorded before: empty, not 0


def test_resuming_without_the_column_keeps_the_recorded_levels(tmp_path):
    path = tmp_path / "metrics.csv"
    with_level = MetricsCsv(path, extra_columns=(TERRAIN_LEVEL,))
    for it in range(3):
        with_level.append(it, 64, 1.0, 0.5, 0.01, 0.02, 1.0, {TERRAIN_LEVEL: 0.5 * it})
    row = MetricsCsv(path, start=2).append(2, 64, 1.0, 0.5, 0.01, 0.02, 1.0)
    table = _table(path)
    assert tuple(table[0]) == (*COLUMNS, TERRAIN_LEVEL) and len(row) == len(COLUMNS) + 1
    assert [r[TERRAIN_LEVEL] for r in table] == ["0.0000", "0.5000", ""]
    MetricsCsv(path, start=0)  # a new run in the folder starts a new file, with its own columns
    assert path.read_bytes() == f"{BASE_HEADER}\r\n".encode()


# -- the env's hook --------------------------------------------------------------------------------


def test_each_kind_reports_the_mean_level_of_its_robots_a_repeated_kind_pooled():
    rough = envs.make("humanoid-rough", num_envs=7, seed=0,
                      **{**SMALL, "terrain.kinds": ("flat", "stairs_up", "flat")})
    try:
        # env i on column i % 3: flat gets envs 0, 2, 3, 5, 6; stairs_up envs 1, 4
        rough.curriculum.levels[:] = torch.tensor([0, 2, 1, 2, 1, 0, 2])
        names, levels = rough.terrain_levels_by_kind()
        assert names == ("flat", "stairs_up")
        assert levels.tolist() == pytest.approx([(0 + 1 + 2 + 0 + 2) / 5, (2 + 1) / 2])
    finally:
        rough.close()


def test_only_a_moving_curriculum_reports_a_level():
    rough = envs.make("humanoid-rough", num_envs=3, seed=0, **SMALL)
    stairs = envs.make("humanoid-footsteps-stairs", num_envs=3, seed=0, num_threads=1,
                       **{"terrain.num_levels": 2, "terrain.tile_size_m": 4.0, "terrain.platform_size_m": 1.0,
                          "terrain.border_m": 1.0})
    try:
        rough.curriculum.levels[:] = torch.tensor([0, 1, 1])
        assert rough.mean_terrain_level().item() == pytest.approx(2 / 3)
        assert stairs.mean_terrain_level() is None  # each robot keeps its level (no curriculum)
        assert stairs.terrain_levels_by_kind() is None
    finally:
        rough.close()
        stairs.close()


# -- tiny training runs on humanoid-rough, CPU -----------------------------------------------------


@pytest.fixture
def recorded(monkeypatch):
    """Every level the env's hook returned, as a float (the constructor's call first)."""
    seen = []
    hook = TerrainGround.mean_terrain_level

    def recording(self):
        level = hook(self)
        seen.append(float(level))
        return level

    monkeypatch.setattr(TerrainGround, "mean_terrain_level", recording)
    return seen


@pytest.mark.parametrize("algo", [None, "fast-sac"])
def test_training_on_the_terrain_writes_the_curriculums_level(tmp_path, recorded, algo):
    if algo is None:
        run = train("humanoid-rough", num_envs=4, max_iterations=3, seed=0, log_root=tmp_path, env_overrides=SMALL,
                    ppo_overrides={"num_steps_per_env": 4, "num_mini_batches": 1})
    else:
        run = train("humanoid-rough", algo=algo, num_envs=4, max_iterations=3, seed=0, log_root=tmp_path,
                    env_overrides=SMALL, algo_overrides=TINY_SAC)
    table = _table(run / "metrics.csv")
    assert tuple(table[0]) == (*COLUMNS, *LEVEL_COLUMNS)
    assert [r["iteration"] for r in table] == ["0", "1", "2"]
    assert recorded[0] == 2.0  # at construction: every robot on its first level
    written = [float(r[TERRAIN_LEVEL]) for r in table]
    assert written == pytest.approx(recorded[1:], abs=5e-5)  # one read an iteration, the env's own
    assert written[0] < 2.0  # the curriculum moved robots down in the first iteration: the column follows it
    for row in table:  # 4 robots on the first 4 kinds, one each: their levels average to the mean
        each = [row[f"{TERRAIN_LEVEL}_{kind}"] for kind in KINDS]
        assert each[4:] == ["", "", ""]  # no robot on stairs or stones
        assert sum(float(v) for v in each[:4]) / 4 == pytest.approx(float(row[TERRAIN_LEVEL]), abs=2e-4)
        assert all(float(v) in (0.0, 1.0, 2.0) for v in each[:4])  # one robot's level: a whole number


def test_resuming_a_run_from_before_the_column_adds_it(tmp_path):
    fast = {"num_steps_per_env": 4, "num_mini_batches": 1, "save_interval": 1}
    run = train("humanoid-rough", num_envs=4, max_iterations=3, seed=0, log_root=tmp_path, env_overrides=SMALL,
                ppo_overrides=fast)
    path = run / "metrics.csv"
    old = _table(path)
    with open(path, "w", newline="") as f:  # the file as a run from before the column wrote it
        writer = csv.DictWriter(f, COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(old)
    (run / "model_2.pt").unlink()  # killed during iteration 2: the resume repeats it
    train(resume=run, max_iterations=4)
    table = _table(path)
    assert tuple(table[0]) == (*COLUMNS, *LEVEL_COLUMNS)
    assert [r["iteration"] for r in table] == ["0", "1", "2", "3"]
    assert [r["mean_reward"] for r in table[:2]] == [r["mean_reward"] for r in old[:2]]
    assert [r[TERRAIN_LEVEL] for r in table[:2]] == ["", ""]
    assert all(0.0 <= float(r[TERRAIN_LEVEL]) <= 2.0 for r in table[2:])
