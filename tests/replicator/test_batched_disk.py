"""``batched_disk``: the GPU path's disk mode, files written on the draw processes from shared memory.

Moving the writing to other processes must change no file: the PNG dataset equals ``run_frames``'s
byte for byte (slow on Warp's CPU device: each process builds the scene). The JPEG mode needs CUDA
and torchvision: its labels equal the PNG dataset's and its images decode to nearly the same pixels.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from ambulo import replicator as rep
from ambulo.replicator.batched_disk import SharedBatch, batch_layout, run_batched_frames, supports
from ambulo.replicator.coco import merge_coco
from ambulo.replicator.encode import jpeg_available
from ambulo.replicator.records import frame_of_line, journals, read_records, split_journal
from ambulo.replicator.writers import json_bytes
from ambulo.sensors.annotators import instance_table


def test_shared_batch_holds_the_layouts_arrays_and_is_removed_on_close():
    import mmap
    import os

    layout = batch_layout(3, 4, 5, jpeg=False)
    block = SharedBatch(layout, pin=False)
    assert {k: (a.shape, a.dtype.str) for k, a in block.arrays.items()} == {
        "instances": ((3, 4, 5), "<u2"), "depth_mm": ((3, 4, 5), "<u2"), "semantic": ((3, 4, 5), "<u2"),
        "rgb": ((3, 4, 5, 3), "|u1")}
    for i, array in enumerate(block.arrays.values()):
        array[...] = i + 1
    path, _, offsets = block.spec
    with open(path, "r+b") as f:  # what a writer process maps
        other = mmap.mmap(f.fileno(), 0)
    view = {k: np.ndarray(shape, dtype, buffer=other, offset=offsets[k]) for k, (shape, dtype) in layout.items()}
    for i, key in enumerate(layout):
        assert (view[key] == i + 1).all(), key  # no two arrays overlap
    del view
    other.close()
    block.close()
    assert not os.path.exists(path)
    assert batch_layout(2, 4, 5, jpeg=True)["jpeg_bytes"] == ((2 * 4 * 5 * 3,), "u1")
    assert "semantic" not in batch_layout(2, 4, 5, jpeg=True, semantic=False)  # not asked for: not copied
    assert batch_layout(2, 4, 5, jpeg=True)["depth_mm"] == ((2, 4, 5), "<u2")  # converted on the device
    assert set(batch_layout(2, 4, 5, jpeg=True, semantic=False, depth=False)) == {"instances", "jpeg_bytes"}
    # RGB and COCO alone: the JPEG files are all a block holds (the masks' runs come from the device)
    assert set(batch_layout(2, 4, 5, jpeg=True, semantic=False, depth=False, instances=False)) == {"jpeg_bytes"}


def test_device_depth_in_mm_is_the_hosts():
    from ambulo.replicator.encode import depth_mm
    from ambulo.replicator.io import depth_to_mm_u16

    rng = np.random.default_rng(1)
    depth = rng.uniform(-1.0, 70.0, (7, 9)).astype(np.float32)
    depth.flat[:8] = [np.inf, -np.inf, np.nan, 0.0, 0.0005, 0.0015, 65.535, 65.5355]  # edges and ties
    got = depth_mm(torch.as_tensor(depth)).numpy().view(np.uint16)
    np.testing.assert_array_equal(got, depth_to_mm_u16(depth))


def test_the_disk_mode_refuses_what_it_cannot_write(tmp_path):
    config = rep.example_config(64, 48)
    assert supports(config.writer)
    raw = dataclasses.replace(config.writer, outputs=("coco", "raw"))
    assert not supports(raw) and not supports(dataclasses.replace(config.writer, depth_format="npy"))
    with pytest.raises(ValueError, match="image format"):
        run_batched_frames(config, tmp_path, 0, [0], producer=None, image_format="webp")
    with pytest.raises(ValueError, match="raw"):
        run_batched_frames(dataclasses.replace(config, writer=raw), tmp_path, 0, [0], producer=None)
    with pytest.raises(ValueError, match="jpg"):  # JPEG is the batched GPU path's
        rep.generate(config, tmp_path / "d", 1, image_format="jpg", show_progress=False)


def _tree(root) -> dict:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _pillow_jpegs(rgb: torch.Tensor) -> list[torch.Tensor]:
    """``encode.encode_jpegs`` with Pillow: the JPEG mode's plumbing without torchvision."""
    import io

    from PIL import Image

    out = []
    for image in rgb.cpu().numpy():
        buffer = io.BytesIO()
        Image.fromarray(image).save(buffer, format="JPEG", quality=95)
        out.append(torch.frombuffer(bytearray(buffer.getvalue()), dtype=torch.uint8))
    return out


