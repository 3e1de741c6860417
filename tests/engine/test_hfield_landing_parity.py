"""engine.mujoco_hfield at a landing: a 5 cm sphere sunk 1.6-1.8 cm into flat ground near a
heightfield vertex (a 5 m/s landing's depth after 2-3 steps of 2 ms).

Around a vertex the six prisms touching it give contacts at the sphere's lowest point (one depth:
the ground is flat); the two cells' other triangles, whose diagonal edges pass 3.54 cm from the
vertex, give a tilted contact each once the sphere's cross-section at the ground reaches them
(radius sqrt(r^2 - (r - depth)^2) = 3.67 cm at 1.6 cm deep). MuJoCo C keeps all; Warp keeps the
deepest and the one furthest from it, so one tilted contact, whose push rolls the sphere away.
The cells' triangulation is mirror-symmetric about the line x = y through a vertex: a sphere centred
on that line has its two tilted contacts equally far from the deepest, and the one kept is decided by
rounding (float64 here, float32 on Warp), which is why
``tests/scenes/test_terrain_box_colliders.py``'s hand, landing on a tile centre (a grid vertex),
rolls mirrored on the two engines. Off that line the far one is unique and the reduction keeps
Warp's: the same contacts, the same rolling (``benchmarks/results/cpu-2026-11-30-s20-hfield-landing.md``)."""

import mujoco
import numpy as np
import pytest

from ambulo.engine.mujoco_hfield import reduce_hfield_contacts
from hfield_contacts import mujoco_contacts, warp_contacts, warp_model_data

RADIUS_M = 0.05
LIMIT_M = 0.02
# 9 x 9 vertices 5 cm apart, flat at 0, the vertex (0, 0) in the middle
XML = f"""<mujoco><asset><hfield name="h" nrow="9" ncol="9" size="0.2 0.2 0.1 0.1"/></asset>
<worldbody><geom type="hfield" hfield="h"/><body pos="0 0 1"><freejoint/>
<geom type="sphere" size="{RADIUS_M}"/></body></worldbody></mujoco>"""
# sphere centres off the vertex and off the mirror line x = y, m
OFF_THE_MIRROR_M = np.array([[1e-3, 3e-4], [3e-4, 1e-3], [-1e-3, -3e-4], [-3e-4, -1e-3]])
ON_THE_MIRROR_M = np.array([[0.0, 0.0], [1e-3, 1e-3], [-5e-4, -5e-4]])


@pytest.fixture(autouse=True)
def mujoco_own_contacts():
    """The reduction is process-wide: every test starts and ends with MuJoCo's own."""
    reduce_hfield_contacts(None, enabled=False)
    yield
    reduce_hfield_contacts(None, enabled=False)


def sunk(offsets_m: np.ndarray, depth_m: float) -> tuple[mujoco.MjModel, np.ndarray]:
    """(model, (n, 7) poses): the sphere's centre at each xy offset from the vertex, its lowest point
    ``depth_m`` under the ground."""
    model = mujoco.MjModel.from_xml_string(XML)
    qpos = np.tile(model.qpos0, (len(offsets_m), 1))
    qpos[:, :2], qpos[:, 2] = offsets_m, RADIUS_M - depth_m
    return model, qpos


def tilted(own: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(deepest point, the two tilted contacts' rows, their distances from it) of MuJoCo's own set."""
    deepest = own[np.argmin(own[:, 0]), 1:4]
    pair = own[own[:, 6] < 0.99]
    assert len(own) == 8 and len(pair) == 2, own  # six at the lowest point, two on the diagonal edges
    return deepest, pair, np.linalg.norm(pair[:, 1:4] - deepest, axis=1)


@pytest.mark.parametrize("depth_m", [0.016, 0.018])
def test_off_the_mirror_line_the_landing_contacts_are_warps(depth_m):
    """Reduced: Warp's 2 contacts (count, depth, point, normal), the deepest and the tilted one
    further from it (by 0.8 mm here: no tie)."""
    model, qpos = sunk(OFF_THE_MIRROR_M, depth_m)
    own = mujoco_contacts(model, qpos, normals=True)
    warp = warp_contacts(model, qpos, LIMIT_M, normals=True)
    reduce_hfield_contacts(LIMIT_M)
    reduced = mujoco_contacts(model, qpos, normals=True)
    for o, r, w in zip(own, reduced, warp, strict=True):
        deepest, pair, far = tilted(o)
        assert abs(far[0] - far[1]) > 5e-4
        assert r.shape == w.shape == (2, 7), (r, w)
        np.testing.assert_allclose(r[:, 0], w[:, 0], atol=2e-5)
        np.testing.assert_allclose(r[:, 1:4], w[:, 1:4], atol=1e-4)
        np.testing.assert_allclose(r[:, 4:], w[:, 4:], atol=2e-3)
        np.testing.assert_allclose(r[0, 1:4], deepest)
        np.testing.assert_allclose(r[1], pair[np.argmax(far)])


def test_on_the_mirror_line_the_two_tilted_contacts_tie():
    """A sphere centred on x = y: its tilted contacts are mirror images about that line, (a, b) and
    (b, a), equally far from the deepest point (to 1e-12 m); reduced, one of them is kept (which one,
    rounding decides, on Warp as here)."""
    model, qpos = sunk(ON_THE_MIRROR_M, 0.016)
    own = mujoco_contacts(model, qpos, normals=True)
    reduce_hfield_contacts(LIMIT_M)
    reduced = mujoco_contacts(model, qpos, normals=True)
    for o, r in zip(own, reduced, strict=True):
        _, pair, far = tilted(o)
        np.testing.assert_allclose(pair[0, [1, 2]], pair[1, [2, 1]], atol=1e-12)  # (a, b) and (b, a)
        assert far[0] == pytest.approx(far[1], abs=1e-12)
        assert r[-1, 6] < 0.99 and any(np.allclose(r[-1], t) for t in pair)
        assert np.sum(r[:, 6] < 0.99) == 1


def test_off_the_mirror_line_a_landing_sphere_rolls_as_on_warp():
    """Thrown down at 5 m/s from 1 cm over the ground, then 0.2 s: it rolls away at ~0.09 m/s on
    both engines, the same way (MuJoCo C reduced vs Warp's CPU device, within 0.5 mm/s)."""
    model = mujoco.MjModel.from_xml_string(XML)
    n, steps = len(OFF_THE_MIRROR_M), 100
    qpos = np.tile(model.qpos0, (n, 1))
    qpos[:, :2], qpos[:, 2] = OFF_THE_MIRROR_M, RADIUS_M + 0.01
    qvel = np.zeros((n, model.nv))
    qvel[:, 2] = -5.0
    reduce_hfield_contacts(LIMIT_M)
    data, cpu = mujoco.MjData(model), []
    for q, v in zip(qpos, qvel, strict=True):
        data.qpos[:], data.qvel[:] = q, v
        for _ in range(steps):
            mujoco.mj_step(model, data)
        cpu.append(data.qvel[:2].copy())
    from ambulo.engine.warp_hfield import limit_hfield_contact_depth

    mjw, wp, m, d = warp_model_data(model, qpos, qvel)
    limit_hfield_contact_depth(LIMIT_M)
    try:
        with wp.ScopedDevice("cpu"):
            for _ in range(steps):
                mjw.step(m, d)
            warp = d.qvel.numpy()[:, :2]
    finally:
        limit_hfield_contact_depth(None)
    cpu = np.array(cpu)
    assert np.all(np.linalg.norm(cpu, axis=1) > 0.05), cpu  # rolling
    np.testing.assert_allclose(cpu, warp, atol=5e-4)
