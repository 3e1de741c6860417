"""The ambulo command line: every command, its one-line errors, and typed --env-cfg/--ppo-cfg.

Tests marked with the ``fake_tasks`` fixture run against a small stand-in registry and a stand-in
``ambulo.rl.train`` (what the CLI itself does); the others go through the real task registry,
PpoCfg and commands.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from ambulo.cli import build_parser, main
from ambulo.cli import demo as cli_demo
from ambulo.cli import rl as cli_rl

SRC = str(Path(__file__).resolve().parents[2] / "src")


# --- a stand-in registry and trainer --------------------------------------------------------


@dataclass(frozen=True)
class FakePhysics:
    solver_iterations: int = 20


@dataclass(kw_only=True)
class FakeEnvCfg:
    num_envs: int = 64
    device: str = "cpu"
    seed: int = 0
    episode_length_s: float = 20.0
    push: bool = True
    friction_range: tuple[float, float] = (0.4, 1.2)
    reward_weights: dict[str, float] = field(default_factory=lambda: {"alive": 1.0})
    robot_file: str | None = None
    physics: FakePhysics = field(default_factory=FakePhysics)


@dataclass(kw_only=True)
class FakePpoCfg:
    num_envs: int = 4096
    max_iterations: int = 1500
    learning_rate: float = 1e-3
    schedule: Literal["adaptive", "fixed"] = "adaptive"
    actor_hidden_dims: tuple[int, ...] = (256, 128, 128)


@pytest.fixture
def fake_tasks(monkeypatch):
    """Tasks 'walk' and 'balance' with FakeEnvCfg / FakePpoCfg; returns the calls made to
    ``ambulo.rl.train`` (a stand-in module, so nothing trains)."""
    monkeypatch.setattr(cli_rl, "task_names", lambda: ["balance", "walk"])
    monkeypatch.setattr(cli_rl, "task_description", lambda name: f"the {name} task")
    monkeypatch.setattr(cli_rl, "default_env_cfg", lambda name: FakeEnvCfg())
    monkeypatch.setattr(cli_rl, "default_ppo_cfg", lambda name: FakePpoCfg())
    calls = []
    rl = types.ModuleType("ambulo.rl")
    rl.train = lambda *args, **kwargs: calls.append((args, kwargs))
    rl.RunError = type("RunError", (Exception,), {})
    rl.TrainingInterrupted = type("TrainingInterrupted", (KeyboardInterrupt,), {})
    monkeypatch.setitem(sys.modules, "ambulo.rl", rl)
    return calls


def one_error_line(capsys, command: str) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"ambulo {command}: error: "), err
    assert "Traceback" not in err
    return lines[0]


def fails(capsys, argv: list[str]) -> str:
    """Run ``ambulo argv``; assert exit status 2 and one error line; return that line."""
    try:
        status = main(argv)
    except SystemExit as exit_:  # argparse's own errors
        status = exit_.code
    assert status == 2
    return one_error_line(capsys, argv[0])


# --- the parser ----------------------------------------------------------------------------


def test_every_command_is_registered():
    commands = build_parser()._subparsers._group_actions[0].choices
    assert {"demo", "view", "generate", "train", "play", "export", "eval"} <= set(commands)


def test_train_help_lists_the_tasks(fake_tasks, capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    out = capsys.readouterr().out
    assert "balance  the balance task" in out and "walk" in out
    assert "--env-cfg" in out and "--ppo-cfg" in out


def test_argparse_errors_are_one_line(capsys):
    line = fails(capsys, ["train", "--num-envs", "many"])
    assert "--num-envs" in line and "see `ambulo train --help`" in line
    with pytest.raises(SystemExit) as exit_:
        main(["trian"])
    assert exit_.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_an_unknown_option_is_refused_by_its_command_naming_the_near_one(capsys):
    # argparse's top-level parser said `see ambulo --help` for `ambulo eval ... --num-episodes 10`
    line = fails(capsys, ["eval", "humanoid-walk", "--shipped", "--num-episodes", "10"])
    assert line.startswith("ambulo eval: error: unrecognized arguments: --num-episodes 10")
    assert "did you mean --episodes?" in line and "see `ambulo eval --help`" in line
    line = fails(capsys, ["plan", "--bogus-flag"])
    assert "unrecognized arguments: --bogus-flag; see `ambulo plan --help`" in line and "mean" not in line


def test_a_coordinate_list_starting_negative_is_a_value_not_an_option():
    # argparse read `--start -4,-2` as an option "-4,-2" and failed with "expected one argument"
    from ambulo.cli import _join_negative_values

    parser = build_parser()
    args = parser.parse_args(_join_negative_values(parser, ["plan", "--start", "-4,-2", "--goal", "-1.5e-1,2,-90"]))
    assert (args.start, args.goal) == ("-4,-2", "-1.5e-1,2,-90")
    # a flag takes no value, and `run` hands the rest to the script untouched
    assert _join_negative_values(parser, ["eval", "x", "--shipped", "-3"])[-2:] == ["--shipped", "-3"]
    run = ["run", "s.py", "--start", "-4,-2"]
    assert _join_negative_values(parser, run) == run


def test_python_dash_m_runs_the_cli():
    result = subprocess.run([sys.executable, "-m", "ambulo.cli", "generate", "--help"],
                            capture_output=True, text=True, env={**os.environ, "PYTHONPATH": SRC},
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert "usage: ambulo generate" in result.stdout


def test_console_script_is_ambulo_cli_main():
    text = (Path(SRC).parent / "pyproject.toml").read_text()
    assert 'ambulo = "ambulo.cli:main"' in text


# --- train: typed overrides ------------------------------------------------------------------


def test_env_cfg_values_reach_train_typed(fake_tasks):
    assert main(["train", "walk", "--env-cfg", "episode_length_s=10",
                 "--env-cfg", "push=false", "--env-cfg", "friction_range=0.5,1.0",
                 "--env-cfg", "reward_weights.alive=2", "--env-cfg", "robot_file=none"]) == 0
    (args, kwargs), = fake_tasks
    assert args == ("walk",)
    env = kwargs["env_overrides"]
    assert env == {"episode_length_s": 10.0, "push": False, "friction_range": (0.5, 1.0),
                   "reward_weights.alive": 2.0, "robot_file": None}
    assert type(env["episode_length_s"]) is float and type(env["friction_range"]) is tuple
    assert kwargs["ppo_overrides"] == {}


def test_env_cfg_dotted_key_reaches_train_as_a_json_safe_dotted_key(fake_tasks):
    assert main(["train", "walk", "--env-cfg", "physics.solver_iterations=50"]) == 0
    overrides = fake_tasks[0][1]["env_overrides"]
    assert overrides == {"physics.solver_iterations": 50}
    assert json.loads(json.dumps(overrides)) == overrides  # what run.json stores


def test_ppo_cfg_values_reach_train_typed(fake_tasks):
    assert main(["train", "walk", "--ppo-cfg", "learning_rate=3e-4", "--ppo-cfg", "schedule=fixed",
                 "--ppo-cfg", "actor_hidden_dims=64,64"]) == 0
    kwargs = fake_tasks[0][1]
    assert kwargs["ppo_overrides"] == {"learning_rate": 3e-4, "schedule": "fixed",
                                       "actor_hidden_dims": (64, 64)}
    assert kwargs["num_envs"] is None and kwargs["max_iterations"] is None


def test_ppo_cfg_sizes_go_to_the_flags(fake_tasks):
    assert main(["train", "walk", "--ppo-cfg", "num_envs=32", "--max-iterations", "5"]) == 0
    kwargs = fake_tasks[0][1]
    assert (kwargs["num_envs"], kwargs["max_iterations"], kwargs["ppo_overrides"]) == (32, 5, {})


def test_no_overrides_pass_empty_dicts(fake_tasks):
    assert main(["train", "balance", "--num-envs", "8", "--seed", "3"]) == 0
    kwargs = fake_tasks[0][1]
    assert kwargs["env_overrides"] == {} and kwargs["ppo_overrides"] == {}
    assert (kwargs["num_envs"], kwargs["seed"], kwargs["resume"]) == (8, 3, None)


@pytest.mark.parametrize("argv, needles", [
    (["--env-cfg", "episode_lenght_s=3"],
     ["--env-cfg unknown key 'episode_lenght_s' in FakeEnvCfg", "did you mean 'episode_length_s'"]),
    (["--env-cfg", "episode_length_s=long"],
     ["--env-cfg bad value 'long' for episode_length_s: expected float", "episode_length_s=20.0"]),
    (["--env-cfg", "push=yes"], ["expected bool (true/false/1/0)"]),
    (["--env-cfg", "friction_range=0.5"], ["expected tuple[float, float]", "give 2 values"]),
    (["--env-cfg", "physics.solver_iteration=5"], ["did you mean 'physics.solver_iterations'"]),
    (["--env-cfg", "reward_weights.alve=5"], ["did you mean 'reward_weights.alive'"]),
    (["--env-cfg", "episode_length_s"], ["expected KEY=VALUE"]),
    (["--env-cfg", "num_envs=8"], ["--env-cfg cannot set num_envs", "use --num-envs"]),
    (["--env-cfg", "device=cuda"], ["use --device"]),
    (["--ppo-cfg", "schedule=adaptiv"],
     ["--ppo-cfg bad value 'adaptiv' for schedule: expected one of 'adaptive', 'fixed'",
      "did you mean 'adaptive'"]),
    (["--ppo-cfg", "learning_rat=1"], ["did you mean 'learning_rate'"]),
    (["--ppo-cfg", "num_envs=8", "--num-envs", "16"], ["--num-envs and --ppo-cfg num_envs"]),
    (["--num-envs", "0"], ["argument --num-envs: '0' is not a whole number above 0",
                           "give e.g. --num-envs 64"]),
    (["--max-iterations", "1.5"], ["'1.5' is not a whole number above 0"]),
    (["--ppo-cfg", "num_envs=0"], ["--num-envs 0 is not positive"]),
    (["--resume", "--env-cfg", "push=false"], ["apply to new runs only"]),
])
def test_bad_train_input_is_one_line(fake_tasks, capsys, argv, needles):
    line = fails(capsys, ["train", "walk", *argv])
    for needle in needles:
        assert needle in line, line
    assert "; " in line
    assert not fake_tasks  # nothing ran


def test_unknown_task_names_close_ones(fake_tasks, capsys):
    line = fails(capsys, ["train", "wlak"])
    assert line == "ambulo train: error: no task named 'wlak'; did you mean 'walk'?"
    assert "tasks: balance, walk" in fails(capsys, ["train", "zzzz"])
    assert "no task given; name one: balance, walk" in fails(capsys, ["train"])


def test_resume_arguments(fake_tasks, capsys, tmp_path):
    (tmp_path / "run.json").write_text("{}")
    assert main(["train", "walk", "--resume"]) == 0
    assert fake_tasks[-1][1]["resume"] is True
    assert main(["train", "--resume", str(tmp_path)]) == 0
    assert fake_tasks[-1][1]["resume"] == str(tmp_path)
    assert "--resume without a run needs the task" in fails(capsys, ["train", "--resume"])
    assert "no run folder, checkpoint or task named" in fails(
        capsys, ["train", "--resume", str(tmp_path / "nothing")])


# --- play / export / eval / view / generate: bad input --------------------------------------


@pytest.mark.parametrize("command", ["play", "export", "eval"])
def test_missing_run_is_one_line(fake_tasks, capsys, tmp_path, command):
    line = fails(capsys, [command, str(tmp_path / "runs" / "walk" / "nope")])
    assert "no run folder, checkpoint or task named" in line and "ambulo train" in line
    assert "did you mean the task 'walk'" in fails(capsys, [command, "wlk"])
    line = fails(capsys, [command, str(tmp_path)])
    assert "is not a run folder (it holds no run.json)" in line
    (tmp_path / "notes.txt").write_text("")
    assert "is not a checkpoint" in fails(capsys, [command, str(tmp_path / "notes.txt")])


@pytest.mark.parametrize("command", ["play", "export", "eval"])
def test_missing_checkpoint_is_one_line(capsys, tmp_path, command):
    (tmp_path / "run.json").write_text("{}")
    line = fails(capsys, [command, str(tmp_path), "--checkpoint", str(tmp_path / "model_9.pt")])
    assert "checkpoint" in line and "not found" in line


def test_view_unknown_asset_names_the_bundled_ones(capsys):
    line = fails(capsys, ["view", "jetbott", "--video", "x.mp4"])
    assert line == "ambulo view: error: no file or bundled asset named 'jetbott'; did you mean 'jetbot'?"


def test_view_without_display_says_how_to_record(capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    assert "--video" in fails(capsys, ["view", "jetbot"])


def test_generate_bad_config_files_are_one_line(capsys, tmp_path):
    line = fails(capsys, ["generate", str(tmp_path / "missing.py"), "--out", str(tmp_path / "o")])
    assert "config file" in line and "not found" in line
    empty = tmp_path / "empty.py"
    empty.write_text("x = 1\n")
    assert "defines neither config() nor CONFIG" in fails(
        capsys, ["generate", str(empty), "--out", str(tmp_path / "o")])
    wrong = tmp_path / "wrong.py"
    wrong.write_text("CONFIG = 3\n")
    assert "gave a int, not a DatasetConfig" in fails(
        capsys, ["generate", str(wrong), "--out", str(tmp_path / "o")])
    assert "--frames 0 is not positive" in fails(capsys, ["generate", "--frames", "0", "--out", "x"])


def test_missing_file_from_a_command_is_one_line(capsys, monkeypatch):
    def boom(args):
        open("/nonexistent/ambulo/file.xml")

    monkeypatch.setattr(cli_demo, "run", boom)  # read when the parser is built
    line = fails(capsys, ["demo"])
    assert line == ("ambulo demo: error: no such file or folder: '/nonexistent/ambulo/file.xml'; "
                    "check the path")


# --- the real registry, PpoCfg and commands --------------------------------------------------


@pytest.fixture
def recorded_train(monkeypatch):
    """The real ``ambulo.rl`` with ``train`` replaced by a recorder."""
    import ambulo.rl

    calls = []
    monkeypatch.setattr(ambulo.rl, "train", lambda *args, **kwargs: calls.append((args, kwargs)))
    return calls


def _first_field(cfg, accepts) -> str | None:
    """The first settable field of ``cfg`` whose annotation ``accepts`` approves."""
    hints = typing.get_type_hints(type(cfg))
    for f in dataclasses.fields(cfg):
        if f.init and f.name not in ("num_envs", "device", "seed") and accepts(hints[f.name]):
            return f.name
    return None


def _is_float_pair(tp) -> bool:
    return typing.get_origin(tp) is tuple and typing.get_args(tp) == (float, float)


def _is_optional_value(tp) -> bool:
    args = typing.get_args(tp)
    return (type(None) in args and len(args) == 2
            and not dataclasses.is_dataclass(next(a for a in args if a is not type(None))))


def test_real_task_configs_type_the_overrides(recorded_train, monkeypatch):
    """Every registered task: keys found in its real config, by annotation, arrive typed."""
    from ambulo import envs

    for task in envs.names():
        cfg = envs.spec(task).cfg_fn()
        argv = ["train", task, "--env-cfg", "episode_length_s=7"]
        expected = {"episode_length_s": 7.0}
        pair = _first_field(cfg, _is_float_pair)
        if pair:
            argv += ["--env-cfg", f"{pair}=(0, 1.5)"]
            expected[pair] = (0.0, 1.5)
        optional = _first_field(cfg, _is_optional_value)
        if optional:
            argv += ["--env-cfg", f"{optional}=none"]
            expected[optional] = None
        if cfg.reward_weights:
            term = next(iter(cfg.reward_weights))
            argv += ["--env-cfg", f"reward_weights.{term}=0.5"]
            expected[f"reward_weights.{term}"] = 0.5
        nested = _first_field(cfg, dataclasses.is_dataclass)
        if nested:
            inner = _first_field(getattr(cfg, nested), lambda tp: tp in (int, float))
            if inner:  # 3 of an int, 0.003 of a float (a valid physics.timestep_s too)
                is_int = typing.get_type_hints(type(getattr(cfg, nested)))[inner] is int
                argv += ["--env-cfg", f"{nested}.{inner}={3 if is_int else 0.003}"]
                expected[f"{nested}.{inner}"] = 3 if is_int else 0.003
        argv += ["--ppo-cfg", "actor_hidden_dims=64,64", "--ppo-cfg", "entropy_coef=0"]
        recorded_train.clear()
        assert main(argv) == 0, argv
        kwargs = recorded_train[0][1]
        assert kwargs["env_overrides"] == expected, task
        assert type(kwargs["env_overrides"]["episode_length_s"]) is float
        # the task's registry config takes the same dotted overrides back (what train does)
        applied = envs.make_cfg(task, **kwargs["env_overrides"])
        assert applied.episode_length_s == 7.0
        if cfg.reward_weights:
            assert applied.reward_weights[term] == 0.5 and len(applied.reward_weights) == len(cfg.reward_weights)
        if nested and inner:
            assert getattr(getattr(applied, nested), inner) == expected[f"{nested}.{inner}"]
        assert kwargs["ppo_overrides"] == {"actor_hidden_dims": (64, 64), "entropy_coef": 0.0}


def test_real_train_help_lists_the_registered_tasks(capsys):
    from ambulo import envs

    with pytest.raises(SystemExit):
        main(["train", "--help"])
    out = capsys.readouterr().out
    for name in envs.names():
        assert name in out


def test_real_unknown_env_key_is_one_line(recorded_train, capsys):
    line = fails(capsys, ["train", "cartpole", "--env-cfg", "episode_lenght_s=3"])
    assert "did you mean 'episode_length_s'" in line
    line = fails(capsys, ["train", "cartpole", "--ppo-cfg", "entropy_coef=lots"])
    assert "bad value 'lots' for entropy_coef: expected float" in line


def test_real_task_without_runs_is_one_line(capsys, tmp_path):
    line = fails(capsys, ["play", "cartpole", "--log-root", str(tmp_path)])
    assert "no runs of task 'cartpole'" in line and "; train one with `ambulo train cartpole`" in line


def test_missing_optional_package_names_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rsl_rl", None)  # as if rsl-rl-lib were not installed
    monkeypatch.setitem(sys.modules, "rsl_rl.runners", None)
    for name in [m for m in sys.modules if m.startswith("ambulo.rl")]:
        monkeypatch.delitem(sys.modules, name)
    line = fails(capsys, ["train", "cartpole", "--max-iterations", "1"])
    assert line.endswith("; pip install 'ambulo[rl]'")
    assert "needs the package 'rsl_rl" in line


def test_demo_prints_what_happened_and_writes_an_mp4(tmp_path, capsys):
    video = tmp_path / "demo.mp4"
    assert main(["demo", "--seconds", "2", "--video", str(video), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "humanoid walked" in out and "stayed up" in out and "jetbot drove" in out
    assert video.stat().st_size > 10_000
    assert [p.name for p in tmp_path.iterdir() if p.name != "demo.mp4" and "demo" in p.name] == []  # no temporary


def test_view_records_a_bundled_asset_headless(tmp_path, capsys):
    video = tmp_path / "rover.mp4"
    assert main(["view", "rover", "--video", str(video), "--seconds", "0.5"]) == 0
    assert video.stat().st_size > 1_000
