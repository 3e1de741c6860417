"""The batched path's randomization on host copies (``HostWorlds``) and its kinematics-only pass.

Applying every world's draws on the host and uploading each field once must leave the device
exactly as applying them world by world on the engine does (the CPU path's draws, the same
float32 values, byte for byte), and the kinematics pass must pose everything as ``forward``
does. Two producers on Warp's CPU device (slow: each builds a MuJoCo Warp model).
"""

from __future__ import annotations

import pytest
import torch

from ambulo import replicator as rep
from ambulo.replicator.batched import BatchedFrameProducer
from ambulo.replicator.draw_pool import DrawPool
from ambulo.replicator.producer import apply_randomizers
from ambulo.replicator.randomizers import SceneContext

MODEL_FIELDS = ("geom_rgba", "geom_matid", "light_diffuse", "light_ambient", "light_dir")
POSED_FIELDS = ("xpos", "xmat", "geom_xpos", "geom_xmat", "light_xpos", "light_xdir", "cam_xpos")


def _state(producer: BatchedFrameProducer) -> dict[str, torch.Tensor]:
    engine, camera = producer.engine, producer.camera
    out = {name: engine.model_field(name).clone() for name in MODEL_FIELDS}
    out["qpos"] = engine.qpos.clone()
    out["camera_offset_pos"] = camera._offset_pos.clone()
    out["camera_offset_rot_gl"] = camera._offset_rot_gl.clone()
    return out


@pytest.mark.slow
def test_host_randomization_leaves_the_device_as_per_world_writes_would():
    config_size, seed, chunk = (48, 36), 4, [5, 9, 2]
    host = BatchedFrameProducer(rep.example_config(*config_size), num_worlds=3, device="cpu")
    direct = BatchedFrameProducer(rep.example_config(*config_size), num_worlds=3, device="cpu")

    logs = host.randomize(seed, chunk)
    host.kinematics()

    # the reference: every randomizer applied world by world on the engine and camera themselves
    ctx = SceneContext(model=direct.model, engine=direct.engine, cameras={direct.camera.name: direct.camera})
    direct.sim.reset(forward=False)
    direct.camera.reset_pose()
    want_logs = []
    for w, index in enumerate(chunk):
        ctx.world = w
        want_logs.append(apply_randomizers(direct.config.randomizers, direct._names, {}, ctx, seed, index))
    direct.engine.forward()

    assert logs == want_logs
    got, want = _state(host), _state(direct)
    for name in want:
        assert torch.equal(got[name], want[name]), name
    # the frames differ from one another (each world got its own draws)
    assert not torch.equal(got["qpos"][0], got["qpos"][1])
    assert not torch.equal(got["geom_rgba"][0], got["geom_rgba"][2])
    for name in POSED_FIELDS:
        assert torch.equal(host.engine.field(name), direct.engine.field(name)), name

    # a second batch starts from the reset state, not from the first batch's
    host.randomize(seed, chunk)
    assert torch.equal(host.engine.qpos, want["qpos"])


@pytest.mark.slow
def test_draws_on_worker_processes_equal_the_draws_in_process():
    # what a draw pool changes: where the draws run, never what they are
    size, seed, chunk = (48, 36), 7, [3, 1, 4, 1, 5]
    config = rep.example_config(*size)
    pooled = BatchedFrameProducer(config, num_worlds=5, device="cpu", draws=DrawPool(config, 2))
    inline = BatchedFrameProducer(rep.example_config(*size), num_worlds=5, device="cpu")
    try:
        assert pooled.randomize(seed, chunk) == inline.randomize(seed, chunk)
        got, want = _state(pooled), _state(inline)
        for name in want:
            assert torch.equal(got[name], want[name]), name
        # batches draw a chunk ahead; the labels are the in-process ones, batch for batch
        for a, b in zip(pooled.batches(seed, range(8)), inline.batches(seed, range(8)), strict=True):
            assert torch.equal(a["index"], b["index"]) and torch.equal(a["boxes"], b["boxes"])
            assert torch.equal(a["rgb"], b["rgb"])
    finally:
        pooled.close()


@pytest.mark.slow
def test_dataset_files_do_not_depend_on_the_worlds_per_launch(tmp_path):
    # frame i is world i % n of some launch: every file must be the same whichever world drew it
    from ambulo.replicator.generate import generate

    for n in (2, 3):
        generate(rep.example_config(64, 48), tmp_path / str(n), 5, seed=11, show_progress=False, device="cpu",
                 num_worlds=n)
    a, b = tmp_path / "2", tmp_path / "3"
    names = sorted(str(f.relative_to(a)) for f in a.rglob("*") if f.is_file())
    # rgb, depth and instance images a frame (the default annotators ask for no semantic image) + the COCO file
    assert len(names) > 5 * 3 and names == sorted(str(f.relative_to(b)) for f in b.rglob("*") if f.is_file())
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
