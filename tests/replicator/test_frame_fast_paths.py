"""This round's per-frame shortcuts give exactly what the steps they replaced gave.

The render state from the position stages alone, instance and semantic maps straight from the id
pass, big-endian uint16 images straight to PNG: each is checked against the computation it replaced,
on the example scene and on numbers chosen to hit the edges (absent ids, more than 256 geoms).
"""

import dataclasses

import mujoco
import numpy as np
import pytest

from ambulo import replicator as rep
from ambulo.replicator.io import depth_to_mm_u16, encode_png
from ambulo.sensors import annotators as ann


@pytest.fixture(name="producer", scope="module")
def small_producer():
    """The example scene at 64x48, with the semantic image the default annotators leave out."""
    config = rep.example_config(64, 48)
    camera = dataclasses.replace(config.camera, annotators=(*config.camera.annotators, "semantic_segmentation"))
    producer = rep.FrameProducer(dataclasses.replace(config, camera=camera))
    yield producer
    producer.close()


def test_the_render_state_is_mj_forwards_for_what_a_picture_shows(producer):
    producer.randomize(3, 17)
    camera, engine = producer.camera, producer.engine
    model = engine.get_model(0)
    data = camera._render_state(0, model)
    full = mujoco.MjData(model)
    engine.batch.get_data(0, full)
    mujoco.mj_forward(model, full)
    for name in ("xpos", "xmat", "xquat", "geom_xpos", "geom_xmat", "site_xpos", "site_xmat", "cam_xpos",
                 "cam_xmat", "light_xpos", "light_xdir", "subtree_com", "ten_length", "wrap_xpos"):
        np.testing.assert_array_equal(getattr(data, name), getattr(full, name), err_msg=name)
    assert np.ptp(data.geom_xpos[:, 0]) > 0  # a scene with things in it, not zeros equal to zeros


def test_instance_and_semantic_maps_from_the_id_pass_are_the_lookups_of_its_geom_ids(producer):
    table = producer.table
    seen = set()
    for index in range(4):
        producer.randomize(5, index)
        capture = producer.capture()
        assert "geom_ids" not in capture  # a dataset frame reads no geom id map: it is not looked up
        renderer = producer.camera.renderer  # the same pass again, with its geom ids
        renderer.queue_ids()
        geom_ids, _ = renderer.read_ids(False)
        instances = capture["instance_segmentation"]
        np.testing.assert_array_equal(instances, ann.instance_map(geom_ids, table))
        np.testing.assert_array_equal(capture["semantic_segmentation"], table.semantic_ids[instances])
        assert instances.dtype == np.int32 and capture["semantic_segmentation"].dtype == np.int32
        seen |= set(np.unique(instances).tolist())
    assert len(seen) > 2  # background and several objects were in view


def test_the_id_pass_maps_any_per_geom_table_with_more_than_256_geoms_too(producer):
    renderer, table = producer.camera.renderer, producer.table
    producer.randomize(5, 1)
    capture = producer.capture()
    renderer.queue_ids()
    short_geom_ids, _ = renderer.read_ids(False)
    renderer.queue_ids()
    # a lookup table as long as a scene of > 256 geoms: the id is decoded from all three channels
    renderer._lut = np.concatenate([renderer._lut, np.full(300, -1, np.int32)])
    geom_ids, _, (instances,) = renderer.read_ids(False, per_geom=(table.geom_instance,), geom_ids=False)
    np.testing.assert_array_equal(geom_ids, short_geom_ids)  # needed for the tables there: kept
    np.testing.assert_array_equal(instances, capture["instance_segmentation"])


def test_big_endian_uint16_images_give_the_same_png_and_depth_values():
    rng = np.random.default_rng(2)
    image = rng.integers(0, 65536, (23, 31)).astype(np.uint16)
    assert encode_png(image.astype(">u2"), 1) == encode_png(image, 1)
    depth = rng.uniform(-1.0, 70.0, (20, 30)).astype(np.float32)
    depth.ravel()[:4] = [np.inf, np.nan, 65.5354, 1e-4]
    big = depth_to_mm_u16(depth, ">")
    assert big.dtype == np.dtype(">u2")
    np.testing.assert_array_equal(big, depth_to_mm_u16(depth))
    with pytest.raises(ValueError, match="uint8 or uint16"):
        encode_png(image.astype(np.int16))
