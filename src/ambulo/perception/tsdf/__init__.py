"""The colour TSDF in sparse voxel blocks (``TsdfMap``) and its parts.

- ``map``: ``TsdfCfg``, ``TsdfMap`` (storage, block hash, ``integrate``, ``dense``) and ``DenseGrid``;
- ``block_hash``: the device-side hash from block coordinates to storage slots;
- ``frame``: the per-frame buffers the Warp and torch paths share;
- ``kernels``: the fused Warp kernels; ``launches``: their recorded launches (CPU, or a dense volume
  too big for a graph); ``graph``: a whole frame as one captured graph (CUDA);
- ``reference``: the eager-torch path the kernels are tested against (and the fallback without Warp).
"""

from .map import DenseGrid, TsdfCfg, TsdfMap

__all__ = ["DenseGrid", "TsdfCfg", "TsdfMap"]
