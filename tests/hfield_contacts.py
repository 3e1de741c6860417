"""Contacts of free spheres posed on a heightfield, read from MuJoCo C and from MuJoCo Warp on its
CPU device: what the heightfield contact tests compare (``tests/engine/test_mujoco_hfield.py``,
``test_hfield_landing_parity.py``). Each returns, per pose, its contacts as sorted rows of
(dist, x, y, z) and, with ``normals``, the contact normal's (nx, ny, nz)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest


def mujoco_contacts(model, qpos, normals: bool = False) -> list[np.ndarray]:
    """Per (nv-free) pose of ``qpos`` (n, nq), MuJoCo C's contacts after ``mj_forward``."""
    data, out, width = mujoco.MjData(model), [], 7 if normals else 4
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        rows = [(c.dist, *c.pos, *(c.frame[:3] if normals else ())) for c in data.contact[:data.ncon]]
        out.append(np.array(sorted(rows)).reshape(-1, width))
    return out


def warp_model_data(model, qpos, qvel=None):
    """(mujoco_warp, warp, model, data): one Warp world a pose on Warp's CPU device."""
    mjw = pytest.importorskip("mujoco_warp")
    wp = pytest.importorskip("warp")
    wp.init()
    with wp.ScopedDevice("cpu"):
        m = mjw.put_model(model)
        d = mjw.put_data(model, mujoco.MjData(model), nworld=len(qpos), nconmax=8 * len(qpos), njmax=32 * len(qpos))
        d.qpos = wp.array(qpos.astype(np.float32), dtype=float)
        if qvel is not None:
            d.qvel = wp.array(qvel.astype(np.float32), dtype=float)
    return mjw, wp, m, d


def warp_contacts(model, qpos, limit_m: float, normals: bool = False) -> list[np.ndarray]:
    """The same from MuJoCo Warp's forward pass, under the engines' depth limit ``limit_m`` (switched
    on for the call only: it is process-wide)."""
    from ambulo.engine.warp_hfield import limit_hfield_contact_depth

    mjw, wp, m, d = warp_model_data(model, qpos)
    limit_hfield_contact_depth(limit_m)
    try:
        with wp.ScopedDevice("cpu"):
            mjw.forward(m, d)
            count = int(d.nacon.numpy()[0])
            world, dist = d.contact.worldid.numpy()[:count], d.contact.dist.numpy()[:count]
            columns = [d.contact.pos.numpy()[:count]] + ([d.contact.frame.numpy()[:count, 0]] if normals else [])
    finally:
        limit_hfield_contact_depth(None)
    rows = np.concatenate([dist[:, None], *columns], axis=1)
    return [np.array(sorted(map(tuple, rows[world == w]))).reshape(-1, rows.shape[1]) for w in range(len(qpos))]
