"""The shipped humanoid-walk-robust policy: its contract records the CPU-engine evaluation of every
transfer corner, and on the CPU engine it walks at two of the hardest corners (gains x0.8, 20 ms
latency; CoM 3 cm back-right, its worst in training, and 3 cm forward-left, where the shipped
humanoid-walk policy tracks 0.30-0.35 m/s off) as it does at nominal."""

import json
import sys

from ambulo.policies import policy_dir
from script_loader import ROOT, load_script

bench = load_script(ROOT / "benchmarks" / "robustness.py")
HARDEST = ("gains0.8_lat20ms_com-3-3+3cm", "gains0.8_lat20ms_com+3+3+3cm")


def test_contract_says_it_walks_at_every_corner_on_the_cpu_engine():
    contract = json.loads((policy_dir("humanoid-walk-robust") / "contract.json").read_text())
    cpu = contract["eval_cpu"]
    assert cpu["device"] == "cpu" and cpu["episodes"] == 340  # 17 blocks of 20: nominal and 16 corners
    assert cpu["walks_robust"] is True and cpu["blocks_failed"] == []
    assert cpu["fall_rate"] <= 0.05 and cpu["mean_abs_vel_error_m_s"] <= 0.2


def test_walks_at_the_hardest_corners_as_at_nominal(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["robustness.py", "--shipped", "humanoid-walk-robust", "--set", "corners",
                                      "--batched", "--only", ",".join((*HARDEST, "nominal")), "--num-episodes", "8",
                                      "--episode-length-s", "10", "--num-threads", "1"])
    bench.main()
    rows = json.loads(capsys.readouterr().out.splitlines()[-1].removeprefix("RESULT "))["rows"]
    for name in (*HARDEST, "nominal"):
        # no robot falls in 10 s, and each tracks its commands within walks' 0.2 m/s bar
        assert rows[name]["fall_rate"] == 0.0, (name, rows[name])
        assert rows[name]["mean_abs_vel_error_m_s"] < 0.2, (name, rows[name])
