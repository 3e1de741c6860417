"""The per-frame working state shared by ``TsdfMap``'s two integration paths: the padded images and
allocation buffers kept between frames (``_FrameBuffers``) and a frame's small host matrices
(``_FrameGeometry``), with the padded border's depth.

Separate so that the Warp path (``tsdf/map.py``) and the torch reference path (``tsdf/reference.py``, a base
class of ``TsdfMap``) both import these types without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from . import kernels

_NO_DEPTH = kernels.NO_DEPTH
"""Depth of the padded image's border: a voxel projecting off the image reads it and is not updated."""


@dataclass
class _FrameBuffers:
    """Per-image-size working buffers of ``TsdfMap.integrate`` (kept between frames)."""

    shape: tuple[int, int]
    k: np.ndarray
    """(3, 3) float32 intrinsics the buffers were built for."""
    rays: torch.Tensor
    """(H/s, W/s, 3) float32 camera rays (z = 1) of the allocation pixels."""
    depth: torch.Tensor
    """(H + 2, W + 2) float32 depth (non-finite readings as _NO_DEPTH, which fails every depth range
    test as they do), _NO_DEPTH on the 1-pixel border."""
    depth_inner: torch.Tensor
    """(H, W) view of ``depth`` without its border (the frame's depth is copied in here)."""
    rgb: torch.Tensor
    """(H + 2, W + 2, 3) uint8 colour, same padding."""
    band: torch.Tensor
    """(3, 1, 1, 1) float32 offsets -trunc, 0, trunc along a ray, m."""
    r_blocks: int
    volume: torch.Tensor | None
    """(side^3 + 1,) bool dense block cells around the camera (torch path), None where too big."""
    strides: torch.Tensor
    volume_stamp: torch.Tensor | None = None
    """(parts, side^3) int32 frame stamp of each cell, per part of ``mark_band_blocks`` (Warp path: the
    volume is never cleared)."""
    new_keys: torch.Tensor | None = None
    """(parts, side^3) int64 keys of this frame's new blocks, per part (Warp path)."""


@dataclass
class _FrameGeometry:
    """A frame's small per-frame matrices, computed on the host (numpy float32; the Warp kernels read
    them from a ``FrameParams`` array) and shared by both backends, so that both do the same float32
    arithmetic."""

    k: np.ndarray
    """(3, 3) float32 intrinsics."""
    rot_cw: np.ndarray
    """(3, 3) float32 world-to-camera rotation; t_cw: (3,) its translation, m."""
    t_cw: np.ndarray
    kr: np.ndarray
    """(3, 3) float32 K' R_cw, K' = K with the principal point shifted by the 1-pixel pad; kt = K' t_cw."""
    kt: np.ndarray
    local_px: np.ndarray
    """(3, B^3) float32 K' R_cw of each local voxel offset."""
    rot_blocks: np.ndarray
    """(3, 3) float32 R_wc^T / block size: ray @ rot_blocks is a ray's world direction in blocks / m."""
    start_blocks: np.ndarray
    """(3,) float32 camera position in blocks + 0.5 / B."""
    position_blocks: np.ndarray
    """(3,) float32 camera position in blocks."""
