"""The terrain as a task's ground: one heightfield and the box tiles' boxes
(``scenes.terrain.boxes``), the feet touching them through sphere soles, and the feet's contact
sensor against them. humanoid-rough and humanoid-footsteps-stairs build their scenes with it, so
both get the same feet on the same terrain (MuJoCo Warp's box-heightfield contacts push resting
feet down: ``scenes.terrain.sphere_soles``)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import torch

from ambulo.core.rows import take_rows
from ambulo.scenes.terrain import (
    HeightScan,
    HeightScanCfg,
    TerrainCfg,
    TerrainCurriculum,
    TerrainCurriculumCfg,
    TerrainHeights,
    add_terrain,
    check_kind_weights,
    generate,
    restrict_box_colliders,
    sphere_soles,
)
from ambulo.sensors import ContactSensor, ContactSensorCfg
from ambulo.utils.validate import Checked


@dataclass(kw_only=True)
class TerrainGroundCfg(Checked):
    """What a task on the terrain adds to its cfg (a dataclass mixin listed after the task's own cfg:
    humanoid-rough, g1-rough and humanoid-footsteps-stairs); ``add_terrain_ground`` reads it."""

    terrain: TerrainCfg = field(default_factory=TerrainCfg)
    height_scan: HeightScanCfg = field(default_factory=lambda: HeightScanCfg(height_offset_m=0.9))
    """``height_offset_m``: the robot's nominal base height (the humanoid's 0.9 m)."""
    spawn_radius_m: float = 0.3
    """Robots start uniformly within +-this of their tile's centre along x and y, m."""
    terrain_friction: float = 1.0
    """Sliding friction of the terrain geom before randomization."""
    sole_sphere_radius_m: float | None = 0.02
    """The feet touch the terrain through four spheres of this radius at their soles' corners
    (``scenes.terrain.sphere_soles``: MuJoCo Warp's box-heightfield contacts push resting feet
    down); None: through their boxes (right on the CPU engine only)."""
    sole_contact_timeconst_s: float | None = 0.01
    """The sole spheres' contact time constant, s (``solref``; None: the foot box's 0.02): stiffer
    soles sink less under stomping exploration, where Warp's sphere-hfield contacts degrade."""
    warp_hfield_contact_depth_m: float | None = 0.02
    """On MuJoCo Warp, terrain contacts deeper than this are limited to it, pointing up
    (``engine.warp_hfield``): once a sole sphere sinks past its radius Warp's contacts are
    metres deep and sideways, which made robots run away (hundreds of rad/s) and fall. The
    sphere radius: shallower contacts are right. None: Warp's own contacts."""
    box_collider_bodies: tuple[str, ...] | None = None
    """Robot bodies (names under ``robot.prim_path``) whose colliding geoms touch the terrain's static
    boxes (``TerrainCfg.box_tiles``); every other geom passes through the boxes, still stands on the
    hfield, and self-collisions are unchanged (``scenes.terrain.restrict_box_colliders``). Cuts MuJoCo
    Warp's nxn broadphase, which tests every colliding geom against every box in every world each
    physics step (humanoid-rough: 23 geoms x 489 terrain geoms, 11,251 candidate pairs a world with the
    asset's 4 ``<pair>``s; ``HUMANOID_BOX_COLLIDERS``, the legs: 12 x 488 boxes + 23 x the hfield,
    5,883). None: every geom touches the boxes."""
    mujoco_hfield_contacts_as_warp: bool = True
    """On the CPU engine (MuJoCo C), reduce heightfield contacts as MuJoCo Warp does: at most 4 a
    geom, Warp's subset, and ``warp_hfield_contact_depth_m`` deep at most (``engine.mujoco_hfield``).
    MuJoCo C keeps one contact per prism a sole sphere overlaps, many tilted off the ground: a
    policy trained on Warp fell in 0.17-0.38 of its episodes on MuJoCo C's hfield tiles against
    0.016 on Warp, and in 0.008-0.016 with this. False: MuJoCo C's own contacts."""

    def __post_init__(self):
        super().__post_init__()
        # each tiles setting of the task (humanoid-rough's ``curriculum``, footsteps-stairs' ``levels``)
        # against the terrain here, not only where the tiles are built: `--env-cfg curriculum.kind_weights=1,2`
        # then fails in one line as it is parsed, before a run folder exists
        for f in fields(self):
            tiles = getattr(self, f.name)
            if isinstance(tiles, TerrainCurriculumCfg):
                check_kind_weights(tiles.kind_weights, self.terrain.kinds, f"{f.name}.kind_weights")


