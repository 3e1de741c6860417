"""humanoid-rough's default ``box_collider_bodies`` (the legs, ``HUMANOID_BOX_COLLIDERS``): the candidate
geom pairs of MuJoCo's filter, which MuJoCo Warp's nxn broadphase tests every step, go from every
colliding robot geom x every terrain geom to the legs' 12 x the boxes (the hfield keeps all 23), and
robots still stand on the box tiles (flat, the stairs pit's floor, the summit) on their soles."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.envs.humanoid_rough import HUMANOID_BOX_COLLIDERS
from ambulo.scenes.terrain import candidate_geom_pairs

SMALL = {"terrain.num_levels": 2, "terrain.kinds": ("flat", "stairs_up", "stairs_down"), "terrain.border_m": 2.0}
ROBOT_GEOMS, LEG_GEOMS = 23, 12  # colliding: 2 thighs, 2 shanks, 8 sole spheres are the legs'
EXPLICIT_PAIRS = 4  # the asset's foot-foot and foot-shank <pair>s


def make(**colliders):
    """humanoid-rough as its cfg builds it, or with ``box_collider_bodies=`` given."""
    return envs.make("humanoid-rough", num_envs=3, seed=1, num_threads=1, play=True, engine="mujoco",
                     **colliders, **SMALL)


def box_ids(model) -> np.ndarray:
    terrain = model.body("/World/terrain").id
    return np.flatnonzero((model.geom_bodyid == terrain) & (model.geom_type == mujoco.mjtGeom.mjGEOM_BOX))


@pytest.fixture(scope="module")
def legs_env():
    env = make()  # the task's default: the legs, HUMANOID_BOX_COLLIDERS
    yield env
    env.close()


def test_only_the_legs_pair_with_the_boxes(legs_env):
    counts = {}
    for name, env in (("all", None), ("legs", legs_env)):
        own = make(box_collider_bodies=None) if env is None else env
        model = own.engine.model
        boxes = box_ids(model)
        pairs = candidate_geom_pairs(model)
        with_box = np.isin(pairs, boxes).any(axis=1)
        counts[name] = (len(pairs), int(with_box.sum()), {model.geom(int(g)).name for g in pairs[with_box].ravel()
                                                          if g not in boxes},
                        {model.body(int(model.geom_bodyid[g])).name.rsplit("/", 1)[1]
                         for g in pairs[with_box].ravel() if g not in boxes})
        if env is None:
            own.close()
    nbox = len(box_ids(legs_env.engine.model))
    assert counts["all"][:2] == (ROBOT_GEOMS * (nbox + 1) + EXPLICIT_PAIRS, ROBOT_GEOMS * nbox)
    assert counts["legs"][:2] == (LEG_GEOMS * nbox + ROBOT_GEOMS + EXPLICIT_PAIRS, LEG_GEOMS * nbox)
    legs = counts["legs"][2]
    assert len(legs) == LEG_GEOMS and all(n.split("/")[3].split("_")[1] in ("thigh", "shank", "foot") for n in legs)
    assert counts["legs"][3] == set(HUMANOID_BOX_COLLIDERS)


def test_the_warp_model_tests_the_same_fewer_pairs(legs_env):
    mjw = pytest.importorskip("mujoco_warp")
    wp = pytest.importorskip("warp")
    model = legs_env.engine.model
    with wp.ScopedDevice("cpu"):
        warp_pairs = mjw.put_model(model).nxn_geom_pair_filtered.numpy()
    assert len(warp_pairs) == LEG_GEOMS * len(box_ids(model)) + ROBOT_GEOMS + EXPLICIT_PAIRS
    assert {tuple(p) for p in warp_pairs.tolist()} == {tuple(p) for p in candidate_geom_pairs(model).tolist()}


def test_robots_stand_on_the_box_tiles_on_their_soles(legs_env):
    env = legs_env
    env.reset()
    for _ in range(20):  # 0.4 s in the default pose
        _, _, dones, _ = env.step(torch.zeros(env.num_envs, env.num_actions))
        assert not dones.any()
    assert (env.base_height_over_ground_m() > 0.85).all()
    model, boxes = env.engine.model, box_ids(env.engine.model)
    for world in range(env.num_envs):  # env i on column i % 3: flat, the pit's floor, the summit
        con = env.engine.get_data(world).contact
        on_box = np.isin(con.geom1, boxes) | np.isin(con.geom2, boxes)
        other = np.where(np.isin(con.geom1, boxes), con.geom2, con.geom1)[on_box]
        assert len(set(other.tolist())) >= 4, f"world {world}: {len(set(other.tolist()))} geoms on boxes"
        assert all(model.geom(int(g)).name.rsplit("/", 1)[1].startswith("sole_sphere") for g in other)