@pytest.mark.slow
def test_files_written_on_the_draw_processes_equal_run_frames_files(tmp_path, monkeypatch):
    from PIL import Image

    from ambulo.replicator import batched_disk
    from ambulo.replicator.batched import BatchedFrameProducer
    from ambulo.replicator.draw_pool import DrawPool
    from ambulo.replicator.producer import run_frames
    from ambulo.replicator.writers import prepare_dirs

    config = rep.example_config(64, 48)
    config = dataclasses.replace(config, writer=dataclasses.replace(config.writer,
                                                                    outputs=("coco", "depth", "masks", "kitti")))
    # 3 worlds for 7 frames: two full launches and a partial one, two blocks in turn
    producer = BatchedFrameProducer(config, num_worlds=3, device="cpu", draws=DrawPool(config, 2))
    monkeypatch.setattr(batched_disk, "encode_jpegs", _pillow_jpegs)
    try:
        for name in ("pool", "threads", "jpg"):
            prepare_dirs(tmp_path / name, config.writer)
        run_batched_frames(config, tmp_path / "pool", 2, list(range(7)), producer)
        run_frames(config, tmp_path / "threads", 2, list(range(7)), producer=producer, writer_threads=2)
        run_batched_frames(config, tmp_path / "jpg", 2, list(range(7)), producer, image_format="jpg")
    finally:
        producer.close()
    pool, threads = _tree(tmp_path / "pool"), _tree(tmp_path / "threads")
    assert len(pool) >= 7 * 4 + 1 and sorted(pool) == sorted(threads)  # 4 images a frame, the records
    for name in pool:
        assert pool[name] == threads[name], name
    # JPEG: each frame's files at their places, the same record but for the RGB file, the same pixels
    pngs, jpgs = (read_records(tmp_path / d / "frames") for d in ("pool", "jpg"))
    for i in range(7):
        png, jpg = pngs[i], jpgs[i]
        assert jpg["file_name"] == f"rgb/{i:06d}.jpg"
        assert {k: v for k, v in jpg.items() if k not in ("file_name", "files")} == \
            {k: v for k, v in png.items() if k not in ("file_name", "files")}
        a = np.asarray(Image.open(tmp_path / "jpg" / jpg["file_name"]), np.float64)
        # JPEG's loss on a small textured image: a few levels; another frame's picture: tens
        assert np.abs(a - np.asarray(Image.open(tmp_path / "pool" / png["file_name"]), np.float64)).mean() < 6.0
        for name in png["files"]:
            if not name.startswith("rgb/"):
                assert (tmp_path / "jpg" / name).read_bytes() == (tmp_path / "pool" / name).read_bytes(), name


@pytest.mark.skipif(not (torch.cuda.is_available() and jpeg_available("cuda")), reason="needs CUDA and torchvision")
def test_a_jpeg_dataset_has_the_png_datasets_labels_and_nearly_its_pixels(tmp_path):
    from PIL import Image

    config = rep.example_config(160, 120)
    paths = {fmt: rep.generate(config, tmp_path / fmt, 6, seed=3, show_progress=False, device="cuda", num_worlds=4,
                               draw_workers=2, image_format=fmt) for fmt in ("png", "jpg")}
    png, jpg = (json.loads(paths[fmt].read_text()) for fmt in ("png", "jpg"))
    assert [i["file_name"] for i in jpg["images"]] == [f"rgb/{i:06d}.jpg" for i in range(6)]
    assert jpg["annotations"] == png["annotations"]
    fingerprint = json.loads((tmp_path / "jpg" / "dataset.json").read_text())["fingerprint"]
    assert "jpeg" in fingerprint["image_source"]
    for i in range(6):
        a = np.asarray(Image.open(tmp_path / "png" / f"rgb/{i:06d}.png"), np.float64)
        b = np.asarray(Image.open(tmp_path / "jpg" / f"rgb/{i:06d}.jpg"), np.float64)
        assert a.shape == b.shape and np.abs(a - b).mean() < 6.0


