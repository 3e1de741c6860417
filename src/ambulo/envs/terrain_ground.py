"""The terrain as a task's ground: one heightfield, the feet touching it through sphere soles, and
the feet's contact sensor against it. humanoid-rough and humanoid-footsteps-stairs build their
scenes with it, so both get the same feet on the same terrain (MuJoCo Warp's box-heightfield
contacts push resting feet down: ``scenes.terrain.sphere_soles``)."""

from __future__ import annotations

from ambulo.scenes.terrain import add_terrain, generate, sphere_soles
from ambulo.sensors import ContactSensor, ContactSensorCfg


def add_terrain_ground(env, spec, task: str) -> None:
    """Add ``env.cfg.terrain`` to ``spec`` as the ground (``env.terrain``: the generated grid) and the
    feet's contact sensor against it (``env.feet``). Reads the cfg's ``terrain``,
    ``terrain_friction``, ``robot.prim_path``, ``feet_bodies``, ``sole_sphere_radius_m`` (None: the
    foot boxes touch the terrain), ``sole_contact_timeconst_s`` and, on MuJoCo Warp,
    ``warp_hfield_contact_depth_m`` (``engine.warp_hfield``); ``task`` names the task in the
    error for a cfg that also asks for a ground plane."""
    cfg = env.cfg
    if cfg.ground is not None:
        raise ValueError(f"{task}'s ground is its terrain; set ground=None")
    env.terrain = generate(cfg.terrain)
    geom = add_terrain(spec, env.terrain, friction=cfg.terrain_friction)
    feet = tuple(f"{cfg.robot.prim_path}/{foot}" for foot in cfg.feet_bodies)
    if cfg.sole_sphere_radius_m is not None:  # the humanoid's foot geoms are named as its foot bodies
        sphere_soles(spec, feet, cfg.sole_sphere_radius_m, timeconst_s=cfg.sole_contact_timeconst_s)
    if _on_warp(cfg):  # process-wide, and set before the engine first steps (graph capture)
        from ambulo.engine.warp_hfield import limit_hfield_contact_depth

        limit_hfield_contact_depth(cfg.warp_hfield_contact_depth_m)
    env.feet = env.sim.add(ContactSensor(ContactSensorCfg(
        name="feet_contact", prim_paths=feet, include_subtree=True, against=geom.name)))


def _on_warp(cfg) -> bool:
    """Whether the env's engine is MuJoCo Warp (``EnvCfg.engine``: "auto" picks it on CUDA)."""
    return cfg.engine == "warp" or (cfg.engine == "auto" and str(cfg.device).startswith("cuda"))


__all__ = ["add_terrain_ground"]
