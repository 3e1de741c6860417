"""The terrain tasks on the CPU engine get MuJoCo Warp's heightfield contacts
(``TerrainGroundCfg.mujoco_hfield_contacts_as_warp``, ``engine.mujoco_hfield``): robots standing
in the default pose on hfield tiles touch them with at most 4 contacts a sole sphere, where
MuJoCo C's own contacts give a sphere up to one per prism it overlaps."""

import mujoco
import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.engine.mujoco_hfield import MAX_CONTACTS, reduce_hfield_contacts
from ambulo.envs.humanoid_rough import HumanoidRoughEnv

SMALL = {"terrain.num_levels": 3, "terrain.tile_size_m": 4.0, "terrain.platform_size_m": 1.0,
         "terrain.border_m": 1.0, "terrain.kinds": ("rough", "slope_up", "slope_down")}


@pytest.fixture(autouse=True)
def mujoco_own_contacts_after():
    yield
    reduce_hfield_contacts(None, enabled=False)  # process-wide: leave MuJoCo's own to later tests


def standing_sphere_contacts(**overrides) -> np.ndarray:
    """Contacts of each touching sole sphere with the hfield after 24 robots stood 0.5 s in the
    default pose, spawned off their platforms onto the tiles' hfield."""
    cfg = envs.make_cfg("humanoid-rough", num_envs=24, seed=0, num_threads=1, push_interval_s=None,
                        spawn_radius_m=1.5, **SMALL, **overrides)
    env = HumanoidRoughEnv(cfg)
    env.reset()
    hold = torch.zeros(env.num_envs, env.num_actions)
    for _ in range(25):
        env.step(hold)
    model = env.engine.model
    hfield = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_HFIELD)
    counts: dict[tuple[int, int], int] = {}
    for w in range(env.num_envs):
        data = env.engine.get_data(w)
        for c in data.contact[:data.ncon]:
            if hfield in (c.geom1, c.geom2):
                key = (w, int(c.geom2 if c.geom1 == hfield else c.geom1))
                counts[key] = counts.get(key, 0) + 1
    env.close()
    return np.array(list(counts.values()))


def test_standing_soles_get_at_most_warps_contacts_on_the_cpu_engine():
    reduced = standing_sphere_contacts()
    own = standing_sphere_contacts(mujoco_hfield_contacts_as_warp=False)
    assert reduced.size >= 40 and own.size >= 40  # the robots stand on the hfield
    assert own.max() > MAX_CONTACTS  # MuJoCo's own: a contact per overlapped prism
    assert reduced.max() <= MAX_CONTACTS
    assert reduced.mean() < own.mean()
