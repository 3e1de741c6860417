"""Headless OpenGL contexts for MuJoCo's renderer, and the GL renderer string.

The backend is chosen at the first context, never at ``import ambulo``: ``import mujoco`` imports
the backend ``MUJOCO_GL`` names, and for EGL without libEGL PyOpenGL raises an AttributeError
there that mujoco does not catch, which broke every command, training too (issue 22). Contexts
come from ``mujoco.egl``/``mujoco.osmesa`` directly, so what ``import mujoco`` bound (GLFW when
``MUJOCO_GL`` is unset) does not matter. PyOpenGL binds its platform once per process, so a
backend is chosen only if its library loads: a failed import cannot be undone by a fallback.
"""

from __future__ import annotations

import ctypes
import os
import sys

_BACKEND_ERRORS = (ImportError, AttributeError, OSError, RuntimeError)

_HEADLESS = {"egl": "EGL", "osmesa": "OSMesa"}
"""Headless backends in the order tried (EGL uses a GPU when there is one) -> PyOpenGL's library."""

_PACKAGE = {"egl": "libegl1", "osmesa": "libosmesa6"}
"""The Debian/Ubuntu package of each headless backend's library."""

INSTALL = "install libegl1 (or libosmesa6): apt-get install libegl1 libosmesa6; or set MUJOCO_GL"


class NoOpenGLError(RuntimeError):
    """No OpenGL context can be made here; ``str(err)`` is one line ``"<problem>; <fix>"``."""

    def __init__(self, problem: str, fix: str = INSTALL):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}")


def _loadable(backend: str) -> bool:
    """Whether the library PyOpenGL loads for ``backend`` loads here (the names PyOpenGL tries)."""
    name = _HEADLESS[backend]
    for filename in [f"lib{name}.so", *(f"lib{name}.so.{i}" for i in range(9, -1, -1))]:
        try:
            ctypes.CDLL(filename)
        except OSError:
            continue
        return True
    return False


def _has_display() -> bool:
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def gl_backend() -> str:
    """The backend ``create_gl_context`` uses: the user's ``MUJOCO_GL`` (or ``PYOPENGL_PLATFORM``,
    which leaves PyOpenGL no other); else GLFW with a display; else EGL if libEGL loads, then
    OSMesa if libOSMesa does; else ``NoOpenGLError`` naming the packages to install."""
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    platform = os.environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    if chosen or platform in _HEADLESS:
        return chosen or platform
    if _has_display():
        return "glfw"
    backend = next((b for b in _HEADLESS if _loadable(b)), None)
    if backend is None:
        raise NoOpenGLError("no headless OpenGL: no display, and neither libEGL nor libOSMesa can be loaded")
    return backend


def _context_class(backend: str):
    if backend in _HEADLESS and not _loadable(backend):  # PyOpenGL would fail with an AttributeError
        raise NoOpenGLError(f"MUJOCO_GL={backend} but lib{_HEADLESS[backend]} cannot be loaded",
                            f"install {_PACKAGE[backend]} (apt-get install {_PACKAGE[backend]}), or unset "
                            "MUJOCO_GL to use what is installed")
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    elif backend == "glfw":
        from mujoco.glfw import GLContext
    else:
        raise NoOpenGLError(f"ambulo cannot render with MUJOCO_GL={backend}", "set MUJOCO_GL=egl, osmesa or glfw")
    return GLContext


def create_gl_context(width: int, height: int):
    """A current offscreen GL context of at least ``width`` x ``height`` pixels."""
    backend = gl_backend()
    try:
        context = _context_class(backend)(width, height)
    except NoOpenGLError:
        raise
    except _BACKEND_ERRORS as err:
        raise NoOpenGLError(
            f"could not create an OpenGL context with MUJOCO_GL={backend} ({' '.join(str(err).split())})",
            "install Mesa's drivers (apt-get install libegl-mesa0 libgl1-mesa-dri libosmesa6) or set "
            "MUJOCO_GL=egl|osmesa") from err
    # processes started from here (Ray workers, spawned ones) render the same way without probing
    os.environ.setdefault("MUJOCO_GL", backend)
    context.make_current()
    return context


def gl_renderer_string() -> str:
    """GL_RENDERER of the current context, e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)'.

    Recorded in dataset metadata so that a silent fallback to a software
    rasterizer (the usual cause of 'EGL is as slow as OSMesa') is visible.
    """
    from OpenGL import GL

    name = GL.glGetString(GL.GL_RENDERER)
    return name.decode() if isinstance(name, bytes) else str(name)