def add_terrain_ground(env, spec, task: str, soles=sphere_soles) -> None:
    """Add ``env.cfg.terrain`` to ``spec`` as the ground (``env.terrain``: the generated grid) and the
    feet's contact sensor against it (``env.feet``). Reads the cfg's ``terrain``,
    ``terrain_friction``, ``robot.prim_path``, ``feet_bodies``, ``sole_sphere_radius_m`` (None: the
    feet touch the terrain through their own geoms), ``sole_contact_timeconst_s``, ``box_collider_bodies`` and, on MuJoCo
    Warp, ``warp_hfield_contact_depth_m`` (``engine.warp_hfield``); ``task`` names the task in the
    error for a cfg that also asks for a ground plane. ``soles(spec, feet, radius_m, timeconst_s)``
    gives the feet (full body names) their sole spheres: ``sphere_soles`` for box feet named as
    their bodies (the humanoid's)."""
    cfg = env.cfg
    if cfg.ground is not None:
        raise ValueError(f"{task}'s ground is its terrain; set ground=None")
    env.terrain = generate(cfg.terrain)
    geom = add_terrain(spec, env.terrain, friction=cfg.terrain_friction)
    feet = tuple(f"{cfg.robot.prim_path}/{foot}" for foot in cfg.feet_bodies)
    if cfg.sole_sphere_radius_m is not None:
        soles(spec, feet, cfg.sole_sphere_radius_m, timeconst_s=cfg.sole_contact_timeconst_s)
    if cfg.box_collider_bodies is not None:  # after the soles: their spheres are the feet's colliders
        restrict_box_colliders(spec, geom.parent.name,
                               tuple(f"{cfg.robot.prim_path}/{body}" for body in cfg.box_collider_bodies))
    if _on_warp(cfg):  # process-wide, and set before the engine first steps (graph capture)
        from ambulo.engine.warp_hfield import limit_hfield_contact_depth

        limit_hfield_contact_depth(cfg.warp_hfield_contact_depth_m)
    else:  # process-wide too: MuJoCo's table of collision functions
        from ambulo.engine.mujoco_hfield import reduce_hfield_contacts

        reduce_hfield_contacts(cfg.warp_hfield_contact_depth_m, enabled=cfg.mujoco_hfield_contacts_as_warp)
    # every geom of the terrain's body: its hfield and, with ``TerrainCfg.box_tiles``, its boxes
    env.feet = env.sim.add(ContactSensor(ContactSensorCfg(
        name="feet_contact", prim_paths=feet, include_subtree=True, against_body=geom.parent.name)))


def _on_warp(cfg) -> bool:
    """Whether the env's engine is MuJoCo Warp (``EnvCfg.engine``: "auto" picks it on CUDA)."""
    return cfg.engine == "warp" or (cfg.engine == "auto" and str(cfg.device).startswith("cuda"))


