"""Both terrain tasks build their ground with ``envs.terrain_ground``: the feet touch the heightfield
through the sole spheres only (MuJoCo Warp's box-heightfield contacts push resting feet down), and
the feet's contact sensor reads the terrain."""

from __future__ import annotations

import mujoco
import pytest

import ambulo.envs as envs
from ambulo.scenes.terrain import TERRAIN_PRIM_PATH


@pytest.mark.parametrize("task", ["humanoid-rough", "humanoid-footsteps-stairs"])
def test_feet_touch_the_terrain_through_sole_spheres_only(task):
    env = envs.make(task, num_envs=1, seed=0, num_threads=1, play=True)
    model = env.unwrapped.sim.model if hasattr(env, "unwrapped") else env.sim.model
    feet = [f"{env.cfg.robot.prim_path}/{foot}" for foot in env.cfg.feet_bodies]
    for foot in feet:
        box = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, foot)
        assert box >= 0
        # the box no longer collides with the world (the spheres do, in the same body)
        assert model.geom_contype[box] == 0 and model.geom_conaffinity[box] == 0
        spheres = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{foot}/sole_sphere{i}") for i in range(4)]
        assert all(s >= 0 for s in spheres)
        assert all(model.geom_type[s] == mujoco.mjtGeom.mjGEOM_SPHERE for s in spheres)
        assert all(model.geom_bodyid[s] == model.geom_bodyid[box] for s in spheres)
    # the feet's contacts are read against the terrain body's geoms (its hfield and box tiles)
    assert env.feet.cfg.against_body == TERRAIN_PRIM_PATH and env.feet.cfg.against is None
