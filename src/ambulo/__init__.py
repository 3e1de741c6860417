"""ambulo: open robotics simulation and learning on MuJoCo."""

import os as _os
import sys as _sys

# MuJoCo picks its GL backend when first imported. Without a display, default to
# EGL (GPU or Mesa's llvmpipe) so renderers work headless; users may override.
# ambulo.render reads the choice back from MUJOCO_GL: this is the one place it is made.
_has_display = _os.environ.get("DISPLAY") or _os.environ.get("WAYLAND_DISPLAY")
if _sys.platform.startswith("linux") and not _has_display and "MUJOCO_GL" not in _os.environ:
    _os.environ["MUJOCO_GL"] = "egl"
    _os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

__version__ = "0.1.0"
