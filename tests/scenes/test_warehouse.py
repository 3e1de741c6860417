"""The warehouse bay (``ambulo.scenes.warehouse``) that the replicator's tutorial dataset renders:
the objects it scatters and labels, the room that bounds them, and the humanoid whose head camera
sees them, as they come out of the compiled model."""

from __future__ import annotations

import mujoco
import numpy as np

from ambulo.core.semantics import semantic_labels
from ambulo.robots import humanoid
from ambulo.scenes.warehouse import OBJECTS, ROOM_HALF_M, WALL_HEIGHT_M, build_warehouse_scene


def _forward() -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = build_warehouse_scene().compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def test_every_object_is_a_labelled_free_body_of_its_shape_parked_below_the_floor():
    model, data = _forward()
    labels = semantic_labels(model)
    assert sorted(labels.values()) == sorted(label for label, _, _ in OBJECTS)
    for i, (label, kind, size) in enumerate(OBJECTS):
        body = model.body(f"/World/objects/{label}_{i}").id
        assert labels[body] == label
        assert model.body_jntnum[body] == 1
        assert model.jnt_type[model.body_jntadr[body]] == mujoco.mjtJoint.mjJNT_FREE
        geom = model.body_geomadr[body]
        assert model.geom_type[geom] == getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}")
        np.testing.assert_allclose(model.geom_size[geom][: len(size)], size)
        assert data.xpos[body][2] < -5.0  # out of every view until a scatter places it


def test_the_walls_close_the_room_and_the_humanoid_stands_inside_with_its_head_camera_mount():
    model, data = _forward()
    inner = []
    for i in range(4):
        wall = model.geom(f"/World/wall_{i}").id
        centre, half = data.geom_xpos[wall], model.geom_size[wall]
        assert np.isclose(half[2], WALL_HEIGHT_M / 2) and np.isclose(centre[2], WALL_HEIGHT_M / 2)
        axis = int(np.argmax(np.abs(centre[:2])))  # the wall's normal
        inner.append(abs(centre[axis]) - half[axis])
        assert half[1 - axis] >= ROOM_HALF_M  # spans the room's side
    assert np.allclose(inner, ROOM_HALF_M - 0.1)
    pelvis = data.xpos[model.body(f"{humanoid.PRIM_PATH}/{humanoid.BASE_BODY}").id]
    mount = data.site_xpos[model.site(f"{humanoid.PRIM_PATH}/{humanoid.HEAD_CAMERA_SITE}").id]
    assert np.all(np.abs(pelvis[:2]) < ROOM_HALF_M - 0.1)
    assert 1.0 < mount[2] < WALL_HEIGHT_M
