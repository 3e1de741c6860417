"""humanoid-rough: humanoid-walk over a terrain curriculum, with a height scan and transfer randomization.

The task of humanoid-walk (rewards, falls) on a grid of tiles
(``scenes.terrain``: flat, rough, slopes, stairs up and down to 0.15 m risers, stepping stones)
that robots climb level by level as they walk out of their tile or cover what their commands ask
(``scenes.terrain.curriculum``), judged by ``walks_rough`` (the issue's 0.25 m/s). The
actor sees, after humanoid-walk's 72 values, a height scan: base height over the ground at a
17 x 11 grid around the base (``HeightScanCfg``), read from the terrain's samples on the device.
The critic sees the clean scan and, privileged, each foot's height over the ground under it.
Falls count against the ground under the base (a robot on a 0.75 m stair summit is not fallen).
Transfer randomization (``envs.transfer``, humanoid-walk's ``transfer`` setting) is on: gains,
motor strength, joint friction and armature, CoM offsets at start, action latency and observation
delay per episode (``transfer_cfg_wide``).

Play and evaluation put every robot on the hardest level, with no curriculum and no transfer
randomization (``humanoid_rough_play_cfg``); ``mean_terrain_level`` reports where training is.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import torch

from ambulo.core.rows import fill_rows, put_rows
from ambulo.robots import humanoid
from ambulo.scenes.terrain import (
    TerrainCfg,
    TerrainCurriculumCfg,
)
from ambulo.utils.math import rotate_yaw

from .humanoid_walk import HumanoidWalkCfg, HumanoidWalkEnv, as_play, humanoid_walk_cfg, humanoid_walk_ppo
from .registry import Criterion, TaskSpec, register
from .terrain_ground import TerrainGround, TerrainGroundCfg
from .transfer import PLAY_KEEPS, transfer_cfg_wide

WALKS_ROUGH = Criterion("walks_rough", max_values={"fall_rate": 0.05, "mean_abs_vel_error_m_s": 0.25})
"""What walking means on the hardest tiles of the terrain curriculum (humanoid-rough, g1-rough):
the issue's bars, falls <= 5 % and velocity error <= 0.25 m/s (flat ground's ``walks`` asks 0.2)."""


HUMANOID_BOX_COLLIDERS = humanoid.LEG_BODIES
"""humanoid-rough's ``box_collider_bodies`` (its default since session 20; None: every geom): the thighs,
shanks and feet (with their sole spheres), 12 of the robot's 23 colliding geoms, touch the flat,
stairs and border boxes; pelvis, torso, head and arms pass through them (the hfield still holds
them). Not the pelvis: a fall ends the episode once the base is 0.5 m over the ground under it
(``min_base_height_m``), and the pelvis capsule (radius 0.09 m, +-0.07 m across) reaches a box top
at most one 0.15 m riser above that ground only with the base ~0.3 m over it, so it never touches a
box before its episode has ended; what a fallen robot does after that (it rests on its legs and on
the hfield under the boxes) is never learnt from. Not the feet alone: the shipped walker's shins
and thighs touch stair boxes when it trips (2-8 sampled contacts per 8 robots x 10 s at 1 m/s).
The shipped walker on the CPU engine, flat and stairs tiles, 8 seeds x 8 robots x 20 s: the
same trajectories bit for bit with and without (``benchmarks/box_colliders_walk.py``; results in
``benchmarks/results/cpu-2026-11-30-s19-box-colliders.md``). Why the default: on an H200 (4,096 worlds) rough/flat
env throughput is 0.512 with it against 0.474 without, the issue's bar being 0.5 (``benchmarks/rough_terrain.py``,
``benchmarks/results/h200x2-2026-11-30-session20.md``)."""


@dataclass(kw_only=True)
class RoughTerrainCfg(TerrainGroundCfg):
    """What a walking task on the terrain curriculum adds to its cfg (a dataclass mixin: humanoid-rough
    and g1-rough list it after their walking cfg): the terrain ground's and the curriculum's."""

    curriculum: TerrainCurriculumCfg = field(default_factory=TerrainCurriculumCfg, metadata={PLAY_KEEPS: True})
    """Training's terrain curriculum. Play and evaluation keep their own (``as_rough_play``: every robot
    on the hardest level, the kinds in equal shares) whatever the run trained with: its
    ``kind_weights`` must not change what ``walks_rough`` pools."""
    scan_in_actor: bool = True
    """The actor sees the height scan; False: only the critic does (a blind walker)."""


@dataclass(kw_only=True)
class HumanoidRoughCfg(HumanoidWalkCfg, RoughTerrainCfg):
    """humanoid-rough settings: humanoid-walk's and the terrain's."""


def as_rough(walk: HumanoidWalkCfg, cls: type) -> HumanoidWalkCfg:
    """``walk``'s settings in ``cls`` (a walking cfg with ``RoughTerrainCfg``) on the terrain grid,
    with the issue's transfer ranges (``transfer_cfg_wide``) and scan noise of +-5 cm."""
    cfg = cls(**{name: getattr(walk, name) for name in walk.__dataclass_fields__})
    cfg.ground = None  # the terrain is the ground
    # a robot on the last row walks out of the grid: 15 m of border holds a 20 s episode at up to
    # 1 m/s from 4 m inside (legged_gym keeps 25 m); past the heightfield's edge it would fall
    cfg.terrain = TerrainCfg(border_m=15.0)
    cfg.transfer = transfer_cfg_wide()
    cfg.observation_noise = dict(cfg.observation_noise, height_scan=0.05)
    # forward walking only, as Isaac Lab's H1 and G1 rough tasks command (vx 0..1 m/s, no lateral,
    # yaw rate +-1 rad/s; heading envs turn first): a humanoid climbs stairs facing them, and the
    # flat task's backward and sideways 0.5-1 m/s over 0.15 m risers and stepping stones is no
    # rough walker's job (session 16's PPO: 0.42 m/s error on stairs tiles, 0.55 on stones).
    # Omnidirectional rough walking stays one --env-cfg away (commands.lin_vel_x_m_s=-1,1 ...)
    cfg.commands = replace(cfg.commands, lin_vel_x_m_s=(0.0, 1.0), lin_vel_y_m_s=(0.0, 0.0))
    return cfg


