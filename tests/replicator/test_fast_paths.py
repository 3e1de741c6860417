"""The generator's fast paths give exactly what the straightforward computations give.

Each vectorized step of a frame (tight boxes from runs, COCO RLEs of all instances at once,
instance and depth maps, batched random draws, one write per randomizer, one quaternion) is
checked against the per-object, per-pixel or per-call version it replaced, on hand-made
segmentations whose objects wrap rows, touch the image's edges or are a single pixel.
"""

import dataclasses
import warnings

import numpy as np
import pytest
import torch
from pycocotools import mask as mask_utils

from ambulo import replicator as rep
from ambulo.core import randomize as dist
from ambulo.core.randomize.fields import geoms_by_body, write_field
from ambulo.replicator.coco import InstanceRuns, column_runs, frame_annotations, instance_rles, runs_tight_boxes
from ambulo.replicator.io import depth_to_mm_u16
from ambulo.sensors import annotators as ann
from ambulo.utils.rotations import quat_to_mat


def hand_made_segmentations() -> list[np.ndarray]:
    """(H, W) int32 instance maps with 0 = background and ids 1..6."""
    a = np.zeros((7, 9), np.int32)
    a[0, 0] = 1                 # one pixel in the first corner
    a[6, 8] = 2                 # and in the last
    a[2, 5:] = 3                # a run to the end of row 2 ...
    a[3, :4] = 3                # ... and on from the start of row 3: one run in row order
    a[1:6, 3] = 4               # a column: one run per row
    a[4:6, 6:9] = 5             # a block on the right edge
    b = np.full((4, 5), 6, np.int32)  # one object fills the image
    c = np.zeros((3, 4), np.int32)    # nothing visible
    d = np.zeros((5, 5), np.int32)
    d[:, 0], d[:, 4] = 1, 1     # two separate parts of one object
    d[2, :] = 2                 # crossing them
    return [a, b, c, d]


def random_segmentations(count: int = 25) -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    out = []
    for trial in range(count):
        h, w = (int(v) for v in rng.integers(1, 30, 2))
        seg = rng.integers(0, 7, (h, w)) * (rng.random((h, w)) < 0.7)
        if trial % 2:
            seg = np.repeat(seg, 3, axis=1)[:, :w]  # longer runs
        out.append(seg.astype(np.int32))
    return out


