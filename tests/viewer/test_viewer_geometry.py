"""The shapes the page draws come from the compiled model: sizes, poses in the body frame,
colours (material rule), which geoms are visible, which bodies are static."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

pytest.importorskip("viser")
from ambulo.viewer.geometry import INFINITE_PLANE_HALF_M, geom_shapes, root_bodies, static_bodies, subtree

XML = """
<mujoco>
  <asset><material name="red" rgba="1 0 0 1"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <body name="box" pos="1 2 3">
      <freejoint/>
      <geom name="box" type="box" size="0.1 0.2 0.3" pos="0.5 0 0" rgba="0 1 0 1"/>
      <geom name="hidden" type="sphere" size="0.1" group="3"/>
      <body name="arm" pos="0 0 1">
        <joint type="hinge"/>
        <geom name="arm" type="capsule" size="0.05 0.2" euler="90 0 0" material="red"/>
      </body>
    </body>
    <body name="fixed" pos="0 0 1"><geom name="fixed" type="cylinder" size="0.1 0.4"/></body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(XML)


def shape(model, name):
    geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    return next(s for s in geom_shapes(model) if s.geom_id == geom)


def test_box_size_pose_and_colour_in_body_frame(model):
    box = shape(model, "box")
    lo, hi = box.vertices_b.min(axis=0), box.vertices_b.max(axis=0)
    np.testing.assert_allclose(hi - lo, [0.2, 0.4, 0.6], atol=1e-6)  # 2 x size
    np.testing.assert_allclose((hi + lo) / 2, [0.5, 0, 0], atol=1e-6)  # geom pos in the body frame
    assert box.rgba == (0.0, 1.0, 0.0, 1.0)


def test_capsule_turned_by_its_geom_quat_and_coloured_by_its_material(model):
    arm = shape(model, "arm")
    extent = arm.vertices_b.max(axis=0) - arm.vertices_b.min(axis=0)
    # euler 90 about x lays the capsule's z axis along -y: length 2 * (0.2 + 0.05) along y
    np.testing.assert_allclose(extent, [0.1, 0.5, 0.1], atol=2e-3)
    assert arm.rgba == (1.0, 0.0, 0.0, 1.0)


def test_infinite_plane_is_drawn_finite_and_group_3_is_hidden(model):
    floor = shape(model, "floor")
    assert floor.is_plane
    np.testing.assert_allclose(np.abs(floor.vertices_b[:, :2]).max(), INFINITE_PLANE_HALF_M)
    hidden = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "hidden")
    assert hidden not in {s.geom_id for s in geom_shapes(model)}


def test_static_bodies_roots_and_subtrees(model):
    ids = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in ("box", "arm", "fixed")}
    static = static_bodies(model)
    assert static[0] and static[ids["fixed"]] and not static[ids["box"]] and not static[ids["arm"]]
    assert root_bodies(model) == [ids["box"]]
    assert subtree(model, ids["box"]) == [ids["box"], ids["arm"]]