def as_rough_play(cfg: HumanoidWalkCfg) -> HumanoidWalkCfg:
    """Play and evaluation of a rough task's ``cfg``: the walking play variant (no pushes, noise or
    transfer randomization), every robot on the hardest level."""
    cfg = as_play(cfg)
    cfg.curriculum = TerrainCurriculumCfg(enabled=False, init_level=-1)
    return cfg


def humanoid_rough_cfg() -> HumanoidRoughCfg:
    """humanoid-walk's settings on the terrain grid (``as_rough``), the terrain's boxes colliding with the
    legs only (``HUMANOID_BOX_COLLIDERS``)."""
    cfg = as_rough(humanoid_walk_cfg(), HumanoidRoughCfg)
    cfg.box_collider_bodies = HUMANOID_BOX_COLLIDERS  # fewer broadphase pairs on MuJoCo Warp, same walking
    return cfg


def humanoid_rough_play_cfg() -> HumanoidRoughCfg:
    """Play and evaluation: every robot on the hardest level (``as_rough_play``)."""
    return as_rough_play(humanoid_rough_cfg())


def commanded_velocity_w(command: torch.Tensor, heading_w: torch.Tensor) -> torch.Tensor:
    """(N, 2) commanded planar velocity in the world frame, m/s: ``command``'s (N, 3) (vx, vy) in
    the heading frame turned by ``heading_w`` (N,) rad (the yaw rate, column 2, is not used)."""
    return rotate_yaw(heading_w.float(), command[:, :2])


