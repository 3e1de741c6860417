"""Perception on any RGB-D stream, tensor-first (torch: the same code on the CPU and CUDA).

- ``frames``: ``RgbdFrame`` (depth, colour, intrinsics, pose) and back-projection.
- ``tsdf``: colour TSDF in sparse voxel blocks (``block_hash``); ``esdf``: exact windowed EDT.
- ``slices``: occupancy / distance slices for a height band, the height / steppability map.
- ``costmap``: Nav2's inflation for a humanoid footprint, as a (H, W) uint8 tensor.
- ``mesh``: marching cubes (whole map or incremental per block) and PLY output.
- ``vo``: RGB-D visual odometry (OpenCV ORB, PnP RANSAC, depth refinement, keyframes, recovery);
  ``trajectory``: TUM files and ``evo`` scoring.
- ``stereo``: OpenCV SGBM disparity and disparity -> depth.
- ``scenes`` and ``walk``: the seeded indoor scene and the humanoid's head camera walking in it;
  ``reference``: Open3D ground truth and Open3D's TSDF to compare with.

OpenCV, Open3D, evo and scikit-image come with ``pip install 'ambulo[perception]'``; each is
imported only by the part that uses it.
"""

from .costmap import Costmap, InflationCfg, inflate, nav2_cost
from .esdf import Esdf, edt, esdf_from_grid
from .frames import RgbdFrame, backproject
from .slices import HeightMap, Slice2D, distance_slice, height_map, occupancy_slice
from .tsdf import DenseGrid, TsdfCfg, TsdfMap

__all__ = ["Costmap", "DenseGrid", "Esdf", "HeightMap", "InflationCfg", "RgbdFrame", "Slice2D", "TsdfCfg", "TsdfMap",
           "backproject", "distance_slice", "edt", "esdf_from_grid", "height_map", "inflate", "nav2_cost",
           "occupancy_slice"]
