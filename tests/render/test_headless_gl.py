"""A headless machine without libEGL or libOSMesa (issue 22): ambulo imports and trains, and a
render fails in one line naming what to install.

The libraries are hidden from a subprocess by a ``sitecustomize`` that makes ``ctypes`` fail to
load them, the way ``dlopen`` fails when they are not installed. PyOpenGL then fails exactly as
on such a machine (``AttributeError: 'NoneType' object has no attribute 'eglQueryString'``, the
same as with the files bind-mounted away in a private mount namespace) and no root is needed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ambulo.render import gl

SRC = str(Path(__file__).resolve().parents[2] / "src")

HIDE_GL = '''
import ctypes, ctypes.util, re
_hidden = re.compile(r"(^|/)lib(EGL|OSMesa)[._]")
_init, _find = ctypes.CDLL.__init__, ctypes.util.find_library
def _no_gl(self, name, *args, **kwargs):
    if name and _hidden.search(str(name)):
        raise OSError(f"{name}: cannot open shared object file: No such file or directory")
    _init(self, name, *args, **kwargs)
ctypes.CDLL.__init__ = _no_gl
ctypes.util.find_library = lambda name: None if name in ("EGL", "OSMesa") else _find(name)
'''


@pytest.fixture(scope="module")
def without_gl(tmp_path_factory):
    """Runs ``python -m ambulo ...`` (or ``python -c``) headless with no libEGL/libOSMesa."""
    shim = tmp_path_factory.mktemp("no_gl")
    (shim / "sitecustomize.py").write_text(HIDE_GL)
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env["PYTHONPATH"] = os.pathsep.join([str(shim), SRC])

    def run(*argv: str, **extra_env: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, *argv], capture_output=True, text=True,
                              env={**env, **extra_env}, timeout=300)
    return run


def test_the_shim_reproduces_the_missing_library(without_gl):
    result = without_gl("-c", "import mujoco", MUJOCO_GL="egl")
    assert result.returncode == 1 and "AttributeError" in result.stderr, result.stderr


def test_training_needs_no_gl(without_gl, tmp_path):
    result = without_gl("-m", "ambulo", "train", "cartpole", "--max-iterations", "2", "--num-envs", "8",
                        "--log-root", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert list(tmp_path.glob("cartpole/*/model_*.pt"))


def test_a_render_without_gl_is_one_line_naming_the_packages(without_gl, tmp_path):
    video = tmp_path / "out.mp4"
    result = without_gl("-m", "ambulo", "view", "jetbot", "--video", str(video), "--seconds", "0.1")
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ambulo view: error: "), result.stderr
    assert "libegl1" in lines[0] and "libosmesa6" in lines[0] and "MUJOCO_GL" in lines[0]
    assert not list(tmp_path.iterdir())


# --- the choice, in this process -----------------------------------------------------------------


@pytest.fixture
def headless(monkeypatch):
    """No display, no MUJOCO_GL; returns the set of backends whose library 'loads'."""
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    loadable = {"egl", "osmesa"}
    monkeypatch.setattr(gl, "_loadable", lambda backend: backend in loadable)
    return loadable


def test_egl_then_osmesa_then_one_line(headless):
    assert gl.gl_backend() == "egl"
    headless.discard("egl")
    assert gl.gl_backend() == "osmesa"
    headless.discard("osmesa")
    with pytest.raises(gl.NoOpenGLError) as err:
        gl.gl_backend()
    assert "\n" not in str(err.value) and "apt-get install libegl1 libosmesa6" in str(err.value)


def test_the_users_choice_wins(headless, monkeypatch):
    headless.clear()
    monkeypatch.setenv("MUJOCO_GL", " OSMesa ")
    assert gl.gl_backend() == "osmesa"
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.setenv("PYOPENGL_PLATFORM", "egl")  # PyOpenGL can then only do EGL
    assert gl.gl_backend() == "egl"


def test_a_display_means_glfw(headless, monkeypatch):
    monkeypatch.setenv("DISPLAY", ":0")
    assert gl.gl_backend() == "glfw"
