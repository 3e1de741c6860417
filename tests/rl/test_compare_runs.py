"""scripts/compare_runs.py: falls by tile kind averaged from an iteration on, and the curriculum's level at given
iterations, read from a run folder, its .tgz or its evals.csv (with the metrics.csv beside it), against values
worked out by hand."""

from __future__ import annotations

import tarfile

import pytest

from script_loader import ROOT, load_script

compare = load_script(ROOT / "scripts" / "compare_runs.py")

EVALS = ("iteration,wall_s,env_steps,fall_rate,metrics,criteria_met,by_kind,eval_engine\n"
         "99,10.0,100,0.500,mean_abs_vel_error_m_s=0.5,False,flat:0.200/0.30 stones:0.800/0.60,cpu\n"
         "199,20.0,200,0.100,mean_abs_vel_error_m_s=0.3,False,flat:0.000/0.20 stones:0.300/0.40,cpu\n"
         "299,30.0,300,0.040,mean_abs_vel_error_m_s=0.2,True,flat:0.100/0.10 stones:0.100/0.30,training\n")
METRICS = ("iteration,env_steps,terrain_level,terrain_level_stones\n"
           "0,8,1.0,0.5\n"
           "150,1200,2.0,1.5\n"
           "310,2480,4.0,3.0\n")


def test_means_from_an_iteration_on_are_worked_out_by_hand():
    evals = compare._rows(EVALS)
    # iterations 199 and 299: pooled (0.1 + 0.04) / 2, flat (0 + 0.1) / 2, stones (0.3 + 0.1) / 2
    n, pooled, by_kind = compare.falls_by_kind(evals, 150)
    assert n == 2
    assert pooled == pytest.approx(0.07)
    assert by_kind == pytest.approx({"flat": 0.05, "stones": 0.2})
    assert compare.falls_by_kind(evals, 199)[0] == 2  # "from iteration 199 on" counts 199
    n, pooled, by_kind = compare.falls_by_kind(evals, 0)
    assert (n, by_kind["stones"]) == (3, pytest.approx(1.2 / 3))
    assert compare.falls_by_kind(evals, 1000)[0] == 0


def test_levels_are_the_last_row_at_or_before_each_iteration():
    metrics = compare._rows(METRICS)
    # nothing before iteration 0 is logged at -1; 149 reads row 0, 150 and 300 read row 150; then the last row
    assert compare.levels_at(metrics, "terrain_level_stones", [-1, 149, 150, 300]) == [None, 0.5, 1.5, 1.5, 3.0]
    assert compare.levels_at(metrics, "terrain_level", [1000]) == [4.0, 4.0]
    assert compare.levels_at(metrics, "terrain_level_lava", [1000]) == [None, None]


def test_a_folder_a_tgz_and_an_evals_csv_read_the_same(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "evals.csv").write_text(EVALS)
    (run / "metrics.csv").write_text(METRICS)
    with tarfile.open(tmp_path / "run.tgz", "w:gz") as tar:
        for name in ("evals.csv", "metrics.csv"):
            tar.add(run / name, arcname=name)
    (tmp_path / "s1-evals.csv").write_text(EVALS)
    (tmp_path / "s1-metrics.csv").write_text(METRICS)
    for path in (run, tmp_path / "run.tgz", tmp_path / "s1-evals.csv"):
        assert compare.read_run(path) == (compare._rows(EVALS), compare._rows(METRICS))
    compare.main(["--from-iteration", "150", "--at", "149,300", "--level-kind", "stones",
                  f"a={run}", f"b={tmp_path / 'run.tgz'}"])
    out = capsys.readouterr().out
    assert "| a | 2 | 0.070 | 0.05 | 0.20 |" in out
    assert "| b | 0.50 | 1.50 | 3.00 (310) |" in out


def test_bad_paths_are_one_line_naming_them(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit, match="no evals.csv there"):
        compare.read_run(tmp_path / "empty")
    (tmp_path / "broken.tgz").write_bytes(b"not a tar")
    with pytest.raises(SystemExit, match="not a readable .tgz"):
        compare.read_run(tmp_path / "broken.tgz")


@pytest.mark.parametrize("text", ["iteration,wall_s\n99,10.0\n",  # no fall_rate column
                                  EVALS.replace("199,", "two,", 1)])  # an iteration that is not a number
def test_a_malformed_evals_csv_is_one_line_naming_it(tmp_path, text):
    path = tmp_path / "bad-evals.csv"
    path.write_text(text)
    with pytest.raises(SystemExit, match=r"bad-evals.csv: not the evals.csv / metrics.csv of .*pass a run folder"):
        compare.main([f"a={path}"])
