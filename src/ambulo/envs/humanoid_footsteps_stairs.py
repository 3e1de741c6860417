"""humanoid-footsteps-stairs: humanoid-footsteps over 0.10 m stairs, targets with heights, a height scan.

humanoid-footsteps (its plans, touchdown rule, rewards and ``places_feet``) on humanoid-rough's
terrain (``scenes.terrain``): a grid of tiles, one column each of flat ground, stairs up (a pit
the robot climbs out of) and stairs down (a summit), levels of risers from 0.05 m to the issue's
0.10 m (treads 0.30 m). Robots start on their tile's flat centre platform, at random, and keep
their tile (no curriculum: a footstep plan asks for no distance, so legged_gym's "walked far"
rule has nothing to read); play and evaluation put every robot on the 0.10 m level.

Plans are drawn as on flat ground, then each footstep moves along its step to lie flat on a tread
(``footstep_terrain.TreadSnap``); a target's height is the ground under its sole centre
(``targets_z_m``; a planner plan's ``foot_z_m`` through ``follow_plans``). The actor's command
grows to 12 values: per target x, y (m, heading frame), z (m, the target's height over the
ground under the base), cos and sin of its yaw relative to the heading, side. After it, as on
humanoid-rough, a 17 x 11 height scan around the base (``HeightScanCfg``, +-5 cm noise in
training). The critic also sees each foot's height over the ground under it. Foot contacts are
against every geom of the terrain body (its hfield and, with ``box_tiles``, its boxes:
``ContactSensorCfg.against_body``); falls count against the ground under the base, so a robot on a tread
0.5 m up is not fallen. A new task rather than an option of humanoid-footsteps: the shipped flat
policy keeps its 79 observations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ambulo.scenes.terrain import (
    TerrainCfg,
    TerrainCurriculumCfg,
)

from .footstep_sampler import relative_xyyaw
from .footstep_terrain import TreadSnap, TreadSnapCfg
from .humanoid_footsteps import (
    PLACES_FEET,
    HumanoidFootstepsCfg,
    HumanoidFootstepsEnv,
    humanoid_footsteps_cfg,
    humanoid_footsteps_metrics,
)
from .humanoid_walk import as_play, humanoid_walk_ppo
from .registry import TaskSpec, register
from .terrain_ground import TerrainGround, TerrainGroundCfg
from .transfer import PLAY_KEEPS

STAIR_RISER_M = 0.10
"""The issue's step height (issue 30 item 4: footsteps "over 0.10 m steps"), m."""


def stairs_terrain_cfg() -> TerrainCfg:
    """Flat, stairs-up and stairs-down columns; 4 levels of risers 0.05 .. 0.10 m; 8 m tiles
    (10 treads of 0.30 m from the 2 m platform to the edge); 10 m of flat border (a plan walks
    at most ~0.5 m/s, 10 m in an episode, and a tile holds most of it)."""
    return TerrainCfg(kinds=("flat", "stairs_up", "stairs_down"), num_levels=4,
                      stair_riser_range_m=(0.05, STAIR_RISER_M), border_m=10.0)


@dataclass(kw_only=True)
class HumanoidFootstepsStairsCfg(HumanoidFootstepsCfg, TerrainGroundCfg):
    """humanoid-footsteps settings and the terrain ground's (the stairs grid)."""

    terrain: TerrainCfg = field(default_factory=stairs_terrain_cfg)
    levels: TerrainCurriculumCfg = field(default_factory=lambda: TerrainCurriculumCfg(enabled=False,
                                                                                       max_init_level=3),
                                         metadata={PLAY_KEEPS: True})
    """Which level (riser) each robot gets: uniform over the levels, kept (``enabled`` False). Training
    only (``PLAY_KEEPS``): play and evaluation put every robot on the 0.10 m level with each column an
    equal share whatever the run trained with (``levels.kind_weights`` included)."""
    treads: TreadSnapCfg = field(default_factory=TreadSnapCfg)

