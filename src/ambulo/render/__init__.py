"""Headless rendering helpers shared by cameras and the data generator."""

from .gl import NoOpenGLError, create_gl_context, gl_backend, gl_renderer_string
from .offscreen import OffscreenRenderer, RenderSettings, fast_render_settings, quality_render_settings

__all__ = [
    "NoOpenGLError",
    "OffscreenRenderer",
    "RenderSettings",
    "create_gl_context",
    "fast_render_settings",
    "gl_backend",
    "gl_renderer_string",
    "quality_render_settings",
]
