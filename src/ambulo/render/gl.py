"""Headless OpenGL contexts for MuJoCo's renderer, and the GL renderer string.

MuJoCo picks its GL backend from ``MUJOCO_GL`` when ``mujoco`` is first imported;
on a headless Linux machine the default (GLFW) needs a display and fails, so
``ambulo/__init__.py`` sets EGL there (Mesa's llvmpipe when there is no GPU).
Contexts are created here from that same choice, whatever mujoco saw.
"""

from __future__ import annotations

import os

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
    """The backend ``create_gl_context`` uses: ``MUJOCO_GL``, which importing ``ambulo`` set to
    EGL on a headless Linux machine unless the user chose; GLFW (a window system) otherwise."""
    return os.environ.get("MUJOCO_GL", "").strip().lower() or "glfw"


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
