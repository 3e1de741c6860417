"""Humanoids resting on box tiles (``TerrainCfg.box_tiles``): each touching sole sphere has exactly
one terrain contact on the CPU engine (the hfield gave up to 3, one per prism), all with boxes, and
the feet's contact sensor counts them (it reads every geom of the terrain body, not the hfield's
alone)."""

from __future__ import annotations

import mujoco
import numpy as np
import torch

import ambulo.envs as envs

SMALL = {"terrain.num_levels": 2, "terrain.border_m": 2.0}


def test_resting_soles_get_one_contact_each_on_flat_and_stairs_tiles():
    # env i stands on column i % 3: flat, stairs_up (the pit's floor), stairs_down (the summit)
    env = envs.make("humanoid-footsteps-stairs", num_envs=3, seed=1, num_threads=1, play=True, engine="mujoco",
                    **SMALL)
    assert env.cfg.terrain.kinds == ("flat", "stairs_up", "stairs_down") and env.cfg.terrain.box_tiles
    env.reset()
    for _ in range(10):  # 0.2 s: the robots settle on their soles
        env.step(torch.zeros(env.num_envs, env.num_actions))
    model = env.engine.model
    terrain = model.geom_bodyid[model.geom("/World/terrain/geom").id]
    feet = [model.body(f"{env.cfg.robot.prim_path}/{foot}").id for foot in env.cfg.feet_bodies]
    sensed = env.feet.data.num_contacts.cpu().numpy()
    for world in range(env.num_envs):
        data = env.engine.get_data(world)
        con = data.contact
        on_terrain = model.geom_bodyid[con.geom1] == terrain
        other = np.where(on_terrain, con.geom2, con.geom1)
        ground = np.where(on_terrain, con.geom1, con.geom2)
        touching = on_terrain | (model.geom_bodyid[con.geom2] == terrain)
        spheres, count = np.unique(other[touching], return_counts=True)
        assert len(spheres) >= 4, f"world {world}: {len(spheres)} sole spheres touch the ground"
        assert (count == 1).all(), f"world {world}: contacts per touching sphere {count.tolist()}"
        assert all(model.geom(int(g)).name.endswith(tuple(f"sole_sphere{i}" for i in range(4))) for g in spheres)
        assert (model.geom_type[ground[touching]] == mujoco.mjtGeom.mjGEOM_BOX).all()
        per_foot = [int(np.isin(model.geom_bodyid[spheres], [foot]).sum()) for foot in feet]
        assert sensed[world].tolist() == per_foot  # the sensor counts the box contacts
