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
    assert seen == [(4, (conditions[CORNER], conditions["nominal"]), (CORNER, "nominal"))]  # one env, one rollout
    result = json.loads(out.splitlines()[-1].removeprefix("RESULT "))
    assert result["batched"] and list(result["rows"]) == [CORNER, "nominal"]


def test_an_unknown_row_is_named(monkeypatch, capsys):
    with pytest.raises(SystemExit):
        run(monkeypatch, capsys, "--only", "nominal,gains0.9")
    assert "no condition gains0.9" in capsys.readouterr().err


def test_the_corner_rows_are_the_robust_tasks_blocks_one_definition():
    """The table's corner rows and humanoid-walk-robust's evaluation blocks are ``transfer_corners``;
    one corner checked by hand: gains x0.8, 20 ms latency, CoM (+3, -3, +3) cm."""
    from ambulo import envs
    from ambulo.envs.transfer import TransferCfg, transfer_corners

    rows = bench.corner_conditions()
    corners = transfer_corners()
    assert list(rows) == ["nominal", "issue_three", *corners] and len(corners) == 16
    assert all(rows[name] == cfg for name, cfg in corners.items())
    blocks = envs.spec("humanoid-walk-robust").eval_blocks()
    assert blocks.names == ("nominal", *corners)
    assert blocks.env_overrides["transfer_blocks"] == (rows["nominal"], *corners.values())
    com = (0.03, -0.03, 0.03)
    assert corners["gains0.8_lat20ms_com+3-3+3cm"] == TransferCfg(
        kp_scale_range=(0.8, 0.8), kd_scale_range=(0.8, 0.8), action_latency_range_s=(0.02, 0.02),
        com_offset_box_m=(com, com))
    assert len({(c.kp_scale_range, c.action_latency_range_s, c.com_offset_box_m) for c in corners.values()}) == 16
