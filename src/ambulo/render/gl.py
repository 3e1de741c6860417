"""Headless OpenGL contexts for MuJoCo's renderer, and the GL renderer string.

MuJoCo picks its GL backend from ``MUJOCO_GL`` when ``mujoco`` is first imported;
on a headless Linux machine the default (GLFW) needs a display and fails. We
therefore choose ourselves: ``MUJOCO_GL`` when the user set it, otherwise EGL
without a display (Mesa's llvmpipe when there is no GPU) and GLFW with one.
"""

from __future__ import annotations

import os
import platform

_BACKEND_ERRORS = (ImportError, AttributeError, OSError, RuntimeError)


def _context_class(backend: str):
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    elif backend == "glfw":
        from mujoco.glfw import GLContext
    else:
        raise ValueError(f"unknown GL backend {backend!r}; use MUJOCO_GL=egl, osmesa or glfw")
    return GLContext


def gl_backend() -> str:
    """The backend ``create_gl_context`` uses: ``MUJOCO_GL`` or a headless default."""
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen:
        return chosen
    if platform.system() == "Linux" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "egl"
    return "glfw"


def create_gl_context(width: int, height: int):
    """A current offscreen GL context of at least ``width`` x ``height`` pixels."""
    backend = gl_backend()
    try:
        context = _context_class(backend)(width, height)
    except _BACKEND_ERRORS as err:
        raise RuntimeError(
            f"could not create a headless OpenGL context with MUJOCO_GL={backend} ({err}). "
            "On Linux without a GPU install Mesa (apt-get install libegl1 libgl1-mesa-dri) "
            "for EGL, or libosmesa6 and set MUJOCO_GL=osmesa."
        ) from err
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
