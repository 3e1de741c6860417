"""g1-rough: g1-walk over humanoid-rough's terrain curriculum, with its height scan and transfer randomization.

humanoid-rough's task (commands, rewards, the ``walks_rough`` criterion, the curriculum, falls against
the ground under the base, the scan in the actor and the feet's heights over the ground in the
critic, ``transfer_cfg_wide``) on g1-walk's robot (the G1 29-DoF URDF, URDF-derived drive gains,
rotor armature, only the feet touch the ground). Nothing of either is restated: the cfg is
``G1WalkCfg`` + ``RoughTerrainCfg`` filled by ``as_rough``, the env is ``HumanoidRoughEnv``'s hooks
before ``G1WalkEnv``'s. Needs the ``robots`` extra.

The G1's soles are its URDF's four contact spheres per foot (radius 5 mm, 3 cm below the ankle roll
link). On the terrain they grow to ``sole_sphere_radius_m`` (2 cm, the humanoid's sole spheres)
with their lowest points kept (``g1_sole_spheres``): MuJoCo Warp's sphere-heightfield contacts
misfire once a sphere's centre sinks below the surface, and its terrain contact depth limit
(``warp_hfield_contact_depth_m``, 2 cm) is right only for contacts shallower than the radius.
Standing on Warp's CPU device a 5 mm sphere sinks 4.6-5.2 mm, its whole radius, a 2 cm one
3.7-4.3 mm; under unit-noise actions without the depth limit 5 mm spheres sent worlds to 6e7 rad/s
(2 cm ones: 234 rad/s; with the limit both ~60, as the CPU engine).

Play and evaluation: every robot on the hardest level, no transfer randomization (``as_rough_play``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco

from ambulo.core import geom_collides

from .g1_walk import G1WalkCfg, G1WalkEnv, g1_walk_cfg
from .humanoid_rough import (
    WALKS_ROUGH,
    HumanoidRoughEnv,
    RoughTerrainCfg,
    as_rough,
    as_rough_play,
    humanoid_rough_metrics,
)
from .humanoid_walk import humanoid_walk_ppo
from .registry import TaskSpec, register

G1_SCAN_HEIGHT_M = 0.76
"""The G1's pelvis height in its default pose (g1-walk's start), m: the scan's zero."""


def g1_sole_spheres(spec: mujoco.MjSpec, feet: tuple[str, ...], radius_m: float,
                    timeconst_s: float | None = None) -> list[str]:
    """Grow the colliding spheres of the ``feet`` bodies (full spec names) to ``radius_m``, each
    centre raised along its body's z by the growth so its lowest point stays where it was (the
    sole's plane and its contact points on level ground keep), with contact time constant ``timeconst_s`` (``solref``
    (timeconst_s, 1); None: unchanged); return their names or, unnamed, their bodies'.
    ValueError for a foot with no colliding sphere. The spheres' mass is unchanged: the URDF's
    links carry explicit inertials."""
    grown = []
    for foot in feet:
        spheres = [g for g in spec.geoms if g.parent is not None and g.parent.name == foot
                   and g.type == mujoco.mjtGeom.mjGEOM_SPHERE and geom_collides(g)]
        if not spheres:
            raise ValueError(f"g1_sole_spheres: {foot!r} has no colliding sphere geom")
        for sphere in spheres:
            sphere.pos = sphere.pos + [0.0, 0.0, radius_m - float(sphere.size[0])]
            sphere.size = [radius_m, 0.0, 0.0]
            if timeconst_s is not None:
                sphere.solref = [timeconst_s, 1.0]
            grown.append(sphere.name or foot)
    return grown


@dataclass(kw_only=True)
class G1RoughCfg(G1WalkCfg, RoughTerrainCfg):
    """g1-rough settings: g1-walk's and the terrain's."""


def g1_rough_cfg() -> G1RoughCfg:
    """g1-walk's settings on the terrain grid (``as_rough``: wide transfer ranges, scan noise), the
    scan zeroed at the G1's pelvis height and the CoM offsets on its pelvis and torso."""
    cfg = as_rough(g1_walk_cfg(), G1RoughCfg)
    cfg.height_scan = dataclasses.replace(cfg.height_scan, height_offset_m=G1_SCAN_HEIGHT_M)
    cfg.transfer = dataclasses.replace(cfg.transfer, com_bodies=("pelvis", "torso_link"))
    return cfg


def g1_rough_play_cfg() -> G1RoughCfg:
    """Play and evaluation: every robot on the hardest level, no transfer (``as_rough_play``)."""
    return as_rough_play(g1_rough_cfg())


class G1RoughEnv(HumanoidRoughEnv, G1WalkEnv):
    """humanoid-rough's hooks on g1-walk's robot; see the module docstring."""

    cfg: G1RoughCfg
    terrain_task = "g1-rough"
    terrain_soles = staticmethod(g1_sole_spheres)

    def _design_scene(self, spec) -> None:
        super()._design_scene(spec)  # TerrainGround's: the terrain, the sole spheres, the feet's sensor
        self._g1_spec(spec)  # not reached through super(): TerrainGround builds the ground itself


register(TaskSpec(
    name="g1-rough",
    env_cls=G1RoughEnv,
    cfg_fn=g1_rough_cfg,
    play_cfg_fn=g1_rough_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="g1-walk over humanoid-rough's terrain curriculum (slopes, rough, 0.15 m stairs, stones) with a "
                "height scan and transfer randomization (robots extra)",
    step_metrics=humanoid_rough_metrics,
    criteria=(WALKS_ROUGH,),
))

__all__ = ["G1RoughCfg", "G1RoughEnv", "g1_rough_cfg", "g1_rough_play_cfg", "g1_sole_spheres"]
