"""scripts/plot_eval_curves.py: reads evals.csv as `ambulo train --eval-every` writes it (the metrics cells through
periodic_eval.metrics_from_text, the inverse of what writes them) and marks the
first evaluation that walks on both engines."""

from __future__ import annotations

from script_loader import ROOT, load_script

plot = load_script(ROOT / "scripts" / "plot_eval_curves.py")

HEADER = ("iteration,wall_s,env_steps,fall_rate,mean_episode_length_s,mean_return,metrics,criteria_met,"
          "cpu_engine_metrics,cpu_engine_criteria_met\n")


def test_rows_are_minutes_and_the_criterion_needs_both_engines(tmp_path):
    path = tmp_path / "evals.csv"
    path.write_text(HEADER
                    + "49,90.0,100,0.300,15.0,10.0,mean_abs_vel_error_m_s=0.5 mean_abs_yaw_rate_error_rad_s=0.4,False,,\n"
                    + "99,150.0,200,0.000,20.0,30.0,mean_abs_vel_error_m_s=0.19 mean_abs_yaw_rate_error_rad_s=0.2,"
                      "True,fall_rate=0.000 mean_abs_vel_error_m_s=0.21,False\n"
                    + "149,210.0,300,0.010,20.0,35.0,mean_abs_vel_error_m_s=0.18 mean_abs_yaw_rate_error_rad_s=0.2,"
                      "True,fall_rate=0.000 mean_abs_vel_error_m_s=0.19,True\n")
    rows = plot.read_evals(path)
    assert [r["minutes"] for r in rows] == [1.5, 2.5, 3.5]
    assert [r["vel_error_m_s"] for r in rows] == [0.5, 0.19, 0.18]
    assert [r["fall_rate"] for r in rows] == [0.3, 0.0, 0.01]
    # met on the GPU but not on the CPU engine is not met
    assert [r["met"] for r in rows] == [False, False, True]
    assert [r["met_training_engine"] for r in rows] == [False, True, True]
    assert plot.legend("run", rows)[0] == "run: walks at 3.5 min"
    # without its last row the run met the criterion on its own engine only: said so, not "walks"
    assert plot.legend("run", rows[:2])[0] == "run: criterion at 2.5 min, not on the CPU engine"
    assert plot.legend("run", rows[:1])[0] == "run: not yet"


def test_it_writes_a_png(tmp_path):
    path = tmp_path / "evals.csv"
    path.write_text(HEADER + "9,30.0,10,0.0,20.0,1.0,mean_abs_vel_error_m_s=0.1,True,,\n")
    out = tmp_path / "curves.png"
    import sys
    argv, sys.argv = sys.argv, ["plot_eval_curves.py", "--out", str(out), f"one run={path}"]
    try:
        plot.main()
    finally:
        sys.argv = argv
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_metrics_cells_read_back_what_the_periodic_evaluation_wrote():
    from ambulo.rl.periodic_eval import _metrics_text, metrics_from_text

    result = {"fall_rate": 0.0, "mean_abs_vel_error_m_s": 0.123456, "mean_abs_yaw_rate_error_rad_s": 0.2,
              "mean_return": 40.0}
    assert metrics_from_text(_metrics_text(result)) == {"mean_abs_vel_error_m_s": 0.1235,
                                                        "mean_abs_yaw_rate_error_rad_s": 0.2}
    assert metrics_from_text("") == {}


def test_a_file_that_is_not_an_evals_csv_is_one_line_naming_it(tmp_path):
    import pytest

    path = tmp_path / "metrics.csv"
    path.write_text("iteration,env_steps,mean_reward\n0,100,1.0\n")
    with pytest.raises(SystemExit, match=r"metrics.csv line 2: not an evals.csv row .*KeyError"):
        plot.read_evals(path)


def test_a_run_judged_in_blocks_plots_its_worst_block(tmp_path):
    """humanoid-walk-robust's evals.csv: the pooled cells pass the bars, the worst corner does not."""
    path = tmp_path / "evals.csv"
    path.write_text(HEADER.rstrip("\n") + ",worst_block,cpu_engine_worst_block\n"
                    + "49,90.0,100,0.010,20.0,30.0,mean_abs_vel_error_m_s=0.15,False,,,"
                      "gains0.8_lat0ms_com-3-3+3cm fall_rate=0.0500 mean_abs_vel_error_m_s=0.246 blocks_failed=6,\n")
    (row,) = plot.read_evals(path)
    assert row["vel_error_m_s"] == 0.246 and row["fall_rate"] == 0.05 and not row["met"]


def test_the_worst_block_cell_reads_back():
    from ambulo.rl.periodic_eval import _worst_block_cell, worst_block_from_text

    blocks = [{"name": "nominal", "fall_rate": 0.0, "mean_abs_vel_error_m_s": 0.1},
              {"name": "gains0.8_lat20ms_com+3+3+3cm", "fall_rate": 0.0625, "mean_abs_vel_error_m_s": 0.123456}]
    result = {"blocks": blocks, "worst_block": blocks[1]["name"], "blocks_failed": [blocks[1]["name"]]}
    assert worst_block_from_text(_worst_block_cell(result)) == (
        "gains0.8_lat20ms_com+3+3+3cm", {"fall_rate": 0.0625, "mean_abs_vel_error_m_s": 0.1235, "blocks_failed": 1.0})
    assert _worst_block_cell({"fall_rate": 0.0}) == "" and worst_block_from_text("") is None


def test_the_bars_are_the_tasks_criterion():
    """humanoid-rough's walks_rough allows 0.25 m/s, humanoid-walk's walks 0.2: a rough run's curve drawn against
    the flat bar would sit above a line its criterion marks do not use."""
    from ambulo.envs.humanoid_rough import WALKS_ROUGH
    from ambulo.envs.humanoid_walk import WALKS

    rough = (WALKS_ROUGH.max_values["mean_abs_vel_error_m_s"], WALKS_ROUGH.max_values["fall_rate"])
    assert plot.criterion_bars("humanoid-rough") == rough == (0.25, 0.05)
    assert plot.criterion_bars(None) == (WALKS.max_values["mean_abs_vel_error_m_s"], WALKS.max_values["fall_rate"])
    assert plot.criterion_bars(None) != rough


def test_an_unknown_task_is_one_line():
    import pytest

    with pytest.raises(SystemExit, match="no task named 'humanoid-ruff'.*humanoid-rough"):
        plot.criterion_bars("humanoid-ruff")