class HumanoidRoughEnv(TerrainGround, HumanoidWalkEnv):
    """Velocity tracking over the terrain curriculum; see the module docstring. g1-rough puts it
    before ``G1WalkEnv`` (``envs.g1_rough``): its hooks work on any ``HumanoidWalkEnv``."""

    cfg: HumanoidRoughCfg
    terrain_task = "humanoid-rough"

    def _setup(self) -> None:
        super()._setup()
        n, dev, cfg = self.num_envs, self.device, self.cfg
        self.curriculum = self._setup_terrain(cfg.curriculum)
        f32 = dict(dtype=torch.float32, device=dev)
        self._start_xy = torch.zeros(n, 2, **f32)
        self.distance_m = torch.zeros(n, **f32)
        """(N,) horizontal distance of each robot from where its episode started, m."""
        self.command_displacement_w = torch.zeros(n, 2, **f32)
        """(N, 2) where the commands would have carried each robot this episode: its commanded
        (vx, vy), turned from its heading frame into the world by its heading, integrated, m."""

    # -- RLEnv hooks ------------------------------------------------------------------------
    def _post_physics(self) -> None:
        super()._post_physics()
        xy = self.robot.data.root_pos_w[:, :2].float()
        self.distance_m = torch.linalg.vector_norm(xy - self._start_xy, dim=-1)
        self.command_displacement_w += commanded_velocity_w(self.commands.command, self.robot.data.heading_w) \
            * self.step_dt_s

    def _reset_idx(self, rows: torch.Tensor) -> None:
        # the curriculum reads how far the ended episodes got before anything is reset
        # against the displacement the commands asked for, not their path length: commands turn
        # (yaw rates, resampled headings) and reverse, so a robot tracking them perfectly ends on
        # average 2.1 m from its start after a 4.3 m path (start of training, 20,000 simulated
        # episodes) and a path-length rule moved 48 % of perfect trackers down, so the population
        # sank to the easiest tiles (session 12: mean level 1.96 -> 0.2 in 540 iterations)
        asked_m = torch.linalg.vector_norm(self.command_displacement_w, dim=-1)
        self.curriculum.update(rows, self.distance_m, asked_m, self._fell)
        super()._reset_idx(rows)
        xy = self._spawn_on_tiles(rows, self.curriculum.origins_w)
        put_rows(self._start_xy, slice(None), xy, rows)
        fill_rows(self.distance_m, rows, 0.0)
        fill_rows(self.command_displacement_w, rows, 0.0)

    def _step(self, actions):
        obs, rewards, dones, extras = super()._step(actions)
        if "episode" in extras:  # every stats window: the curriculum's progress, a device scalar
            extras["episode"]["Curriculum/terrain_level"] = self.curriculum.mean_level()
        return obs, rewards, dones, extras

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        terms = super()._policy_terms()
        if self.cfg.scan_in_actor:
            terms["height_scan"] = self._height_scan()
        return terms

    def _privileged_terms(self) -> dict[str, torch.Tensor]:
        terms = super()._privileged_terms()
        if not self.cfg.scan_in_actor:
            terms["height_scan"] = self._height_scan()
        terms["feet_height_over_ground"] = self._feet_height_over_ground_m()
        return terms

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        terms = super()._get_terminations()
        fell_height = self.base_height_over_ground_m() < self.cfg.min_base_height_m
        self._fell = fell_height | terms["tilt"]
        return {"base_height": fell_height, "tilt": terms["tilt"]}


def humanoid_rough_metrics(env: HumanoidRoughEnv) -> dict[str, torch.Tensor]:
    """The velocity errors (the criterion's), the level, and each robot's distance from where its
    episode started, m: reported, not judged. A walker can meet the pooled criterion while refusing
    a kind's terrain (session 24: on the hardest stepping stones and stairs down, robots that stayed
    on the start platform did not fall); the distance per tile kind shows it beside flat ground's."""
    lin_err, yaw_err = env.velocity_tracking_error()
    return {"abs_vel_error_m_s": lin_err, "abs_yaw_rate_error_rad_s": yaw_err,
            "terrain_level": env.curriculum.levels.float(), "distance_from_start_m": env.distance_m}


register(TaskSpec(
    name="humanoid-rough",
    env_cls=HumanoidRoughEnv,
    cfg_fn=humanoid_rough_cfg,
    play_cfg_fn=humanoid_rough_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="forward walking (0-1 m/s) over a terrain curriculum (slopes, rough, 0.15 m stairs, stones) with a "
                "height scan and transfer randomization",
    step_metrics=humanoid_rough_metrics,
    criteria=(WALKS_ROUGH,),
))

__all__ = ["HUMANOID_BOX_COLLIDERS", "WALKS_ROUGH", "HumanoidRoughCfg", "HumanoidRoughEnv", "RoughTerrainCfg", "as_rough", "as_rough_play", "humanoid_rough_cfg",
           "humanoid_rough_metrics", "humanoid_rough_play_cfg"]
