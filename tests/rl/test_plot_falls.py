"""scripts/plot_falls.py: each robot's path over the hardest tile of a kind, and which fell. Its falls
are those ``ambulo eval`` counts for the same run, seed, episodes and terrain (an independent loop)."""

from __future__ import annotations

import pytest

from ambulo.rl import evaluate, train
from script_loader import ROOT, load_script

plot_falls = load_script(ROOT / "scripts" / "plot_falls.py")
SMALL = {"terrain.num_levels": 3, "terrain.tile_size_m": 4.0, "terrain.platform_size_m": 1.0,
         "terrain.border_m": 1.0, "num_threads": 1}


@pytest.fixture(scope="module")
def rough_run(tmp_path_factory):
    """A barely trained humanoid-rough policy: it falls in most 3 s episodes."""
    return train("humanoid-rough", num_envs=4, max_iterations=2, seed=0, log_root=tmp_path_factory.mktemp("runs"),
                 env_overrides=SMALL, ppo_overrides={"num_steps_per_env": 4, "num_mini_batches": 1})


def test_the_falls_are_those_ambulo_eval_counts(rough_run):
    paths, fell, grid = plot_falls.kind_paths(rough_run, "model_1.pt", "stairs_down", episodes=6, seed=3,
                                              episode_length_s=3.0)
    reference = evaluate(rough_run, checkpoint="model_1.pt", num_episodes=6, episode_length_s=3.0, seed=3,
                         quiet=True, device="cpu", env_overrides={"terrain.kinds": ("stairs_down",)})
    assert fell.mean() == pytest.approx(reference["fall_rate"]) and 0 < fell.sum()
    assert paths.shape == (150, 6, 2)  # 3 s at 50 Hz, one path a robot
    started = paths[0] - grid.tile_centers_w[-1, 0, :2]  # every robot starts on the hardest tile's platform
    assert abs(started).max() <= grid.cfg.platform_size_m / 2
    for i in range(6):  # a path ends with its episode (nan after)
        ended = paths[:, i, 0] != paths[:, i, 0]
        assert ended.any() == bool(fell[i]) and (not ended.any() or ended[ended.argmax():].all())


def test_the_script_writes_the_picture(rough_run, tmp_path, capsys):
    out = tmp_path / "falls.png"
    plot_falls.main([str(rough_run), "--checkpoint", "model_1.pt", "--kinds", "stepping_stones,flat",
                     "--episodes", "3", "--episode-length-s", "0.5", "--out", str(out)])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("stepping_stones: fall rate") and lines[1].startswith("flat: fall rate")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_shipped_walkers_falls_are_those_ambulo_eval_counts():
    from ambulo.rl.evaluate import evaluate_shipped

    _, fell, _ = plot_falls.kind_paths(None, None, "stairs_down", episodes=4, seed=5, episode_length_s=2.0,
                                       shipped="humanoid-rough")
    reference = evaluate_shipped("humanoid-rough", num_episodes=4, episode_length_s=2.0, seed=5, quiet=True,
                                 env_overrides={"terrain.kinds": ("stairs_down",)})
    assert fell.mean() == pytest.approx(reference["fall_rate"])


def test_bad_input_gets_one_line(capsys, tmp_path):
    out = str(tmp_path / "x.png")
    for argv, says in ((["--out", out], "give a run folder with --checkpoint, or --shipped TASK"),
                       (["--shipped", "humanoid-walk", "--out", out], "task humanoid-walk has no terrain tiles"),
                       (["--shipped", "humanoid-rough", "--kinds", "stones", "--episodes", "1", "--out", out],
                        "unknown ['stones']")):
        with pytest.raises(SystemExit):
            plot_falls.main(argv)
        assert says in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()