def humanoid_footsteps_stairs_cfg() -> HumanoidFootstepsStairsCfg:
    """humanoid-footsteps' settings on the stairs terrain, scan noise +-5 cm (humanoid-rough's)."""
    flat = humanoid_footsteps_cfg()
    cfg = HumanoidFootstepsStairsCfg(**{name: getattr(flat, name) for name in flat.__dataclass_fields__})
    cfg.ground = None  # the terrain is the ground
    cfg.observation_noise = dict(cfg.observation_noise, height_scan=0.05)
    return cfg


def humanoid_footsteps_stairs_play_cfg() -> HumanoidFootstepsStairsCfg:
    """Play and evaluation: no pushes, noise or randomization, every robot on the 0.10 m level."""
    cfg = as_play(humanoid_footsteps_stairs_cfg())
    cfg.levels = TerrainCurriculumCfg(enabled=False, init_level=-1)
    return cfg


class HumanoidFootstepsStairsEnv(TerrainGround, HumanoidFootstepsEnv):
    """Footstep following over stairs; see the module docstring."""

    cfg: HumanoidFootstepsStairsCfg
    terrain_task = "humanoid-footsteps-stairs"

    def _setup(self) -> None:
        super()._setup()  # the sampler; the first reset (spawn, plans) comes after every setup
        self.tiles = self._setup_terrain(self.cfg.levels)
        self.treads = TreadSnap(self.cfg.treads, self.heights.height_at, self.sampler, self.device)

    # -- terrain ------------------------------------------------------------------------------
    def _footstep_z_m(self, xy_w: torch.Tensor) -> torch.Tensor:
        return self.heights.height_at(xy_w)

    def _next_footstep(self, stance_xyyaw_w, stance_side, segments):
        pose, segments = self.sampler.next_footstep(stance_xyyaw_w, stance_side, segments)
        pose, z = self.treads.snap(stance_xyyaw_w, pose)
        return pose, z, segments

    def _spawn(self, rows) -> None:
        self._spawn_on_tiles(rows, self.tiles.origins_w)

    # -- RLEnv hooks ----------------------------------------------------------------------------
    def footstep_command(self) -> torch.Tensor:
        """(N, 12) the actor's command: per target x, y (m, heading frame), z (m: its height over
        the ground under the base), cos, sin of the yaw relative to the heading, side (+1 left)."""
        rel = relative_xyyaw(self._base_xyyaw_w()[:, None].expand(-1, 2, -1), self.targets_xyyaw_w)
        ground = self.heights.height_at(self.robot.data.root_pos_w[:, :2])
        z = self.targets_z_m - ground[:, None]
        cmd = torch.cat([rel[..., :2], z[..., None], torch.cos(rel[..., 2:]), torch.sin(rel[..., 2:]),
                         self.target_sides[..., None]], dim=-1)
        return cmd.reshape(self.num_envs, 12)

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        return {**super()._policy_terms(), "height_scan": self._height_scan()}

    def _privileged_terms(self) -> dict[str, torch.Tensor]:
        terms = super()._privileged_terms()
        terms["feet_height_over_ground"] = self._feet_height_over_ground_m()
        return terms

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        terms = super()._get_terminations()  # humanoid-walk's (z over 0) and the lost plan
        fell_height = self.base_height_over_ground_m() < self.cfg.min_base_height_m
        self._fell = fell_height | terms["tilt"] | terms["lost_plan"]
        return {**terms, "base_height": fell_height}


register(TaskSpec(
    name="humanoid-footsteps-stairs",
    env_cls=HumanoidFootstepsStairsEnv,
    cfg_fn=humanoid_footsteps_stairs_cfg,
    play_cfg_fn=humanoid_footsteps_stairs_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="humanoid-footsteps over stairs of 0.05-0.10 m risers (and flat tiles): targets with heights, "
                "drawn on the treads, and a height scan",
    step_metrics=humanoid_footsteps_metrics,
    criteria=(PLACES_FEET,),
))

__all__ = ["STAIR_RISER_M", "HumanoidFootstepsStairsCfg", "HumanoidFootstepsStairsEnv", "humanoid_footsteps_stairs_cfg",
           "humanoid_footsteps_stairs_play_cfg", "stairs_terrain_cfg"]
