"""PPO (rsl-rl-lib) must solve cartpole on CPU; the run then plays, exports and evaluates."""

import csv

import numpy as np
import pytest
import torch

from ambulo.rl import evaluate, export, play, train
from ambulo.rl.runs import checkpoints, read_run_info


@pytest.fixture(scope="module")
def cartpole_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    return train("cartpole", max_iterations=60, seed=0, log_root=root), root


def test_ppo_solves_cartpole(cartpole_run):
    run_dir, _ = cartpole_run
    rows = list(csv.DictReader(open(run_dir / "metrics.csv")))
    assert [int(r["iteration"]) for r in rows] == list(range(60))
    # episodes are 5 s long; "solved" = the pole stays up for nearly all of them
    assert float(rows[-1]["mean_episode_length_s"]) >= 4.75
    assert float(rows[0]["mean_episode_length_s"]) < 2.0
    assert any(p.name.startswith("events.out.tfevents") for p in run_dir.iterdir())
    assert [it for it, _ in checkpoints(run_dir)] == [0, 20, 40, 59]
    assert read_run_info(run_dir)["task"] == "cartpole"


def test_tensorboard_reads_the_learning_curve(cartpole_run):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    run_dir, _ = cartpole_run
    events = EventAccumulator(str(run_dir))
    events.Reload()
    reward_tags = [t for t in events.Tags()["scalars"] if "mean_reward" in t]
    assert reward_tags, events.Tags()["scalars"]
    curve = [e.value for e in events.Scalars(reward_tags[0])]
    assert len(curve) >= 50
    assert np.mean(curve[-5:]) > np.mean(curve[:5])  # it learned


def test_eval_over_100_episodes(cartpole_run):
    run_dir, _ = cartpole_run
    result = evaluate(run_dir, num_episodes=100, episode_length_s=None, quiet=True)
    assert result["episodes"] == 100
    assert result["fall_rate"] <= 0.05
    assert result["mean_episode_length_s"] >= 4.75
    assert (run_dir / "eval.json").is_file()


def test_export_round_trip_with_onnxruntime(cartpole_run, tmp_path):
    import onnxruntime as ort

    run_dir, _ = cartpole_run
    result = export(run_dir, out_dir=tmp_path)
    assert result["onnx_max_abs_diff"] < 1e-4
    assert result["torchscript_max_abs_diff"] < 1e-5  # loaded in a fresh process
    # the ONNX file alone, on a fresh batch of another size, matches the trained actor
    obs = np.random.default_rng(0).normal(size=(7, 4)).astype(np.float32)
    session = ort.InferenceSession(str(result["onnx"]), providers=["CPUExecutionProvider"])
    onnx_actions = session.run(None, {"obs": obs})[0]
    state = torch.load(result["checkpoint"], weights_only=False)["actor_state_dict"]
    assert onnx_actions.shape == (7, 1)
    mean = state["obs_normalizer._mean"].numpy()
    std = state["obs_normalizer._std"].numpy()
    x = (obs - mean) / (std + 1e-2)
    layers = sorted(k for k in state if k.startswith("mlp.") and k.endswith(".weight"))
    for i, key in enumerate(layers):
        x = x @ state[key].numpy().T + state[key.replace("weight", "bias")].numpy()
        if i < len(layers) - 1:
            x = np.where(x > 0, x, np.expm1(x))  # ELU
    np.testing.assert_allclose(onnx_actions, x, atol=1e-4)


def test_play_writes_an_mp4(cartpole_run, tmp_path):
    import imageio.v3 as iio

    run_dir, _ = cartpole_run
    try:
        video = play(run_dir, seconds=0.5, out=tmp_path / "play.mp4", width=160, height=120)
    except RuntimeError as err:
        if "OpenGL" in str(err):
            pytest.skip(f"no OpenGL platform here: {err}")
        raise
    frames = iio.imread(video)
    assert frames.shape == (25, 120, 160, 3)
    assert frames.std() > 1.0  # not a blank image
