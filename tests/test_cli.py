"""The ambulo command line: the README's demo and the headless viewer."""

import pytest

from ambulo.cli import build_parser, main


def test_demo_prints_what_happened_and_writes_an_mp4(tmp_path, capsys):
    video = tmp_path / "demo.mp4"
    assert main(["demo", "--seconds", "2", "--video", str(video), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "humanoid stood" in out and "jetbot drove" in out
    assert video.stat().st_size > 10_000
    assert not (tmp_path / "demo.part.mp4").exists()


def test_view_records_a_bundled_asset_headless(tmp_path, capsys):
    video = tmp_path / "rover.mp4"
    assert main(["view", "rover", "--video", str(video), "--seconds", "0.5"]) == 0
    assert video.stat().st_size > 1_000


def test_view_unknown_asset_names_the_bundled_ones():
    with pytest.raises(FileNotFoundError, match="jetbot"):
        main(["view", "jetbott", "--video", "x.mp4"])


def test_every_command_is_registered():
    commands = build_parser()._subparsers._group_actions[0].choices
    assert {"demo", "view", "generate", "train", "play", "export", "eval"} <= set(commands)


def test_missing_optional_package_names_the_extra(monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "rsl_rl", None)  # as if rsl-rl-lib were not installed
    monkeypatch.setitem(sys.modules, "rsl_rl.runners", None)
    for name in [m for m in sys.modules if m.startswith("ambulo.rl")]:
        monkeypatch.delitem(sys.modules, name)
    assert main(["train", "cartpole", "--max-iterations", "1"]) == 2
    assert "pip install 'ambulo[rl]'" in capsys.readouterr().err
