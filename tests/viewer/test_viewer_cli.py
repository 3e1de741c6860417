"""``--viewer web`` / ``--viewer-port`` on the commands that simulate a World: the URL is printed,
the scene runs its seconds and the server is gone afterwards; bad flags are one-line errors."""

from __future__ import annotations

import re
import socket

import pytest

pytest.importorskip("viser")
from ambulo.cli import main
from ambulo.sim import World
from ports import free_port


def test_view_serves_the_scene_for_its_seconds_then_frees_the_port(capsys):
    World.clear_instance()
    port = free_port()
    assert main(["view", "jetbot", "--viewer", "web", "--viewer-port", str(port), "--seconds", "0.2"]) == 0
    url = re.search(r"ambulo viewer: http://127\.0\.0\.1:(\d+)", capsys.readouterr().out)
    assert url and int(url.group(1)) == port
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0
    World.clear_instance()


@pytest.mark.timeout(120)  # without the checks these would start a server (port 0) or never bind (70000)
@pytest.mark.parametrize("argv, problem", [
    (["view", "jetbot", "--viewer", "web", "--viewer-port", "70000"], "--viewer-port 70000 is not a TCP port"),
    (["view", "jetbot", "--viewer", "web", "--video", "x.mp4"], "--viewer web shows the scene live"),
    (["demo", "--viewer", "web", "--viewer-port", "0"], "--viewer-port 0 is not a TCP port"),
])
def test_bad_viewer_flags_are_one_line_errors(capsys, argv, problem):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and problem in err[0], err
