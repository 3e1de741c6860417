"""``ambulo eval --env-cfg``: a policy evaluated under a changed task config (a friction, terrain or
robot variant), the changes typed against the task's config, applied on top of the run's and named
in the result; the fields eval's own flags set are refused in one line."""

from __future__ import annotations

import json

import pytest

from ambulo.cli import main
from ambulo.rl import runs

SHORT = ["--device", "cpu", "--episodes", "4", "--episode-length-s", "1"]


def result_of(capsys, argv: list[str]) -> dict:
    assert main(argv) == 0
    out = capsys.readouterr().out
    return json.JSONDecoder().raw_decode(out[out.index("{"):])[0]


def test_the_override_reaches_the_evaluated_env_and_is_named(capsys):
    nominal = result_of(capsys, ["eval", "humanoid-walk", "--shipped", *SHORT])
    # a base "fallen" below 2 m: every robot standing at ~0.9 m ends its episode at once
    raised = result_of(capsys, ["eval", "humanoid-walk", "--shipped", *SHORT, "--env-cfg", "min_base_height_m=2.0"])
    assert nominal["fall_rate"] == 0.0 and "env_overrides" not in nominal
    assert raised["fall_rate"] == 1.0
    assert raised["env_overrides"] == {"min_base_height_m": 2.0}


def test_a_none_value_is_applied_not_dropped():
    """make_env_for_run drops None among its caller's overrides (an unset flag); a user's None is a value."""
    info = {"task": "humanoid-rough", "env_overrides": {}, "seed": 0, "device": "cpu"}
    small = {"terrain.num_levels": 1, "terrain.kinds": ("flat",), "terrain.border_m": 1.0}
    env = runs.make_env_for_run(info, num_envs=1, play=True, user_overrides={"box_collider_bodies": None, **small})
    assert env.cfg.box_collider_bodies is None  # humanoid-rough's default is the legs
    env.close()


@pytest.mark.parametrize("argv, needles", [
    (["--env-cfg", "num_envs=3"], ("--env-cfg cannot set num_envs", "--episodes")),
    (["--env-cfg", "episode_length_s=3"], ("--env-cfg cannot set episode_length_s", "--episode-length-s")),
    (["--env-cfg", "no_such_field=1"], ("no_such_field",)),
    (["--env-cfg", "min_base_height_m=2.0", "--num-gpus", "2"], ("not carried to --num-gpus",)),
])
def test_bad_overrides_are_one_line(capsys, argv, needles):
    try:
        status = main(["eval", "humanoid-walk", "--shipped", "--device", "cpu", *argv])
    except SystemExit as exit_:
        status = exit_.code
    assert status == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    for needle in needles:
        assert needle in lines[0]
