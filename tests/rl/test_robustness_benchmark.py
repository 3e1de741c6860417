"""benchmarks/robustness.py --batched: the rows side by side in one env, reported in order, each under
its own transfer terms; --only names are checked."""

import json
import sys

import pytest

from script_loader import ROOT, load_script

bench = load_script(ROOT / "benchmarks" / "robustness.py")
CORNER = "gains0.8_lat20ms_com+3+3+3cm"


def run(monkeypatch, capsys, *args):
    monkeypatch.setattr(sys, "argv", ["robustness.py", "--shipped", "humanoid-walk", "--set", "corners", *args])
    bench.main()
    return capsys.readouterr().out


def test_batched_rows_come_back_in_order_each_under_its_terms(monkeypatch, capsys):
    seen, measure = [], bench.run_episodes

    def recording(env, vec_env, policy, spec, **kwargs):
        seen.append((env.num_envs, env.cfg.transfer_blocks, kwargs.get("blocks")))
        return measure(env, vec_env, policy, spec, **kwargs)

    monkeypatch.setattr(bench, "run_episodes", recording)
    out = run(monkeypatch, capsys, "--batched", "--only", f"{CORNER},nominal", "--num-episodes", "2",
              "--episode-length-s", "0.1", "--num-threads", "1")
    conditions = bench.corner_conditions()
    assert seen == [(4, (conditions[CORNER], conditions["nominal"]), 2)]  # one env, one rollout
    result = json.loads(out.splitlines()[-1].removeprefix("RESULT "))
    assert result["batched"] and list(result["rows"]) == [CORNER, "nominal"]


def test_an_unknown_row_is_named(monkeypatch, capsys):
    with pytest.raises(SystemExit):
        run(monkeypatch, capsys, "--only", "nominal,gains0.9")
    assert "no condition gains0.9" in capsys.readouterr().err
