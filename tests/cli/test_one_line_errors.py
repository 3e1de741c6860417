"""The CLI answers in one line: expected failures print the problem and the fix and exit non-zero.

Most cases call ``ambulo.cli.main([...])`` (the console script's function) and read stderr with
capsys; a few run ``python -m ambulo`` in a subprocess, the real entry point. A traceback is only
for ``--debug`` and for real bugs.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import ambulo.cli
from ambulo.cli import main
from ambulo.cli import view as cli_view
from ambulo.core.importers import AssetError
from ambulo.utils.checks import InvalidValueError
from ambulo.utils.overrides import OverrideError

SRC = str(Path(__file__).resolve().parents[2] / "src")


def _fails(capsys, argv: list[str], *parts: str, status: int = 2) -> str:
    """Run ``ambulo argv``: it must exit ``status`` with one stderr line holding every part."""
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's own errors
        code = exit_.code
    err = capsys.readouterr().err.strip()
    assert code == status, err
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in err
    for part in parts:
        assert part in err, f"{part!r} not in {err!r}"
    return err


@pytest.fixture
def files(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body")
    (tmp_path / "empty.urdf").write_text("")
    (tmp_path / "a_file").write_text("in the way")
    return tmp_path


# --- view: the target -------------------------------------------------------------------------


def test_missing_file(capsys, files):
    _fails(capsys, ["view", str(files / "nope.xml")], "ambulo view: error:", "no file or bundled asset named",
           "nope.xml", "give 'demo', a bundled asset")


def test_misspelled_asset(capsys):
    _fails(capsys, ["view", "jetbto"], "no file or bundled asset named 'jetbto'", "did you mean 'jetbot'?")


def test_folder_as_target(capsys, files):
    _fails(capsys, ["view", str(files), "--video", str(files / "o.mp4")], "is a folder",
           f"give a file in it, e.g. {files / 'broken.xml'}")


def test_unknown_file_kind(capsys, files):
    _fails(capsys, ["view", str(files / "notes.txt"), "--video", str(files / "o.mp4")],
           "is not a scene or robot file (unknown kind '.txt')", "give an MJCF, URDF or USD file")


@pytest.mark.parametrize("name, parts", [("broken.xml", ("broken.xml: cannot be loaded", "XML")),
                                         ("empty.urdf", ("empty.urdf", "malformed URDF", "fix the file or re-export it"))])
def test_malformed_file_is_one_line(capsys, files, name, parts):
    # the importers' AssetError (MuJoCo's parser message spans lines: joined into one)
    _fails(capsys, ["view", str(files / name), "--video", str(files / "o.mp4")], *parts)


# --- view / demo: values and outputs ----------------------------------------------------------


@pytest.mark.parametrize("seconds", ["-1", "0", "nan", "inf"])
def test_bad_duration(capsys, files, seconds):
    _fails(capsys, ["view", "jetbot", "--seconds", seconds, "--video", str(files / "o.mp4")],
           f"--seconds {float(seconds)} is not a positive, finite duration", "give --seconds above 0")
    _fails(capsys, ["demo", "--seconds", seconds, "--no-video", "--quiet"], "ambulo demo: error: --seconds",
           "give --seconds above 0")


def test_video_into_a_folder(capsys, files):
    _fails(capsys, ["view", "jetbot", "--video", str(files), "--seconds", "0.1"], "--video", "is a folder",
           "give a file path, e.g.")


def test_video_below_a_file(capsys, files):
    target = files / "a_file" / "out.mp4"
    _fails(capsys, ["demo", "--video", str(target), "--seconds", "0.1", "--quiet"], "--video", "cannot be written",
           "a_file", "remove it or choose another path")
    assert (files / "a_file").read_text() == "in the way"


def test_unwritable_video_folder(capsys, files, monkeypatch):
    # permission bits do not stop root, so make the probe write fail the way a read-only disk does
    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(files / ".ambulo-probe-x"))

    monkeypatch.setattr("tempfile.NamedTemporaryFile", refuse)
    _fails(capsys, ["view", "jetbot", "--video", str(files / "v.mp4")], "--video",
           f"'{files}': permission denied", "check its permissions, or choose a path you may write to")


# --- the RL commands and --env-cfg (their handlers live in cli/rl.py) --------------------------


def test_unknown_task(capsys):
    _fails(capsys, ["train", "cartpol"], "ambulo train: error: no task named 'cartpol'", "did you mean 'cartpole'?")


@pytest.mark.parametrize("pair, parts", [
    ("episode_length_s=abc", ("bad value 'abc' for episode_length_s: expected float", "e.g. episode_length_s=")),
    ("episode_length_s=nan", ("bad value 'nan'", "give a finite one")),
    ("physics.timestep=0.01", ("unknown key 'physics.timestep'", "did you mean 'physics.timestep_s'?")),
    ("physics.timestep_s=-1", ("bad value -1.0 for physics.timestep_s: it must be > 0", "pass seconds")),
    ("physics.timestep_s=0.2", ("steps above 0.05 s", "pass a step <= 0.05 s")),
])
def test_bad_env_cfg(capsys, pair, parts):
    _fails(capsys, ["train", "cartpole", "--env-cfg", pair], "ambulo train: error: --env-cfg", *parts)


@pytest.mark.parametrize("pairs, parts", [
    (["curriculum.kind_weights=1,2"], ("2 weights for the 7 columns of terrain.kinds", "one weight per column")),
    (["curriculum.kind_weights=0,0,0,0,0,0,0"], ("gives no env a column", "a weight above 0")),
    (["curriculum.kind_weights=1,2", "terrain.kinds=flat,stairs_up"], ("set terrain.kinds first",)),
    (["levels.kind_weights=1,2"], ("levels.kind_weights has 2 weights for the 3 columns of terrain.kinds",)),
])
def test_bad_kind_weights_fail_as_parsed_before_a_run_folder(capsys, tmp_path, pairs, parts):
    env_cfg = [arg for pair in pairs for arg in ("--env-cfg", pair)]
    task = "humanoid-footsteps-stairs" if pairs[0].startswith("levels.") else "humanoid-rough"
    # one iteration of 2 envs bounds the run that a missing check would start
    _fails(capsys, ["train", task, "--device", "cpu", "--num-envs", "2", "--max-iterations", "1",
                    "--log-root", str(tmp_path), *env_cfg],
           "ambulo train: error: --env-cfg bad value", *parts)
    assert not any(tmp_path.iterdir())


def test_unknown_run(capsys):
    _fails(capsys, ["eval", "nosuch"], "ambulo eval: error: no run folder, checkpoint or task named 'nosuch'",
           "pass the folder `ambulo train` printed")


def test_generate_into_a_file(capsys, files):
    err = _fails(capsys, ["generate", "--out", str(files / "a_file"), "--frames", "1", "--workers", "1", "--quiet"],
                 "ambulo generate: error:", "a_file")
    assert "; " in err  # a fix follows the problem (the wording is cli/data.py's)


# --- how main maps exceptions -------------------------------------------------------------------


def _command_raising(monkeypatch, error: BaseException):
    def run(args):
        raise error

    monkeypatch.setattr(cli_view, "run", run)
    monkeypatch.setattr(ambulo.cli.view, "run", run)


@pytest.mark.parametrize("error, parts", [
    (PermissionError(13, "Permission denied", "/data/out"), ("cannot use '/data/out': permission denied",
                                                              "check its permissions")),
    (IsADirectoryError(21, "Is a directory", "/data"), ("cannot use '/data': is a directory",
                                                         "give a file path, not a folder")),
    (NotADirectoryError(20, "Not a directory", "/a/b"), ("cannot use '/a/b': not a directory", "fix the path")),
    (ModuleNotFoundError("No module named 'rsl_rl'", name="rsl_rl"), ("needs the package 'rsl_rl'",
                                                                      "pip install 'ambulo[rl]'")),
    (AssetError("x.xml: cannot be loaded: XML parse error\nElement name=body; fix the file"),
     ("x.xml: cannot be loaded: XML parse error Element name=body", "fix the file")),
    (InvalidValueError("num_worlds", 0, "it must be >= 1", "pass e.g. 64"), ("num_worlds is 0", "pass e.g. 64")),
    (OverrideError("k", "unknown key 'k'", "did you mean 'kp'?"), ("unknown key 'k'; did you mean 'kp'?",)),
])
def test_expected_errors_become_one_line(capsys, monkeypatch, error, parts):
    _command_raising(monkeypatch, error)
    _fails(capsys, ["view", "jetbot"], "ambulo view: error:", *parts)


def test_ctrl_c_is_one_line_and_130(capsys, monkeypatch):
    _command_raising(monkeypatch, KeyboardInterrupt())
    _fails(capsys, ["view", "jetbot"], "ambulo view: interrupted", status=130)


def test_a_real_bug_keeps_its_traceback(monkeypatch):
    _command_raising(monkeypatch, ZeroDivisionError("a bug"))
    with pytest.raises(ZeroDivisionError):
        main(["view", "jetbot"])


@pytest.mark.parametrize("argv", [["--debug", "view", "jetbto"], ["view", "jetbto", "--debug"]])
def test_debug_shows_the_traceback_of_expected_errors(argv):
    with pytest.raises(ambulo.cli.CliError, match="did you mean 'jetbot'"):
        main(argv)


# --- the real entry point -----------------------------------------------------------------------


def _ambulo(*argv: str) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": SRC, "PATH": "/usr/bin:/bin"}
    return subprocess.run([sys.executable, "-m", "ambulo", *argv], capture_output=True, text=True, env=env,
                          timeout=120)


def test_python_m_ambulo_answers_in_one_line(tmp_path):
    result = _ambulo("view", str(tmp_path / "missing.xml"))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"ambulo view: error: no file or bundled asset named '{tmp_path / 'missing.xml'}'; give 'demo', a "
        f"bundled asset ({result.stderr.split('a bundled asset (')[1].split(')')[0]}) or a .xml/.urdf/.usda file"]
    debug = _ambulo("--debug", "view", str(tmp_path / "missing.xml"))
    assert debug.returncode == 1 and "Traceback" in debug.stderr and "CliError" in debug.stderr


def test_python_m_ambulo_bad_value_through_the_library():
    result = _ambulo("train", "cartpole", "--env-cfg", "physics.gravity_m_s2=0,0,inf")
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert "physics.gravity_m_s2" in result.stderr and "e.g. (0, 0, -9.81)" in result.stderr


@pytest.mark.parametrize("pair, shown", [("episode_length_s=-5", "-5.0"), ("episode_length_s=inf", "inf"),
                                         ("episode_length_s=0", "0.0")])
def test_python_m_ambulo_refuses_a_meaningless_episode_length_before_training(tmp_path, pair, shown):
    # -5 made every env done every step; inf failed later, in the run
    result = _ambulo("train", "cartpole", "--env-cfg", pair, "--max-iterations", "1",
                     "--log-root", str(tmp_path / "runs"))
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith(f"ambulo train: error: --env-cfg bad value {shown} for episode_length_s: a duration "
                               "must be "), lines[0]
    assert "pass seconds, e.g. episode_length_s=" in lines[0]
    assert not (tmp_path / "runs").exists()  # refused before any run started


def test_a_device_without_an_engine_is_one_line_and_makes_no_run_folder(tmp_path, capsys):
    from ambulo.cli import main

    assert main(["train", "cartpole", "--device", "cuda:7", "--max-iterations", "1",
                 "--log-root", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "device is 'cuda:7'" in err and "device='cpu'" in err
    assert not (tmp_path / "runs").exists()


def test_a_config_file_with_a_syntax_error_names_its_line(tmp_path, capsys):
    from ambulo.cli import main

    bad = tmp_path / "cfg.py"
    bad.write_text("import math\ndef config(:\n")
    assert main(["generate", str(bad), "--frames", "1", "--out", str(tmp_path / "data")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{bad}:2:" in err and "syntax" in err
