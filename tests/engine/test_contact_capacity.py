"""engine.gpu.contact_capacity: the GPU engine's per-world contact and constraint-row buffers.

A heightfield model is sized from its geoms (MuJoCo Warp's heightfield collision writes at most 4
contacts per geom pair), not from MuJoCo Warp's default guess for heightfield scenes (192
contacts and 1,536 rows for the humanoid, where a world of humanoid-rough peaks at 16 contacts
and 85 rows): several solver kernels run over every row of ``njmax``. The sized buffers must
still hold what a rollout of falling robots on the terrain makes: the engine raises
``EngineOverflowError`` when a world overflows them."""

import mujoco
import numpy as np
import pytest
import torch

mjw = pytest.importorskip("mujoco_warp")

from ambulo.engine.gpu import contact_capacity


def _balls(ground: str) -> mujoco.MjModel:
    """Three free 5 cm spheres over ``ground`` (an hfield or a plane geom's XML)."""
    balls = "".join(f'<body pos="{x} 0 0.1"><freejoint/><geom type="sphere" size="0.05"/></body>' for x in (0, 1, 2))
    asset = '<asset><hfield name="h" nrow="20" ncol="20" size="5 5 0.2 0.1"/></asset>' if "hfield" in ground else ""
    return mujoco.MjModel.from_xml_string(f"<mujoco>{asset}<worldbody>{ground}{balls}</worldbody></mujoco>")


def test_a_heightfield_model_is_sized_per_geom_not_by_mujoco_warps_guess():
    model = _balls('<geom type="hfield" hfield="h"/>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    nconmax, njmax = contact_capacity(model, data, None, None)
    assert nconmax == 4 * 3  # 4 per collidable geom that moves: the three spheres (not the static hfield)
    assert njmax == 4 * nconmax  # pyramidal condim 3: 4 rows a contact; no limits, friction loss
    guess_con, guess_rows = mjw._src.io._default_nconmax(model, data), mjw._src.io._default_njmax(model, data)
    assert guess_con > 4 * nconmax and guess_rows > 4 * njmax  # what it replaces: 128 contacts, 768 rows


def test_static_geoms_add_no_capacity():
    """Terrain tiles as static boxes (``scenes.terrain.boxes``: hundreds of them) never touch each
    other, so they leave the buffers as the heightfield alone does."""
    boxes = "".join(f'<geom type="box" size="0.5 0.5 0.1" pos="{x} {y} -0.1"/>' for x in range(-4, 5) for y in (-1, 1))
    hfield = '<geom type="hfield" hfield="h"/>'
    tiles, plain = _balls(f"{hfield}<body>{boxes}</body>"), _balls(hfield)
    assert tiles.ngeom == plain.ngeom + 18
    assert contact_capacity(tiles, mujoco.MjData(tiles), None, None) == \
        contact_capacity(plain, mujoco.MjData(plain), None, None) == (12, 48)


def test_geoms_that_a_mocap_body_carries_count_as_moving():
    """A mocap body moves, and so do the jointless bodies it carries (their weld ancestor is the
    world): their geoms can touch the terrain, so they take contacts like the free spheres."""
    hfield = '<geom type="hfield" hfield="h"/>'
    carried = '<body mocap="true" pos="0 3 0.2"><geom type="box" size="0.1 0.1 0.1"/>' \
              '<body pos="0.3 0 0"><geom type="sphere" size="0.05"/></body></body>'
    model, plain = _balls(hfield + carried), _balls(hfield)
    assert contact_capacity(model, mujoco.MjData(model), None, None)[0] == \
        contact_capacity(plain, mujoco.MjData(plain), None, None)[0] + 4 * 2


def test_a_model_without_heightfield_keeps_mujoco_warps_floor():
    model = _balls('<geom type="plane" size="5 5 0.1"/>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    nconmax, njmax = contact_capacity(model, data, None, None)
    assert nconmax == mjw._src.io._default_nconmax(model, data) == 48  # above 4 per moving collidable geom (12)
    assert njmax == 4 * nconmax
    assert contact_capacity(model, data, 7, 30) == (7, 30)  # given sizes win


def test_humanoid_rough_falls_fit_the_sized_buffers_on_warp():
    """12 humanoids on the hardest tiles under random actions (most fall within the 1.8 s)
    with transfer randomization's joint friction rows: no world overflows (the engine would
    raise), and the fullest world uses under half of each buffer."""
    import ambulo.envs as envs

    env = envs.make("humanoid-rough", num_envs=12, device="cpu", engine="warp", seed=3, num_threads=1,
                    **{"curriculum.enabled": False, "curriculum.init_level": -1})
    engine, d = env.engine, env.engine.wp_data
    assert (engine.nconmax, engine.njmax) == (92, 389)  # 23 moving collidable geoms; MuJoCo Warp guessed 192, 1,536
    gen = torch.Generator().manual_seed(0)
    peak_contacts = peak_rows = falls = 0
    for _ in range(90):
        _, _, dones, _ = env.step(torch.rand(12, env.num_actions, generator=gen) * 2 - 1)
        falls += int(dones.sum())
        worlds = d.contact.worldid.numpy()[:int(d.nacon.numpy()[0])]
        peak_contacts = max(peak_contacts, int(np.bincount(worlds, minlength=12).max()))
        peak_rows = max(peak_rows, int(d.nefc.numpy().max()))
    engine.check_overflow()  # raises EngineOverflowError if any world overflowed
    assert falls >= 8
    assert 4 <= peak_contacts < engine.nconmax / 2 and 21 < peak_rows < engine.njmax / 2, (peak_contacts, peak_rows)


def test_humanoid_rough_steps_the_same_with_the_sized_buffers_as_with_mujoco_warps_guess():
    """The sizes change only how much is allocated: 4 humanoids on the hardest tiles under random
    actions follow bit-identical trajectories with 92/389 and with MuJoCo Warp's 192/1,536 (a
    buffer too small would drop contacts and part them)."""
    import ambulo.envs as envs

    qpos = {}
    for sizes in ((None, None), (192, 1536)):
        env = envs.make("humanoid-rough", num_envs=4, device="cpu", engine="warp", seed=0, num_threads=1,
                        **{"curriculum.enabled": False, "curriculum.init_level": -1,
                           "physics.max_contacts_per_world": sizes[0], "physics.max_constraints_per_world": sizes[1]})
        generator = torch.Generator().manual_seed(0)
        steps = []
        for _ in range(15):
            env.step(torch.rand(4, env.num_actions, generator=generator) * 2 - 1)
            steps.append(env.engine.field("qpos").clone())
        qpos[sizes] = torch.stack(steps)
        assert env.engine.njmax == (sizes[1] or 389)
    torch.testing.assert_close(qpos[(None, None)], qpos[(192, 1536)], atol=0.0, rtol=0.0)
