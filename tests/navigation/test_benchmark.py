"""``navigation.benchmark``: a killed run resumes (episodes with a JSON are skipped, failed ones
retried), and the summary's figures by hand."""

import json
from dataclasses import asdict

import pytest

from ambulo.navigation import benchmark
from ambulo.navigation.benchmark import EpisodeSpec, episode_path, format_table, run_benchmark, summarize


def _result(spec: EpisodeSpec, *, success: bool, spl: float, collisions: int, replans_ms, fell=False, stuck=False,
            time_s=10.0, wall_s=20.0) -> dict:
    return {"spec": asdict(spec), "status": "arrived" if success else "timeout", "success": success, "spl": spl,
            "fell": fell, "collisions": collisions, "stuck": stuck, "replan_wall_s": [t / 1e3 for t in replans_ms],
            "time_s": time_s, "wall_s": wall_s, "ate_m": 0.0}


def test_a_killed_run_resumes_skipping_finished_episodes_and_retrying_failed_ones(tmp_path, monkeypatch):
    specs = [EpisodeSpec(1000 + i, 0, "oracle") for i in range(3)]
    # the "killed" run finished episode 0 only: its JSON is there
    (tmp_path / "episodes").mkdir()
    episode_path(tmp_path, specs[0]).write_text(json.dumps(_result(specs[0], success=True, spl=0.9, collisions=0,
                                                                   replans_ms=[10])))
    calls, failed = [], set()

    def fake_run_spec(spec, out_dir, base=None, ceiling=False):
        calls.append(spec)
        if spec.apartment_seed == 1002 and spec not in failed:  # fails the first time: nothing written
            failed.add(spec)
            return {"spec": asdict(spec), "error": "Traceback ...\nRuntimeError: boom"}
        data = _result(spec, success=False, spl=0.0, collisions=2, replans_ms=[30])
        episode_path(out_dir, spec).write_text(json.dumps(data))
        return data

    monkeypatch.setattr(benchmark, "run_spec", fake_run_spec)
    run = run_benchmark(specs, tmp_path, workers=1, log=None)
    assert calls == specs[1:] and run.resumed == 1
    s = run.summary["oracle/policy"]
    assert s["episodes"] == 3 and s["errors"] == 1 and s["success"] == pytest.approx(1 / 3)
    assert not episode_path(tmp_path, specs[2]).exists()
    assert benchmark.error_path(tmp_path, specs[2]).read_text().endswith("RuntimeError: boom")
    # run again: 0 and 1 are skipped, the failed 2 is retried
    calls.clear()
    run = run_benchmark(specs, tmp_path, workers=1, log=None)
    assert calls == [specs[2]] and run.resumed == 2 and run.summary["oracle/policy"]["errors"] == 0
    assert json.loads((tmp_path / "summary.json").read_text()) == run.summary


def test_summary_by_hand():
    a, b = EpisodeSpec(1, 0, "oracle"), EpisodeSpec(2, 0, "oracle")
    c, d = EpisodeSpec(1, 0, "full"), EpisodeSpec(2, 0, "full", randomize=True)
    results = [
        _result(a, success=True, spl=0.8, collisions=1, replans_ms=[10, 20, 30], time_s=12.0, wall_s=24.0),
        _result(b, success=False, spl=0.0, collisions=2, replans_ms=[40, 50], fell=True, time_s=8.0, wall_s=16.0),
        _result(c, success=False, spl=0.0, collisions=0, replans_ms=[], stuck=True, time_s=30.0, wall_s=120.0),
        {"spec": asdict(d), "error": "boom"},
    ]
    s = summarize(results, {"oracle/policy": 30.0}, {"oracle/policy": 2})
    assert set(s) == {"oracle/policy", "full/policy", "full/policy/rand"}
    o = s["oracle/policy"]
    assert o["success"] == 0.5 and o["spl"] == pytest.approx(0.4) and o["falls"] == 0.5
    assert o["collisions_per_episode"] == 1.5 and o["stuck"] == 0.0
    # the pooled replans 10..50 ms: the 95th percentile interpolates 40 + 0.8 * (50 - 40)
    assert o["replan_p95_ms"] == pytest.approx(48.0)
    assert o["sim_to_wall"] == pytest.approx(20.0 / 40.0)
    assert o["episodes_per_min"] == pytest.approx(60.0 * 2 / 30.0)
    f = s["full/policy"]
    assert f["stuck"] == 1.0 and f["replan_p95_ms"] == 0.0 and f["episodes_per_min"] is None  # resumed
    r = s["full/policy/rand"]
    assert r["errors"] == 1 and r["success"] == 0.0 and r["sim_to_wall"] is None
    table = format_table(s).splitlines()
    assert len(table) == 2 + 3 and table[2].startswith("| oracle/policy | 2 | 50% | 0.40 | 50% | 1.50 |")


