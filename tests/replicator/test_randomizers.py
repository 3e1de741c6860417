"""Randomizers: scatter never overlaps (checked independently), logs are JSON and replayable; PNG encoder."""

import dataclasses
import io
import json

import mujoco
import numpy as np
import pytest
from PIL import Image

from ambulo import replicator as rep
from ambulo.replicator.io import depth_to_mm_u16, encode_png
from ambulo.utils.rotations import rot_about_axes


def penetrations(model, qpos, floor_geom):
    """(geom1, geom2, depth) of penetrating contacts not involving the floor, from a fresh MjData."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_fwdPosition(model, data)
    out = []
    for c in data.contact[: data.ncon] if data.ncon else []:
        if c.dist < -1e-4 and floor_geom not in c.geom:
            out.append((int(c.geom[0]), int(c.geom[1]), float(c.dist)))
    return out


@pytest.fixture(scope="module")
def producer():
    p = rep.FrameProducer(rep.example_config(64, 48))
    yield p
    p.close()


def test_scatter_places_objects_on_the_floor_in_the_region_without_overlap(producer):
    model = producer.model
    floor = model.geom("/World/floor/geom").id
    objects = [b for b in range(model.nbody) if model.body(b).name.startswith("/World/objects/")]
    for frame in range(6):
        log = producer.randomize(seed=11, index=frame)
        qpos = producer.engine.qpos[0].numpy()
        assert penetrations(model, qpos, floor) == []
        placed = log["objects"]["pose_xy_yaw"]
        assert len(placed) + len(log["objects"]["hidden"]) == len(objects)
        data = producer.engine.get_data(0)
        for key, (x, y, _yaw) in placed.items():
            body = objects[int(key)]
            assert 0.3 <= x <= 3.5 and -1.6 <= y <= 1.6
            assert np.allclose(data.xpos[body][:2], [x, y])
            # resting: the lowest point of the body's geoms is on the floor
            geom = model.body_geomadr[body]
            aabb = model.geom_aabb[geom].reshape(2, 3)
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * aabb[1] + aabb[0]
            lowest = (corners @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom])[:, 2].min()
            assert lowest == pytest.approx(0.0, abs=1e-9)
        active = log["distractors"]["active"]
        assert 2 <= len(active) + len(log["distractors"]["hidden"]) <= 6


def test_crowded_region_hides_objects_instead_of_overlapping():
    config = rep.example_config(64, 48)
    tight = ((0.5, -0.3), (1.1, 0.3))
    randomizers = [dataclasses.replace(r, region=tight) if isinstance(r, rep.Scatter2D) else r
                   for r in config.randomizers]
    p = rep.FrameProducer(dataclasses.replace(config, randomizers=randomizers))
    try:
        log = p.randomize(seed=0, index=0)
        assert log["objects"]["hidden"], "ten objects cannot fit in 0.6 m x 0.6 m"
        model = p.model
        assert penetrations(model, p.engine.qpos[0].numpy(), model.geom("/World/floor/geom").id) == []
        objects = [b for b in range(model.nbody) if model.body(b).name.startswith("/World/objects/")]
        for i in log["objects"]["hidden"]:
            assert p.engine.get_data(0).xpos[objects[i]][2] < -5  # parked under the floor
    finally:
        p.close()


def test_logs_are_json_and_applying_them_sets_the_model(producer):
    log = producer.randomize(seed=3, index=7)
    assert json.loads(json.dumps(log)) == log
    engine = producer.engine
    light = log["lights"]["lights"][0]
    sun = producer.model.light("/World/sun").id
    assert np.allclose(engine.model_field("light_diffuse")[0, sun].numpy(), light["diffuse"])
    rgba = log["object_colors"]["rgba"][0]
    first = producer.model.body("/World/objects/box_0").id
    geom = producer.model.body_geomadr[first]
    assert np.allclose(engine.model_field("geom_rgba")[0, geom].numpy(), rgba)
    jitter = log["camera_jitter"]
    assert len(jitter["position_m"]) == 3 and max(abs(a) for a in jitter["rotation_deg"]) <= 4.0


def test_png_encoder_round_trips_through_pillow():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (7, 5, 3), dtype=np.uint8)
    grey16 = rng.integers(0, 65536, (4, 9), dtype=np.uint16)
    for image in (rgb, grey16):
        decoded = np.asarray(Image.open(io.BytesIO(encode_png(image))))
        assert decoded.dtype.itemsize == image.dtype.itemsize and np.array_equal(decoded, image)
    depth = np.array([[0.0015, 1.2344, np.inf, 70.0]])
    assert depth_to_mm_u16(depth).tolist() == [[2, 1234, 0, 0]]


def test_a_camera_jitter_turns_the_offset_by_its_rotation_vector_and_moves_it_by_its_position(producer):
    """The pose CameraJitter sets is R(rotation vector) @ R_offset (Rodrigues, ``rot_about_axes``) at
    offset + position, for zero, small and the largest rotations, whatever the frame before set."""
    jitter = next(r for r in producer.config.randomizers if isinstance(r, rep.CameraJitter))
    camera = producer.ctx.cameras[jitter.camera]
    base_pos, base_rot = (np.asarray(v, np.float64) for v in camera._default_offset)
    for degrees in ([0.0, 0.0, 0.0], [4.0, -3.0, 2.0], [-4.0, -4.0, -4.0], [1e-9, 0.0, 0.0], [0.0, 0.0, 3.9]):
        params = {"position_m": [0.01, -0.02, 0.005], "rotation_deg": degrees}
        jitter.apply(params, producer.ctx)
        np.testing.assert_allclose(camera._offset_rot_gl[0], rot_about_axes(np.radians(degrees)) @ base_rot,
                                   rtol=0, atol=1e-12, err_msg=str(degrees))
        np.testing.assert_allclose(camera._offset_pos[0], base_pos + params["position_m"], rtol=0, atol=1e-15)
