"""Procedural terrain for locomotion: tiles of sub-terrains by difficulty, one MuJoCo hfield.

- ``subterrains``: each kind's height function (flat, slopes, rough, stairs up and down,
  stepping stones) of a difficulty in [0, 1];
- ``generator``: ``TerrainCfg`` -> ``TerrainGrid`` (levels x kinds tiles, heights, tile centres)
  and ``add_terrain`` (into a scene spec as one hfield geom, for the CPU and GPU engines);
- ``heights``: ``TerrainHeights`` (the same samples interpolated on the device) and
  ``HeightScan`` (the actor's grid of ground heights around the base);
- ``curriculum``: ``TerrainCurriculum`` (legged_gym's level moves, vectorized over worlds);
- ``boxes``: the piecewise-flat tiles (flat, stairs; stepping stones on request) and the border as
  static boxes (``TerrainCfg.box_tiles``, ``box_kinds``), so a resting sphere gets one contact in
  MuJoCo C as in MuJoCo Warp;
- ``box_colliders``: ``restrict_box_colliders`` (only some bodies touch the boxes: fewer candidate
  pairs for MuJoCo Warp's broadphase) and ``candidate_geom_pairs``;
- ``soles``: ``sphere_soles`` (feet touch the hfield through corner spheres: MuJoCo Warp's
  box-hfield contacts are wrong for flat soles).
"""

from .box_colliders import candidate_geom_pairs, restrict_box_colliders
from .boxes import BOX_KINDS, PIECEWISE_FLAT_KINDS, TerrainBoxes, terrain_boxes
from .curriculum import TerrainCurriculum, TerrainCurriculumCfg, check_kind_weights, weighted_columns
from .generator import TERRAIN_PRIM_PATH, TerrainCfg, TerrainGrid, add_terrain, difficulties, generate
from .heights import HeightScan, HeightScanCfg, TerrainHeights
from .soles import sphere_soles
from .subterrains import KINDS

__all__ = ["BOX_KINDS", "KINDS", "PIECEWISE_FLAT_KINDS", "TERRAIN_PRIM_PATH", "HeightScan", "HeightScanCfg", "TerrainCfg", "TerrainCurriculum",
           "TerrainBoxes", "TerrainCurriculumCfg", "TerrainGrid", "TerrainHeights", "add_terrain", "candidate_geom_pairs", "check_kind_weights", "difficulties",
           "generate", "restrict_box_colliders", "sphere_soles", "terrain_boxes", "weighted_columns"]
