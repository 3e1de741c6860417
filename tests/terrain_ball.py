"""A free sphere over a terrain grid: the probe the heightfield contact tests drop on the terrain."""

from __future__ import annotations

import mujoco


def ball_over_terrain(grid, radius_m: float, mass_kg: float = 0.2) -> mujoco.MjModel:
    """The model of ``grid`` (``scenes.terrain.generate``'s) with one free sphere of ``radius_m``
    (qpos: the terrain has none, so the sphere's 7 values are the whole qpos)."""
    from ambulo.scenes.terrain import add_terrain

    spec = mujoco.MjSpec()
    add_terrain(spec, grid)
    body = spec.worldbody.add_body(name="ball")
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius_m, 0, 0], mass=mass_kg)
    return spec.compile()
