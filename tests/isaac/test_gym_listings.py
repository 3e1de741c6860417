"""The Isaac Gym listings of examples/isaacgym run under ``ambulo run`` on the CPU.

They hard-code 4096 envs (and rl_games' batch sizes for them); a CPU test runs them with only
those numbers lowered, the edit a user makes for a laptop run, in a copy.
"""

import shutil
from pathlib import Path

import pytest

from ambulo.isaac import run_script

LISTINGS = Path(__file__).resolve().parents[2] / "examples" / "isaacgym"


def _copy_with(src: Path, dst: Path, edits: dict[str, str]) -> Path:
    text = src.read_text()
    for old, new in edits.items():
        assert text.count(old) == 1, f"{src.name} no longer has exactly one {old!r}"
        text = text.replace(old, new)
    dst.write_text(text)
    return dst


def test_humanoid_walk_env_runs_its_policy_loop_for_an_iteration(tmp_path, monkeypatch, capsys):
    shutil.copytree(LISTINGS / "humanoid_walk", tmp_path / "walk")
    script = _copy_with(LISTINGS / "humanoid_walk" / "train.py", tmp_path / "walk" / "train.py",
                        {"HumanoidWalkEnv(num_envs=4096)": "HumanoidWalkEnv(num_envs=4)"})
    monkeypatch.chdir(tmp_path)
    # one iteration is 100 steps of 1/60 s: 1.7 s of budget runs one and stops in the second
    result = run_script(script, seconds=1.7)
    out = capsys.readouterr().out
    assert "Iteration 0, Mean Reward:" in out and "Iteration 1" not in out
    assert result.budget_spent and result.physics_steps == 102
    assert result.sim_time_s == pytest.approx(102 / 60)


@pytest.mark.slow
def test_rl_games_listing_trains_epochs_through_the_isaacgym_vecenv(tmp_path, monkeypatch, capsys):
    pytest.importorskip("rl_games")
    script = _copy_with(LISTINGS / "humanoid_locomotion_rl_games.py", tmp_path / "loco.py", {
        "num_envs: int = 4096": "num_envs: int = 8", "'num_actors': 4096": "'num_actors': 8",
        "'minibatch_size': 32768": "'minibatch_size': 64"})
    monkeypatch.chdir(tmp_path)
    # an epoch is 24 steps of 2 ms: 0.1 s runs two epochs
    result = run_script(script, seconds=0.1)
    out = capsys.readouterr().out
    assert "epoch: 2/5000" in out and result.budget_spent
    assert (tmp_path / "runs").is_dir()  # rl_games' summaries