def test_specs_name_their_files_and_configs_follow_them():
    spec = EpisodeSpec(7, 2, "mapping", "policy", True)
    assert spec.name == "mapping-policy-rand-apt0007-ep2"
    cfg = benchmark.episode_cfg(spec)
    assert cfg.navigator.mode == "mapping" and cfg.world.randomization.enabled and cfg.world.seed == 7002
    with pytest.raises(Exception, match="unknown mode"):
        benchmark.check_spec(EpisodeSpec(1, 0, "teleport"))


@pytest.mark.slow
def test_two_real_oracle_episodes_over_a_pool_of_two(tmp_path):
    specs = [EpisodeSpec(1000, 0, "oracle"), EpisodeSpec(1001, 0, "oracle")]
    run = run_benchmark(specs, tmp_path, workers=2, log=None)
    for spec in specs:
        data = json.loads(episode_path(tmp_path, spec).read_text())
        assert data["spec"]["apartment_seed"] == spec.apartment_seed and "status" in data
    assert run.summary["oracle/policy"]["episodes"] == 2 and run.summary["oracle/policy"]["errors"] == 0


def test_ceiling_figures_by_hand_and_which_episodes_get_one(tmp_path, monkeypatch):
    a, b, c = (EpisodeSpec(s, 0, "full") for s in (1, 2, 3))
    results = [
        {**_result(a, success=True, spl=0.8, collisions=0, replans_ms=[10], time_s=10.0, wall_s=40.0),
         "ceiling": {"time_s": 10.0, "wall_s": 2.0, "sim_to_wall": 5.0}},
        {**_result(b, success=True, spl=0.8, collisions=0, replans_ms=[10], time_s=20.0, wall_s=40.0),
         "ceiling": {"time_s": 20.0, "wall_s": 3.0, "sim_to_wall": 20.0 / 3.0}},
        _result(c, success=True, spl=0.8, collisions=0, replans_ms=[10], time_s=5.0, wall_s=50.0),  # no ceiling
    ]
    s = summarize(results)["full/policy"]
    assert s["ceiling_sim_to_wall"] == pytest.approx(30.0 / 5.0)
    # the episodes with a ceiling ran 30 s in 80 s: 0.375 sim/wall, 6.25 % of the ceiling's 6
    assert s["of_ceiling"] == pytest.approx((30.0 / 80.0) / 6.0)
    assert summarize(results[2:])["full/policy"]["of_ceiling"] is None
    asked = {}

    def fake_run_spec(spec, out_dir, base=None, ceiling=False):
        asked[spec.apartment_seed] = ceiling
        return _result(spec, success=True, spl=1.0, collisions=0, replans_ms=[1])

    monkeypatch.setattr(benchmark, "run_spec", fake_run_spec)
    specs = [EpisodeSpec(s, 0, "oracle") for s in range(5)] + [EpisodeSpec(s, 0, "full") for s in range(10, 13)]
    run_benchmark(specs, tmp_path, workers=1, log=None, ceiling_every=2)
    assert asked == {0: True, 1: False, 2: True, 3: False, 4: True, 10: True, 11: False, 12: True}


def test_the_ceiling_steps_physics_and_the_turning_policy_for_the_simulated_time():
    from ambulo.navigation.ceiling import physics_policy_ceiling

    top = physics_policy_ceiling(1000, 0, 1.0)
    assert top.time_s == pytest.approx(1.0, abs=1e-6) and top.wall_s > 0 and top.sim_to_wall > 0
    # the policy stepped: it turned on the spot (0.4 rad/s asked) and stood
    assert top.turned_rad > 0.1 and not top.fell


def test_the_perception_device_reaches_the_odometry_and_the_tsdf():
    import torch

    from ambulo.navigation.benchmark import episode_cfg, with_perception_device
    from ambulo.navigation.mapping import OnlineMapper
    from ambulo.utils.checks import InvalidValueError

    base = with_perception_device("meta")  # any torch device the config passes on, not only cuda
    cfg = episode_cfg(EpisodeSpec(3, 0, "full"), base)
    assert cfg.navigator.vo.vo.device == "meta" and cfg.navigator.mapper.device == "meta"
    assert OnlineMapper(cfg.navigator.mapper).device == "meta"
    assert cfg.navigator.vo.vo.match_window_px is not None  # the rest of the preset is kept
    assert with_perception_device("cpu").navigator.mapper.device == "cpu"
    if not torch.cuda.is_available():
        with pytest.raises(InvalidValueError, match="CUDA"):
            with_perception_device("cuda")
