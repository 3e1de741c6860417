"""Denoising of path-traced images with Intel Open Image Denoise (``pyoidn``, CPU or CUDA).

OIDN's ``RT`` filter takes the noisy linear colour with the first-hit albedo and normal of the
same pixels (both nearly noise-free at a few samples per pixel), which is what lets 16 samples per
pixel look like hundreds. The same wheel runs on the CPU (NumPy arrays) and on CUDA (torch tensors,
so a GPU-rendered image is denoised without leaving the device).
"""

from __future__ import annotations

import numpy as np


class NoDenoiserError(RuntimeError):
    """No denoiser can run here (its one-line message names what to install)."""


def _pyoidn():
    try:
        import pyoidn
    except ImportError:
        return None
    return pyoidn


def denoise_numpy(color: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None, *,
                  quality: str = "balanced") -> np.ndarray:
    """(H, W, 3) float32 linear HDR colour -> denoised colour of the same shape.

    ``albedo`` (H, W, 3) in [0, 1] and ``normal`` (H, W, 3) unit vectors are the guides; OIDN needs
    either both or albedo alone. ``quality``: "fast", "balanced" or "high" (OIDN's speed trade).
    """
    oidn = _pyoidn()
    if oidn is None:
        raise NoDenoiserError("denoising needs Open Image Denoise: pip install pyoidn (or pip install 'ambulo[render]')")
    color = np.ascontiguousarray(color, np.float32)
    guides = {}
    if albedo is not None:
        guides["albedo"] = np.ascontiguousarray(np.clip(albedo, 0.0, 1.0), np.float32)
        if normal is not None:
            guides["normal"] = np.ascontiguousarray(normal, np.float32)
    return oidn.denoise(color, hdr=True, quality=quality, **guides)


def denoise_torch(color, albedo=None, normal=None, *, quality: str = "balanced"):
    """As ``denoise_numpy`` for torch tensors, on their own device (CUDA stays on the GPU)."""
    oidn = _pyoidn()
    if oidn is None:
        raise NoDenoiserError("denoising needs Open Image Denoise: pip install pyoidn (or pip install 'ambulo[render]')")
    guides = {}
    if albedo is not None:
        guides["albedo"] = albedo.clamp(0.0, 1.0).contiguous()
        if normal is not None:
            guides["normal"] = normal.contiguous()
    return oidn.denoise(color.contiguous(), hdr=True, quality=quality, **guides)


def has_pyoidn() -> bool:
    return _pyoidn() is not None


__all__ = ["NoDenoiserError", "denoise_numpy", "denoise_torch", "has_pyoidn"]