class TerrainGround:
    """What a humanoid task on the terrain adds to its base env (a mixin, listed first): the scene
    (``add_terrain_ground``), the heights, height scan and tiles (``_setup_terrain``), spawning on a
    tile's centre platform, heights over the ground, and the scan and feet-height terms. The cfg has
    ``terrain``, ``height_scan``, ``spawn_radius_m`` and what ``add_terrain_ground`` reads."""

    terrain_task = "this task"
    """The task's name, for errors."""
    terrain_soles = staticmethod(sphere_soles)
    """How the feet get their sole spheres (``add_terrain_ground``'s ``soles``)."""

    def _design_scene(self, spec) -> None:
        add_terrain_ground(self, spec, self.terrain_task, soles=self.terrain_soles)

    def _setup_terrain(self, tiles_cfg) -> TerrainCurriculum:
        """The heights on the device, the height scanner and the robot's initial root height; returns
        the tiles (``TerrainCurriculum`` of ``tiles_cfg``). Call after the base env's setup."""
        self.heights = TerrainHeights(self.terrain, self.device)
        self.scanner = HeightScan(self.cfg.height_scan, self.heights)
        self._default_root_z = self.robot.data.root_pos_w[:, 2].float().clone()  # the initial state's
        self._tiles = TerrainCurriculum(tiles_cfg, self.terrain, self.num_envs, self.generator, self.device)
        # each env's kind by name (fixed: an env keeps its column), for terrain_levels_by_kind
        columns = tuple(self.terrain.cfg.kinds)
        self._kind_names = tuple(dict.fromkeys(columns))
        name_of_column = torch.tensor([self._kind_names.index(kind) for kind in columns], device=self.device)
        self._kind_name_of_env = name_of_column[self._tiles.kinds]
        return self._tiles

    def mean_terrain_level(self) -> torch.Tensor | None:
        """() float32 the robots' mean terrain level, a device scalar, when their tiles are a
        curriculum (``TerrainCurriculumCfg.enabled``: robots move between levels as their episodes
        end: humanoid-rough, g1-rough); None, for the env's whole life, when each robot keeps its
        level (humanoid-footsteps-stairs). Training writes it to ``metrics.csv`` once an iteration
        (``rl.progress.terrain_level_reader``); reading it to the host is a sync, so no more often."""
        return self._tiles.mean_level() if self._tiles.cfg.enabled else None

    def terrain_levels_by_kind(self) -> tuple[tuple[str, ...], torch.Tensor] | None:
        """(the kinds' names, each once; (K,) float32 the mean level of the robots on each kind, nan
        for a kind without robots), on the device, when the tiles are a curriculum (None otherwise,
        as ``mean_terrain_level``). A kind named twice in ``TerrainCfg.kinds`` pools its columns.
        Training writes it beside the mean (``metrics.csv``'s ``terrain_level_<kind>``): where
        the curriculum holds the robots of each kind, e.g. stepping stones far below the others."""
        if not self._tiles.cfg.enabled:
            return None
        return self._kind_names, self._tiles.mean_level_by_group(self._kind_name_of_env, len(self._kind_names))

    def tile_kinds(self) -> tuple[tuple[str, ...], torch.Tensor]:
        """(the terrain's kind names, in column order; (N,) int64 the column of each env's tile,
        an index into the names). An evaluation reports each kind's episodes on its own
        (``rl.eval_kinds``). Read from the tiles at each call: an env's column is fixed, but the
        tensor is the tiles' own."""
        return tuple(self.terrain.cfg.kinds), self._tiles.kinds

    def ground_height_m(self, xy_w: torch.Tensor) -> torch.Tensor:
        """Terrain heights (m) under (..., 2) world points."""
        return self.heights.height_at(xy_w)

    def base_height_over_ground_m(self) -> torch.Tensor:
        """(N,) base height over the terrain under it, m."""
        root = self.robot.data.root_pos_w
        return root[:, 2].float() - self.heights.height_at(root[:, :2])

    def _spawn_on_tiles(self, rows, origins_w: torch.Tensor) -> torch.Tensor:
        """Put the robots of ``rows`` uniformly within ``spawn_radius_m`` of their tiles' origins
        (``origins_w`` (N, 3)), at their initial height over the ground there; returns their (n, 2) xy."""
        n, r = self._num_rows(rows), self.cfg.spawn_radius_m
        xy = take_rows(origins_w[:, :2], rows) + self._uniform((n, 2), -r, r)
        z = self.heights.height_at(xy) + take_rows(self._default_root_z, rows)
        self.robot.write_root_pose(pos_w=torch.cat([xy, z[:, None]], dim=-1).to(self.engine.dtype), env_ids=rows)
        return xy

    def _height_scan(self) -> torch.Tensor:
        data = self.robot.data
        return self.scanner.scan(data.root_pos_w, data.heading_w)

    def _feet_height_over_ground_m(self) -> torch.Tensor:
        """(N, feet) each foot's height over the ground under it, m (a privileged term)."""
        feet_w = self.robot.data.body_pos_w[:, self.feet_body_ids]
        return feet_w[..., 2].float() - self.heights.height_at(feet_w[..., :2])


__all__ = ["TerrainGround", "add_terrain_ground"]
