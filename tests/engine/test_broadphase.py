"""PhysicsCfg.broadphase: MuJoCo Warp's candidate-pair search, chosen per scene.

Every broadphase must find the pairs that touch, so a scene of spheres and capsules dropped on
stairs of static boxes settles the same way under each (to float32 round-off: the contacts come in
another order). A bad name is one line naming the values."""

import mujoco
import numpy as np
import pytest

mjw = pytest.importorskip("mujoco_warp")

from ambulo.core.physics import PhysicsCfg
from ambulo.engine.gpu import GpuEngine
from ambulo.utils.checks import InvalidValueError


def _stairs_and_bodies() -> mujoco.MjModel:
    """40 static boxes of 5 heights on a floor box, and 6 free bodies (a sphere and a capsule each)
    dropped from 0.5 m at different places over them."""
    xml = ["<mujoco><option timestep='0.005'/><worldbody>"]
    for i in range(40):
        xml.append(f"<geom type='box' size='0.25 0.25 {0.05 + 0.02 * (i % 5)}' pos='{(i % 8) * 0.5} {(i // 8) * 0.5} 0'/>")
    xml.append("<geom type='box' size='5 5 0.5' pos='1.75 1 -0.5'/>")
    for k in range(6):
        xml.append(f"<body pos='{0.3 + 0.6 * k} {0.2 + 0.35 * k} 0.5'><freejoint/><geom type='sphere' size='0.06'/>"
                   "<geom type='capsule' fromto='0 0 0 0.15 0 0' size='0.03'/></body>")
    xml.append("</worldbody></mujoco>")
    return mujoco.MjModel.from_xml_string("".join(xml))


def _settled(broadphase: str) -> tuple[np.ndarray, int]:
    engine = GpuEngine(_stairs_and_bodies(), num_worlds=2, device="cpu", broadphase=broadphase)
    engine.step(200)  # 1 s: every body has landed on its step and come to rest
    return engine.field("qpos").numpy(), int(engine.wp_model.opt.broadphase)


def test_sweep_and_prune_settles_the_bodies_where_all_pairs_does():
    qpos_nxn, kind_nxn = _settled("nxn")
    qpos_sap, kind_sap = _settled("sap_tile")
    assert (kind_nxn, kind_sap) == (int(mjw.BroadphaseType.NXN), int(mjw.BroadphaseType.SAP_TILE))
    heights = qpos_nxn[:, 2::7]
    # each body rests on the box under it: its centre ~1-7 cm above that box's top, not on the floor (z <= 0)
    assert (heights > 0.05).all() and (heights < 0.25).all()
    np.testing.assert_allclose(qpos_sap, qpos_nxn, atol=1e-3)


def test_an_unknown_broadphase_is_one_line_naming_the_choices():
    with pytest.raises(InvalidValueError) as err:
        PhysicsCfg(broadphase="sap")
    message = str(err.value)
    assert "\n" not in message and "sap_tile" in message and "nxn" in message