def test_a_jpeg_frame_has_the_png_frames_files_and_record_but_its_rgb_file(tmp_path):
    import io

    from PIL import Image

    from ambulo.replicator.batched import BatchedFrameProducer
    from ambulo.replicator.io import depth_to_mm_u16
    from ambulo.replicator.writers import prepare_dirs, write_frame_files

    config = rep.example_config(64, 48)
    config = dataclasses.replace(config, writer=dataclasses.replace(config.writer,
                                                                    outputs=("coco", "depth", "masks", "kitti")))
    producer = BatchedFrameProducer(config, num_worlds=2, device="cpu")
    try:
        (index, log, capture), = list(producer.frames(5, [3]))
        table = producer.table
    finally:
        producer.close()
    buffer = io.BytesIO()
    Image.fromarray(capture["rgb"]).save(buffer, format="JPEG", quality=95)
    for name in ("png", "jpg"):
        prepare_dirs(tmp_path / name, config.writer)
    want = write_frame_files(tmp_path / "png", index, capture, table, log, config.writer, fsync_files=False)
    got = write_frame_files(tmp_path / "jpg", index, capture, table, log, config.writer, fsync_files=False,
                            rgb_jpeg=np.frombuffer(buffer.getvalue(), np.uint8),
                            depth_mm_u16=depth_to_mm_u16(capture["depth"]))
    assert got["file_name"] == "rgb/000003.jpg" and (tmp_path / "jpg" / got["file_name"]).read_bytes() == buffer.getvalue()
    assert {k: v for k, v in got.items() if k not in ("file_name", "files")} == \
        {k: v for k, v in want.items() if k not in ("file_name", "files")}
    others = sorted(f for f in want["files"] if not f.startswith("rgb/"))
    assert others == sorted(f for f in got["files"] if not f.startswith("rgb/")) and len(others) >= 3
    for name in others:  # the same pixels (a PNG's row filter and deflate may differ) and the same text
        a, b = (tmp_path / fmt / name for fmt in ("jpg", "png"))
        if name.endswith(".png"):
            np.testing.assert_array_equal(np.asarray(Image.open(a)), np.asarray(Image.open(b)), err_msg=name)
        else:
            assert a.read_bytes() == b.read_bytes(), name


def test_generate_cli_refuses_jpeg_without_the_gpu_path(tmp_path, capsys):
    from ambulo.cli import main

    assert main(["generate", "--frames", "2", "--out", str(tmp_path / "a"), "--image-format", "jpg"]) != 0
    assert "--image-format jpg encodes the RGB images on the GPU" in capsys.readouterr().err
    if not jpeg_available("cpu"):
        assert main(["generate", "--frames", "2", "--out", str(tmp_path / "b"), "--device", "cpu",
                     "--image-format", "jpg"]) != 0
        assert "needs torchvision's JPEG encoder on cpu" in capsys.readouterr().err
    assert not any((tmp_path / d).exists() for d in "ab")  # nothing written


