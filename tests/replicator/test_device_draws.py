"""``device_draws``: the in-memory mode's randomization, all worlds at once on the device.

What a training loop relies on: a frame's scene depends on (seed, index) alone, not on the batch
that renders it; every draw stays in its distribution; scattered objects never overlap each other
or the scenery; and on CUDA a batch makes no host sync (checked with torch's sync debug mode).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from ambulo import replicator as rep
from ambulo.core.randomize import choice, normal, uniform, uniform_int
from ambulo.replicator import device_draws as dd
from ambulo.replicator.randomizers import hsv_to_rgb
from ambulo.utils.rotations import rot_about_axes


def _stream(seed: int, k: int, blocks: torch.Tensor, prefetch: int = 0) -> dd.Stream:
    return dd.Stream(dd.stream_keys(seed, [k], [blocks])[0], prefetch)


def test_uniforms_depend_on_seed_randomizer_and_block_only():
    blocks = torch.tensor([0, 1, 2, 3, 1000])
    u = _stream(5, 2, blocks).take(64)
    assert u.shape == (5, 64) and u.dtype == torch.float32
    assert float(u.min()) >= 0.0 and float(u.max()) < 1.0
    # block 2 alone, in another position, and later slots continue the same stream
    again = _stream(5, 2, torch.tensor([2, 0]))
    np.testing.assert_array_equal(again.take(10)[0].numpy(), u[2, :10].numpy())
    np.testing.assert_array_equal(again.take(54)[1].numpy(), u[0, 10:].numpy())
    for other in (_stream(6, 2, blocks), _stream(5, 3, blocks)):
        assert not torch.equal(other.take(64), u)
    assert len({tuple(row.tolist()) for row in u}) == 5  # every block its own stream
    many = _stream(1, 0, torch.arange(256)).take(4096)
    # drawn up front or take by take, past the prefetch too: the same numbers
    ahead = _stream(5, 2, blocks, prefetch=40)
    np.testing.assert_array_equal(torch.cat([ahead.take(30), ahead.take(34)], 1).numpy(), u.numpy())
    x = torch.tensor([0, 1, 0xFFFFFFFF, 123456789])
    assert dd.mix32(x).tolist() == [dd._mix32_int(v) for v in x.tolist()]
    assert abs(float(many.mean()) - 0.5) < 0.002 and abs(float(many.std()) - math.sqrt(1 / 12)) < 0.002


def test_device_samplers_stay_in_their_distributions():
    stream = _stream(3, 0, torch.arange(512))
    u = dd.sample(uniform((0.0, -2.0), (1.0, -1.0)), stream, 8)
    assert u.shape == (512, 8, 2)
    assert float(u[..., 0].min()) >= 0 and float(u[..., 1].max()) < -1.0 and float(u[..., 1].min()) >= -2.0
    z = dd.sample(normal(3.0, 0.5), stream, 64)
    assert z.shape == (512, 64) and abs(float(z.mean()) - 3.0) < 0.01 and abs(float(z.std()) - 0.5) < 0.01
    k = dd.sample(uniform_int(2, 6), stream, 16)
    assert k.dtype == torch.int64 and set(k.unique().tolist()) == {2, 3, 4, 5, 6}
    c = dd.sample(choice([1.0, 5.0], weights=[3, 1]), stream, 64)
    assert set(c.unique().tolist()) == {1.0, 5.0} and abs(float((c == 5.0).float().mean()) - 0.25) < 0.01
    assert dd.sample(0.7, stream, 3).shape == (512, 3) and float(dd.sample(0.7, stream, 3)[5, 2]) == pytest.approx(0.7)


def test_hsv_and_rotation_vectors_match_the_host_functions():
    rng = np.random.default_rng(0)
    hsv = rng.uniform(0, 1, (50, 3))
    got = dd.hsv_to_rgb(torch.as_tensor(hsv))
    np.testing.assert_allclose(got.numpy(), [hsv_to_rgb(*row) for row in hsv.tolist()], atol=1e-12)
    rotvec = rng.normal(0, 1, (20, 3))
    rotvec[0] = 0.0
    np.testing.assert_allclose(dd.rotvec_to_mat(torch.as_tensor(rotvec)).numpy(), rot_about_axes(rotvec), atol=1e-12)


def _producer(device: str, worlds: int):
    from ambulo.replicator.batched import BatchedFrameProducer

    return BatchedFrameProducer(rep.example_config(64, 48), num_worlds=worlds, device=device)


@pytest.fixture(scope="module")
def warp_cpu_producer():
    producer = _producer("cpu", 4)
    yield producer
    producer.close()


def _scene(producer) -> dict:
    e = producer.engine
    return {"qpos": e.qpos.clone(), "rgba": e.model_field("geom_rgba").clone(),
            "matid": e.model_field("geom_matid").clone(), "light_dir": e.model_field("light_dir").clone(),
            "camera": producer.camera._offset_rot_gl.clone()}


def test_a_frames_device_draws_do_not_depend_on_its_batch(warp_cpu_producer):
    p = warp_cpu_producer
    batch = next(p.batches(7, [0, 1, 2, 3], device_draws=True))
    assert batch["index"].tolist() == [0, 1, 2, 3] and batch["rgb"].shape == (4, 48, 64, 3)
    first = _scene(p)
    assert not torch.equal(first["qpos"][0], first["qpos"][1])
    next(p.batches(7, [5, 2, 9, 0], device_draws=True))
    second = _scene(p)
    for name in first:
        torch.testing.assert_close(second[name][1], first[name][2], rtol=0, atol=0, msg=name)
        torch.testing.assert_close(second[name][3], first[name][0], rtol=0, atol=0, msg=name)
    next(p.batches(8, [0], device_draws=True))  # another seed: another scene
    assert not torch.equal(p.engine.qpos[0], first["qpos"][0])


def test_device_scatter_places_objects_apart_in_the_region(warp_cpu_producer):
    p = warp_cpu_producer
    seen_distractors = set()
    for start in range(0, 24, 4):
        next(p.batches(11, list(range(start, start + 4)), device_draws=True))
        qpos = p.engine.qpos.double()
        circles = []
        for twin in p.device_draws.twins:
            if not isinstance(twin, dd._Scatter):
                continue
            r = twin.r
            (x0, y0), (x1, y1) = r.region
            free = qpos[:, twin.free_index]  # (B, n, 7)
            placed = free[..., 2] > -1.0
            if r.count is not None:
                seen_distractors |= set(placed.sum(1).tolist())
            for w in range(4):
                for j in np.flatnonzero(placed[w].numpy()):
                    x, y = free[w, j, :2].tolist()
                    assert x0 <= x <= x1 and y0 <= y <= y1
                    assert free[w, j, 2] == pytest.approx(float(twin.rest_z[j]), abs=1e-6)
                    circles.append((w, x, y, twin.radius[j]))
                    box = p.device_draws._boxes.double().numpy()
                    gap = np.maximum(np.abs(np.array([x, y]) - box[:, :2]) - box[:, 2:], 0)
                    assert ((gap ** 2).sum(1) >= twin.radius[j] ** 2 - 1e-9).all()
        for i, (w, x, y, r) in enumerate(circles):
            for w2, x2, y2, r2 in circles[i + 1:]:
                assert w != w2 or math.hypot(x - x2, y - y2) >= r + r2 - 1e-5
    assert seen_distractors <= set(range(2, 7)) and len(seen_distractors) >= 3


def test_device_draws_refuse_a_randomizer_without_a_twin():
    from ambulo.replicator.randomizers import Randomizer

    class Custom(Randomizer):
        pass

    with pytest.raises(ValueError, match="no device twin"):
        dd.DeviceDraws([Custom(name="mine")], engine=None, camera=None, model=None)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_a_device_drawn_batch_makes_no_host_sync_on_cuda():
    producer = _producer("cuda", 8)
    try:
        frames = list(range(32))
        batches = producer.batches(0, frames, device_draws=True)
        next(batches)  # the first compiles kernels and builds the draws' tensors
        torch.cuda.synchronize()
        torch.cuda.set_sync_debug_mode("error")
        try:
            for batch in batches:
                assert batch["boxes"].is_cuda
        finally:
            torch.cuda.set_sync_debug_mode("default")
    finally:
        producer.close()
