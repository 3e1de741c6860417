"""``ambulo train --algo fast-sac|fast-td3 --algo-cfg``: what reaches ``ambulo.rl.train`` (a stand-in)."""

import sys
import types

import pytest

import ambulo.rl.config
import ambulo.rl.offpolicy.config  # the settings the CLI types --algo-cfg against, imported for real
from ambulo.cli import main


@pytest.fixture
def calls(monkeypatch):
    made = []
    assert ambulo.rl.config  # imported before ambulo.rl is replaced: the CLI reads the real settings
    rl = types.ModuleType("ambulo.rl")
    rl.train = lambda *args, **kwargs: made.append((args, kwargs))
    rl.RunError = type("RunError", (Exception,), {})
    rl.TrainingInterrupted = type("TrainingInterrupted", (KeyboardInterrupt,), {})
    monkeypatch.setitem(sys.modules, "ambulo.rl", rl)
    return made


def test_algo_and_its_settings_reach_train_typed(calls):
    assert main(["train", "cartpole", "--algo", "fast-sac", "--algo-cfg", "batch_size=512",
                 "--algo-cfg", "critic_hidden_dims=32,32", "--algo-cfg", "num_envs=8"]) == 0
    (args, kwargs), = calls
    assert args == ("cartpole",) and kwargs["algo"] == "fast-sac"
    assert kwargs["algo_overrides"] == {"batch_size": 512, "critic_hidden_dims": (32, 32)}
    assert kwargs["num_envs"] == 8 and kwargs["ppo_overrides"] is None


def test_ppo_stays_the_default(calls):
    assert main(["train", "cartpole", "--ppo-cfg", "learning_rate=3e-4"]) == 0
    (_, kwargs), = calls
    assert kwargs["algo"] is None and kwargs["algo_overrides"] is None
    assert kwargs["ppo_overrides"] == {"learning_rate": 3e-4}


@pytest.mark.parametrize("argv, says", [
    (["--algo", "fast-td3", "--ppo-cfg", "learning_rate=1e-3"], "--ppo-cfg sets PPO's settings"),
    (["--algo-cfg", "batch_size=5"], "--algo-cfg sets the settings of --algo fast-sac"),
    (["--algo", "fast-sac", "--algo-cfg", "batch_sise=5"], "did you mean 'batch_size'"),
    (["--algo", "fast-sac", "--algo-cfg", "algo=fast-td3"], "use --algo instead"),
])
def test_settings_of_the_wrong_algorithm_fail_in_one_line(calls, capsys, argv, says):
    assert main(["train", "cartpole", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err
    assert calls == []
