"""Perception on any RGB-D stream, tensor-first (torch: the same code on the CPU and CUDA).

- ``frames``: ``RgbdFrame`` (depth, colour, intrinsics, pose) and back-projection.
- ``tsdf/``: colour TSDF in sparse voxel blocks (``TsdfMap``: a block hash, fused Warp kernels, a torch
  reference); ``esdf``: exact windowed EDT (``esdf_kernels``).
- ``slices``: occupancy / distance slices for a height band, the height / steppability map.
- ``costmap``: Nav2's inflation for a humanoid footprint, as a (H, W) uint8 tensor.
- ``mesh``: marching cubes (whole map or incremental per block) and PLY output.
- ``vo/``: RGB-D visual odometry (``RgbdOdometry``: OpenCV ORB or kornia features, PnP RANSAC, depth
  refinement, keyframes, recovery, gyro aiding); ``trajectory``: TUM files and ``evo`` scoring.
- ``stereo/``: OpenCV SGBM, and a census + semi-global matcher in torch and Warp; disparity -> depth.
- ``sources/``: the humanoid's head camera walking the indoor scene (``ambulo.scenes.indoor``) and its
  gyro; ``reference``: Open3D ground truth and Open3D's TSDF to compare with; ``box_raycast``: the same
  depth without Open3D; ``pipeline``: ``ambulo map`` end to end; ``images``: PNGs of the maps.

OpenCV, Open3D, evo and scikit-image come with ``pip install 'ambulo[perception]'``; each is
imported only by the part that uses it.
"""

from .costmap import Costmap, InflationCfg, inflate, nav2_cost
from .esdf import Esdf, edt, esdf_from_grid
from .frames import RgbdFrame, backproject
from .slices import HeightMap, Slice2D, distance_slice, height_map, occupancy_slice
from .tsdf import DenseGrid, TsdfCfg, TsdfMap
from .vo import GyroSamples, RgbdOdometry, TrackState, VoCfg, kornia_vo_cfg

__all__ = ["Costmap", "DenseGrid", "Esdf", "GyroSamples", "HeightMap", "InflationCfg", "RgbdFrame", "RgbdOdometry",
           "Slice2D", "TrackState", "TsdfCfg", "TsdfMap", "VoCfg", "backproject", "distance_slice", "edt",
           "esdf_from_grid", "height_map", "inflate", "kornia_vo_cfg", "nav2_cost", "occupancy_slice"]
