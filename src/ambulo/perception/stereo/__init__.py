"""Stereo depth from a rectified pair.

- ``sgm``: census + semi-global matching in torch on any device (``sgm_disparity``, ``CudaGraphSgm``,
  ``stereo_frame`` for the mapper);
- ``kernels``: that matcher's path aggregation as fused Warp kernels;
- ``sgbm_opencv``: OpenCV's SGBM on the host (``sgbm_disparity``).

Each module has its own ``disparity_to_depth`` (numpy in ``sgbm_opencv``, torch in ``sgm``): import
it from the one that matches your arrays.
"""

from .sgbm_opencv import SgbmCfg, sgbm_disparity
from .sgm import CudaGraphSgm, SgmCfg, sgm_disparity, stereo_frame

__all__ = ["CudaGraphSgm", "SgbmCfg", "SgmCfg", "sgbm_disparity", "sgm_disparity", "stereo_frame"]