def test_an_interrupted_disk_mode_run_resumes_to_the_straight_runs_files(tmp_path, monkeypatch, gen):
    # annotations.json is made from the COCO pieces the processes hand back with the frames this
    # run commits, and from the records of the frames an earlier run made: a run cut short after
    # some commits (one frame's record lost, another's file torn, as a kill leaves them) and
    # resumed must give the straight run's files, annotations.json byte for byte
    import importlib

    from ambulo.replicator import coco_file
    from ambulo.replicator.batched import BatchedFrameProducer
    from ambulo.replicator.draw_pool import DrawPool
    from ambulo.replicator.producer import run_frames
    from ambulo.replicator.writers import prepare_dirs

    gen_module = importlib.import_module("ambulo.replicator.generate")  # the module, not its function
    config = rep.example_config(64, 48)
    # RGB and COCO alone (the headline dataset): the processes get no instance image, only run lengths
    config = dataclasses.replace(config, writer=dataclasses.replace(config.writer, outputs=("coco",)))
    # one producer and pool for the three runs (each would build its own: seconds of the test)
    producer = BatchedFrameProducer(config, num_worlds=3, device="cpu", draws=DrawPool(config, 1))
    monkeypatch.setattr(gen_module, "BatchedFrameProducer", lambda *a, draws=None, **k: draws.close() or producer)
    monkeypatch.setattr(producer, "close", lambda: None)
    made, write = {}, coco_file.write_annotations
    monkeypatch.setattr(gen_module, "write_annotations",
                        lambda path, *args, pieces=None, **kw: made.update({path.parent.name: set(pieces or ())})
                        or write(path, *args, pieces=pieces, **kw))
    run, cut = gen_module.run_batched_frames, {"at": None}

    def cut_short(config, out, seed, frames, *args, **kwargs):
        if cut["at"] is None:
            return run(config, out, seed, frames, *args, **kwargs)
        run(config, out, seed, frames[:cut["at"]], *args, **kwargs)
        (journal,) = journals(out / "frames")  # frame 1's batch's commit never happened: no line of it
        journal.write_bytes(b"".join(line + b"\n" for line in split_journal(journal.read_bytes())[0]
                                     if frame_of_line(line) != 1))
        (out / "rgb" / "000004.png").write_bytes(b"torn")  # a file cut short after its record
        raise KeyboardInterrupt("killed")

    monkeypatch.setattr(gen_module, "run_batched_frames", cut_short)
    frames, options = 8, {"seed": 3, "show_progress": False, "device": "cpu", "num_worlds": 3, "draw_workers": 1}
    try:
        rep.generate(config, tmp_path / "straight", frames, **options)
        cut["at"] = 6
        with pytest.raises(KeyboardInterrupt):
            rep.generate(config, tmp_path / "resumed", frames, **options)
        assert not (tmp_path / "resumed" / "annotations.json").exists()
        cut["at"] = None
        rep.generate(config, tmp_path / "resumed", frames, **options)
        prepare_dirs(tmp_path / "threads", config.writer)  # the first disk mode: every file in this process
        run_frames(config, tmp_path / "threads", 3, list(range(frames)), producer=producer, writer_threads=1)
    finally:
        producer.draws.close()
    threads = gen.file_tree(tmp_path / "threads")
    assert threads == {k: v for k, v in gen.file_tree(tmp_path / "straight").items() if k in threads}
    assert len(threads) == frames + 1  # the rgb images and the records
    assert made == {"straight": set(range(frames)), "resumed": {1, 4, 6, 7}}  # the others from records
    assert gen.file_tree(tmp_path / "resumed") == gen.file_tree(tmp_path / "straight")
    straight = (tmp_path / "straight" / "annotations.json").read_bytes()
    assert (tmp_path / "resumed" / "annotations.json").read_bytes() == straight
    assert straight == json_bytes(merge_coco(tmp_path / "straight" / "frames", frames,
                                             instance_table(producer.model).categories,
                                             json.loads(straight)["info"]))


def test_the_jpeg_modes_third_block_is_dropped_rather_than_leave_shared_memory(monkeypatch):
    # three blocks (one being encoded) where /dev/shm holds them and one to spare; where it holds
    # only two and one to spare, two there (page-locked copies) rather than three in a file's pages
    import os
    import types

    from ambulo.replicator import batched_disk

    layout = batch_layout(2, 4, 5, jpeg=True)
    size = batched_disk._offsets(layout)[1]
    room = {"blocks": 4}
    monkeypatch.setattr(batched_disk.os, "statvfs", lambda path: types.SimpleNamespace(
        f_bavail=room["blocks"] * size + 1, f_frsize=1))
    for blocks, want in ((4, (3, "/dev/shm")), (3, (2, "/dev/shm")), (2, (3, tempfile_dir()))):
        room["blocks"] = blocks
        producer = types.SimpleNamespace(disk_blocks=None, close_disk_blocks=lambda: None)
        made = batched_disk.shared_blocks(producer, layout, pin=False, count=3)
        try:
            assert (len(made), os.path.dirname(made[0].path)) == want, blocks
            assert len({b.path for b in made}) == len(made)
        finally:
            for block in made:
                block.close()


def tempfile_dir() -> str:
    import tempfile

    return tempfile.gettempdir()


def test_the_render_thread_waiting_for_a_block_raises_a_later_failure():
    # a batch whose hand-over failed on the JPEG thread may never give its block back: the render's
    # thread, waiting for a free block, must raise that error rather than wait for ever
    import queue
    import threading
    import types

    from ambulo.replicator import batched_disk

    stage, commits = types.SimpleNamespace(failed=[]), types.SimpleNamespace(failed=[])
    threading.Timer(0.3, lambda: stage.failed.append(RuntimeError("process pool broken"))).start()
    with pytest.raises(RuntimeError, match="pool broken"):
        batched_disk._free_block(queue.Queue(), commits, stage)
    free = queue.Queue()
    free.put("block")
    assert batched_disk._free_block(free, types.SimpleNamespace(failed=[]), None) == "block"