def boxes_one_by_one(seg: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The straightforward tight boxes: each instance's nonzero pixels."""
    boxes, pixels = np.full((k, 4), -1, np.int64), np.zeros(k, np.int64)
    for i in range(1, k + 1):
        ys, xs = np.nonzero(seg == i)
        if len(xs):
            boxes[i - 1] = [xs.min(), ys.min(), xs.max(), ys.max()]
            pixels[i - 1] = len(xs)
    return boxes, pixels


@pytest.mark.parametrize("seg", hand_made_segmentations() + random_segmentations())
def test_tight_boxes_from_runs_equal_each_instances_pixels(seg):
    k = 7  # ids 1..7; 7 never appears: an invisible instance
    boxes, pixels = ann.tight_boxes(seg, k)
    expected_boxes, expected_pixels = boxes_one_by_one(seg, k)
    np.testing.assert_array_equal(boxes, expected_boxes)
    np.testing.assert_array_equal(pixels, expected_pixels)
    assert boxes.dtype == np.int64 and pixels.dtype == np.int64


@pytest.mark.parametrize("seg", hand_made_segmentations() + random_segmentations()
                         + [np.array([[1, 1, 2, 0]], np.int32), np.array([[3], [3], [0]], np.int32)])
def test_tight_boxes_and_rles_from_one_pass_of_column_runs_equal_each_their_own(seg):
    """The producer's one pass (``InstanceRuns``): its tight boxes are each instance's pixels' (as
    ``tight_boxes`` finds them in row order) and its RLEs are those found from the image itself."""
    runs = InstanceRuns.of(seg)
    boxes, pixels = runs_tight_boxes(runs, 7)
    expected_boxes, expected_pixels = boxes_one_by_one(seg, 7)
    np.testing.assert_array_equal(boxes, expected_boxes)
    np.testing.assert_array_equal(pixels, expected_pixels)
    assert boxes.dtype == np.int64 and pixels.dtype == np.int64
    ids = np.array([3, 1, 9, 2, 6])
    assert [r["counts"] for r in instance_rles(None, ids, runs=runs)] == [r["counts"] for r in instance_rles(seg, ids)]


def test_hand_made_boxes_by_value():
    boxes, pixels = ann.tight_boxes(hand_made_segmentations()[0], 5)
    assert boxes.tolist() == [[0, 0, 0, 0], [8, 6, 8, 6], [0, 2, 8, 3], [3, 1, 3, 5], [6, 4, 8, 5]]
    assert pixels.tolist() == [1, 1, 7, 5, 6]  # id 3 loses the pixel at (3, 3) to id 4


@pytest.mark.parametrize("seg", hand_made_segmentations() + random_segmentations())
def test_rles_of_all_instances_at_once_equal_pycocotools_encode_of_each_mask(seg):
    present = np.unique(seg[seg > 0])
    ids = np.concatenate([present[::-1], [9]])  # any order; 9 is absent: an empty mask
    masks = np.asfortranarray(np.stack([seg == i for i in ids], axis=-1).astype(np.uint8))
    expected = mask_utils.encode(masks)
    got = instance_rles(seg, ids)
    assert [r["counts"] for r in got] == [r["counts"] for r in expected]
    assert [list(r["size"]) for r in got] == [list(r["size"]) for r in expected]
    # COCO boxes of the RLEs are the tight boxes in COCO's convention (pixel edges, width and height)
    tight, _ = ann.tight_boxes(seg, 9)
    for iid, box in zip(ids, mask_utils.toBbox(got)):
        x0, y0, x1, y1 = tight[iid - 1]
        assert box.tolist() == ([x0, y0, x1 - x0 + 1, y1 - y0 + 1] if x0 >= 0 else [0, 0, 0, 0])
    assert instance_rles(seg, np.array([], np.int64)) == []


@pytest.mark.parametrize("seg", hand_made_segmentations() + random_segmentations()
                         + [np.array([[1, 1, 2, 0]], np.int32), np.array([[3], [3], [0]], np.int32)])
def test_column_runs_equal_the_runs_of_the_column_major_copy(seg):
    flat = seg.T.ravel()  # the straightforward way: copy the ids column by column, compare neighbours
    expected = np.concatenate(([0], np.flatnonzero(flat[1:] != flat[:-1]) + 1))
    starts, ids = column_runs(seg)
    np.testing.assert_array_equal(starts, expected)
    np.testing.assert_array_equal(ids, flat[expected])


def test_instance_map_equals_the_table_lookup():
    table = ann.InstanceTable(body_ids=np.array([3, 5]), labels=["a", "b"], categories=["a", "b"],
                              semantic_ids=np.array([0, 1, 2], np.int32),
                              geom_instance=np.array([0, 0, 1, 1, 2, 0, 2], np.int32), names=["x", "y"])
    geom_ids = np.random.default_rng(0).integers(-1, 6, (13, 17)).astype(np.int32)
    got = ann.instance_map(geom_ids, table)
    np.testing.assert_array_equal(got, table.geom_instance[geom_ids + 1])
    assert got.dtype == np.int32


def test_depth_in_mm_equals_the_straightforward_conversion():
    rng = np.random.default_rng(1)
    for dtype in (np.float32, np.float64):
        depth = rng.uniform(-1.0, 70.0, (40, 50)).astype(dtype)
        depth.ravel()[:12] = [np.inf, -np.inf, np.nan, 0.0, -0.0, 65.5354, 65.5355, 65.536, -0.0004, -0.0006,
                              1e-4, 3.0]
        mm = np.rint(np.where(np.isfinite(depth), depth, 0.0) * 1000.0)
        expected = np.where((mm > 65535) | (mm < 0), 0, mm).astype(np.uint16)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no cast of NaN or inf (its result is the CPU's choice)
            got = depth_to_mm_u16(depth)
        np.testing.assert_array_equal(got, expected)
        assert got.dtype == np.uint16 and got.ravel()[:6].tolist() == [0, 0, 0, 0, 0, 65535]


def test_sample_columns_gives_the_numbers_of_its_definition():
    """All scalar uniforms: one (rows, k) draw mapped column by column; otherwise one
    distribution's column after the other."""
    rows = 7
    uniforms = [dist.uniform(0.0, 1.0), dist.uniform(0.2, 0.9), dist.uniform(-3, 5)]
    a, b = torch.Generator().manual_seed(11), torch.Generator().manual_seed(11)
    u = torch.rand((rows, 3), generator=a, dtype=torch.float64)
    low, high = torch.tensor([0.0, 0.2, -3.0], dtype=torch.float64), torch.tensor([1.0, 0.9, 5.0], dtype=torch.float64)
    assert torch.equal(dist.sample_columns(b, uniforms, rows), low + (high - low) * u)
    mixed = [dist.uniform(0.0, 1.0), dist.normal(0.0, 2.0), 0.5]
    a, b = torch.Generator().manual_seed(11), torch.Generator().manual_seed(11)
    expected = torch.stack([dist.as_distribution(d).sample(a, rows) for d in mixed], 1)
    assert torch.equal(dist.sample_columns(b, mixed, rows), expected)
    assert torch.equal(expected[:, 2], torch.full((rows,), 0.5, dtype=torch.float64))
    assert torch.rand(1, generator=a).item() == torch.rand(1, generator=b).item()  # same state after
    assert dist.sample_columns(torch.Generator().manual_seed(0), [dist.uniform(0, 1)], 0).shape == (0, 1)


def test_uniform_samples_are_unchanged_by_its_cached_bounds():
    u = dist.uniform((0.8, 0.8, 0.75), (1.0, 1.0, 1.0))
    a, b = torch.Generator().manual_seed(5), torch.Generator().manual_seed(5)
    for size in (None, 4, 4):  # the second draw of 4 uses the cached tensors
        low, high = torch.tensor(u.low, dtype=torch.float64), torch.tensor(u.high, dtype=torch.float64)
        shape = (3,) if size is None else (size, 3)
        expected = low + (high - low) * torch.rand(shape, generator=b, dtype=torch.float64)
        assert torch.equal(u.sample(a, size), expected)
    assert u == dist.uniform((0.8, 0.8, 0.75), (1.0, 1.0, 1.0))  # the cache is not a field


def test_one_write_per_randomizer_equals_writing_body_after_body():
    geoms = [np.array([0, 1, 2]), np.array([], int), np.array([2, 5]), np.array([7])]  # geom 2 in two bodies
    targets, body_of = geoms_by_body(9, geoms)
    values = np.arange(len(geoms) * 4, dtype=np.float64).reshape(-1, 4) / 7
    loop = torch.zeros(2, 9, 4, dtype=torch.float32)
    for g, v in zip(geoms, values):
        loop[1, g] = torch.tensor(v, dtype=torch.float32)
    once = torch.zeros(2, 9, 4, dtype=torch.float32)
    write_field(once, values[None, body_of], rows=1, index=targets)
    assert torch.equal(loop, once)
    assert targets.tolist() == [0, 1, 2, 5, 7] and body_of.tolist() == [0, 0, 2, 2, 3]


def test_randomizers_write_what_their_per_body_loops_wrote():
    """Colours and materials of the example scene: the one-write apply against the loop it replaced."""
    producer = rep.FrameProducer(dataclasses.replace(rep.example_config(32, 24), randomizers=[
        rep.ColorRandomizer(name="c", prims="/World/objects/*"),
        rep.MaterialRandomizer(name="m", prims="/World/objects/*"), rep.LightRandomizer(name="l")]))
    try:
        engine, ctx = producer.engine, producer.ctx
        colors, materials, lights = producer.config.randomizers
        for seed in range(3):
            rng = np.random.default_rng(seed)
            for r in (colors, materials, lights):
                r.apply(r.sample(rng, ctx), ctx)
            params = {r.name: r.sample(np.random.default_rng([seed, 1]), ctx) for r in (colors, materials, lights)}
            rgba, matid = engine.model_field("geom_rgba").clone(), engine.model_field("geom_matid").clone()
            for geoms, color in zip(colors._targets.geoms, params["c"]["rgba"]):
                rgba[0, geoms] = torch.tensor(color, dtype=rgba.dtype)
            for geoms, pick in zip(materials._targets.geoms, params["m"]["palette_index"]):
                value = materials._base[geoms] if pick < 0 else np.full(len(geoms), materials._mat_ids[pick])
                matid[0, geoms] = torch.as_tensor(value, dtype=matid.dtype)
            expected_lights = {f: engine.model_field(f).clone() for f in ("light_diffuse", "light_ambient",
                                                                          "light_dir")}
            for lid, p in zip(lights._ids, params["l"]["lights"]):
                diffuse, ambient, direction = expected_lights.values()
                diffuse[0, lid] = torch.tensor(p["diffuse"], dtype=diffuse.dtype)
                ambient[0, lid] = p["ambient"]
                direction[0, lid] = torch.tensor(p["dir"], dtype=direction.dtype)
            for r in (colors, materials, lights):
                r.apply(params[r.name], ctx)
            assert torch.equal(engine.model_field("geom_rgba"), rgba)
            assert torch.equal(engine.model_field("geom_matid"), matid)
            for name, expected in expected_lights.items():
                assert torch.equal(engine.model_field(name), expected), name
    finally:
        producer.close()


def test_one_quaternion_gives_the_batched_rotation_bit_for_bit():
    q = np.random.default_rng(2).normal(size=(3000, 4))
    q[::3] *= 1e-4
    q[1::3] *= 1e4
    np.testing.assert_array_equal(np.array([quat_to_mat(v) for v in q]), quat_to_mat(q))
    assert quat_to_mat([1, 0, 0, 0]).shape == (3, 3)


def test_frame_annotations_keep_their_fields_and_values():
    """A capture with every optional part: the record's annotation, field by field."""
    seg = hand_made_segmentations()[0]
    boxes, pixels = ann.tight_boxes(seg, 5)
    visible = np.flatnonzero(pixels > 0)
    capture = {
        "instance_segmentation": seg,
        "bounding_box_2d_tight": {"instance_id": visible + 1, "box": boxes[visible], "pixels": pixels[visible]},
        "bounding_box_2d_loose": {"instance_id": np.array([3, 5]), "box": np.array([[0.5, 1.5, 8.5, 3.5],
                                                                                    [5.5, 3.5, 8.5, 6.5]])},
        "bounding_box_3d": {key: np.arange(5 * n, dtype=np.float64).reshape(5, *shape) / 3
                            for key, n, shape in (("center_w", 3, (3,)), ("rot_w", 9, (3, 3)),
                                                  ("half_extent", 3, (3,)), ("center_c", 3, (3,)),
                                                  ("rot_c", 9, (3, 3)))},
        "visible_fraction": np.array([1.0, 0.5, 0.25, 0.125, 1.0], np.float32),
    }
    anns = frame_annotations(capture, np.array([0, 2, 1, 1, 2, 1]), [f"/o{i}" for i in range(1, 6)], 2)
    assert [a["instance_id"] for a in anns] == [3, 4, 5]  # ids 1 and 2 have one pixel: fewer than 2
    a = anns[0]
    assert a["category_id"] == 1 and a["bbox"] == [0.0, 2.0, 9.0, 2.0] and a["area"] == 7
    assert a["prim_path"] == "/o3" and a["iscrowd"] == 0 and a["segmentation"]["size"] == [7, 9]
    assert a["bbox_loose"] == [1.0, 2.0, 8.0, 2.0] and "bbox_loose" not in anns[1]
    assert a["bbox_3d"]["rot_c"] == (np.arange(45.0).reshape(5, 3, 3) / 3)[2].tolist()
    assert a["visible_fraction"] == 0.25 and type(a["visible_fraction"]) is float
    assert all(type(v) is float for v in a["bbox"]) and type(a["area"]) is int


def test_collision_checker_without_surface_contacts_finds_what_filtering_them_found():
    """The checker's model lets the support surface collide with nothing and makes only contacts
    with the scattered objects' geoms; the bodies it reports are those of the full model's
    contacts with a scattered object, the surface's dropped, for random placements."""
    import mujoco

    producer = rep.FrameProducer(rep.example_config(32, 24))
    try:
        scatter = next(r for r in producer.config.randomizers if isinstance(r, rep.Scatter2D))
        checker, model = scatter._checker, producer.model
        data = mujoco.MjData(model)
        rng = np.random.default_rng(4)
        movers = np.zeros(model.ngeom, bool)
        movers[np.concatenate(scatter._geoms)] = True
        found_any = others_touch = False
        for _ in range(60):
            qpos = producer.engine.qpos[0].numpy().copy()
            scatter._park_all(qpos)
            for i in range(len(scatter._bodies)):  # crowded: many objects touch
                scatter._write(qpos, i, [rng.uniform(0.3, 1.2), rng.uniform(-0.5, 0.5), rng.uniform(-3, 3)])
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
            geoms = data.contact.geom[:data.ncon]
            hit = (data.contact.dist[:data.ncon] < -1e-4) & ~checker._ignore[geoms].any(1)
            hit &= movers[geoms].any(1)
            expected = {int(b) for b in model.body_rootid[model.geom_bodyid[geoms[hit]]].ravel()}
            assert checker.colliding_roots(qpos) == expected
            found_any |= bool(expected)
            others_touch |= bool((~movers[geoms]).all(1).any())
        assert found_any and data.ncon > 0  # the full model made surface contacts; they were dropped
        made = checker.data.contact.geom[:checker.data.ncon]
        assert not checker._ignore[made].any() and movers[made].any(1).all()
        assert others_touch  # the full model made contacts without the objects; the checker did not
    finally:
        producer.close()
