"""``cpu_jpeg``: the CPU's share of the disk mode's JPEG encode, chosen by frame index.

The split must depend on the frame index alone (a resumed run batches its frames otherwise and must
still write the straight run's bytes), give the share exactly, and the frames of the CPU's share
must be encoded on the processes from the rendered pixels at nvjpeg's quality and chroma; share 0
must leave every frame to the GPU encoder (the files before the share existed). The disk-mode test
runs on MuJoCo Warp's CPU device with Pillow (4:2:0) standing in for nvjpeg, so which encoder wrote
a file shows in its bytes, and a thread standing in for the draw process (its start and exit are most
of a spawned pool's time here; ``test_batched_disk`` runs the real one).
"""

from __future__ import annotations

import dataclasses
import io
from fractions import Fraction

import numpy as np
import pytest
import torch
from PIL import Image, JpegImagePlugin

from ambulo import replicator as rep
from ambulo.replicator.cpu_jpeg import cpu_worlds, encode_jpeg_cpu, on_cpu, share_fraction


def test_the_split_is_by_index_exact_and_independent_of_the_batches():
    third = share_fraction(1 / 3)
    assert third == Fraction(1, 3) and share_fraction("0.25") == Fraction(1, 4)
    assert [i for i in range(12) if on_cpu(i, third)] == [2, 5, 8, 11]  # evenly spread
    for share in (Fraction(1, 3), Fraction(2, 5), Fraction(1, 8), Fraction(5, 7)):
        for start in (0, 7, 1001):  # any n*d consecutive frames: exactly n*numerator on the CPU
            assert sum(on_cpu(i, share) for i in range(start, start + 3 * share.denominator)) == 3 * share.numerator
    frames = list(range(40))
    for size in (1, 3, 7, 16):  # other batch sizes, the same frames on the CPU
        chunks = [frames[s:s + size] for s in range(0, len(frames), size)]
        picked = {chunk[w] for chunk in chunks for w in cpu_worlds(chunk, third)}
        assert picked == {i for i in frames if on_cpu(i, third)}
    assert cpu_worlds(frames, share_fraction(0)) == [] and cpu_worlds(frames, share_fraction(1)) == frames
    for bad in (-0.1, 1.5):
        with pytest.raises(ValueError, match="within 0 and 1"):
            share_fraction(bad)


def test_the_cpu_encoder_keeps_the_quality_and_nvjpegs_444_chroma():
    # a rendered-looking image: flat areas meeting at sharp coloured edges
    image = np.zeros((48, 64, 3), np.uint8)
    image[:, :32] = (200, 40, 40)
    image[:, 32:] = (30, 90, 220)
    image[20:30] = (90, 200, 60)
    data = encode_jpeg_cpu(image)
    decoded = Image.open(io.BytesIO(data))
    assert JpegImagePlugin.get_sampling(decoded) == 0  # 4:4:4, as torchvision's nvjpeg encoder sets
    # a third of a level off; 4:2:0 chroma blurs the coloured edges (3.1), quality 50 too (2.9)
    assert np.abs(np.asarray(decoded, np.float64) - image).mean() < 1.0


def _gpu_standin(rgb: torch.Tensor) -> list[torch.Tensor]:
    """``encode.encode_jpegs`` stand-in (no torchvision here): Pillow at 4:2:0, bytes the CPU share's
    4:4:4 encoder never writes, so a file tells which encoder made it."""
    out = []
    for image in rgb.cpu().numpy():
        buffer = io.BytesIO()
        Image.fromarray(image).save(buffer, format="JPEG", quality=95, subsampling=2)
        out.append(torch.frombuffer(bytearray(buffer.getvalue()), dtype=torch.uint8))
    return out


def _pool_in_this_process(config, monkeypatch):
    """A ``DrawPool`` whose 'process' is a thread of this one (its worker state here): the same draws
    and ``_write_part`` over the same shared block, without a spawned interpreter's start and exit
    (most of this test's time on the shared VM)."""
    import concurrent.futures as cf

    from ambulo.replicator import batched_disk, draw_pool
    from ambulo.replicator.processes import _dump_config

    pool = draw_pool.DrawPool(config, 1)
    pool._pool.shutdown()  # no process started yet: they start on the first submit
    pool._pool = cf.ThreadPoolExecutor(1)
    monkeypatch.setattr(draw_pool, "_worker", {"payload": _dump_config(config)})
    monkeypatch.setattr(batched_disk, "_blocks", {})  # this process's mappings of the blocks
    return pool


def test_the_cpu_share_is_encoded_by_the_writers_from_the_rendered_pixels(tmp_path, monkeypatch):
    from ambulo.replicator import batched_disk
    from ambulo.replicator.batched import BatchedFrameProducer
    from ambulo.replicator.writers import prepare_dirs

    config = rep.example_config(64, 48)
    config = dataclasses.replace(config, writer=dataclasses.replace(config.writer, outputs=("coco",)))
    producer = BatchedFrameProducer(config, num_worlds=3, device="cpu", draws=_pool_in_this_process(config, monkeypatch))
    monkeypatch.setattr(batched_disk, "encode_jpegs", _gpu_standin)
    # straight: [0 1 2] [3 4 5] [6], one CPU frame a batch at world 2; resumed-like sparse frames:
    # [1 2 4] (CPU frame 2 at world 1) and [5 8 11] (all three on the CPU: nvjpeg gets no image);
    # share 0: every frame to the GPU encoder
    runs = {"short": ([0, 1], Fraction(1, 3)), "straight": (list(range(7)), Fraction(1, 3)), "sparse": ([1, 2, 4, 5, 8, 11], Fraction(1, 3)),
            "share0": ([0, 1, 2], Fraction(0))}
    rows = {}  # each run's blocks' raw RGB rows for the CPU's frames, and the blocks themselves
    try:
        for name, (frames, share) in runs.items():
            prepare_dirs(tmp_path / name, config.writer)
            batched_disk.run_batched_frames(config, tmp_path / name, 2, frames, producer, image_format="jpg",
                                            cpu_jpeg_share=share)
            layout, blocks = producer.disk_blocks
            rows[name] = (layout[0].get("rgb_cpu", ((0,),))[0][0], blocks)
        rendered = {int(i): rgb.copy() for batch in producer.batches(2, list(range(12)))
                    for i, rgb in zip(batch["index"].tolist(), batch["rgb"].cpu().numpy())}
    finally:
        producer.close()
    for name, (frames, share) in runs.items():
        by_cpu = set()
        for index in frames:
            data = (tmp_path / name / f"rgb/{index:06d}.jpg").read_bytes()
            pixels = rendered[index]
            cpu, gpu = encode_jpeg_cpu(pixels), _gpu_standin(torch.as_tensor(pixels[None]))[0].numpy().tobytes()
            assert data in (cpu, gpu), (name, index)  # this frame's pixels, not another's
            if data == cpu:
                by_cpu.add(index)
            decoded = np.asarray(Image.open(io.BytesIO(data)), np.float64)
            assert np.abs(decoded - pixels).mean() < 6.0, (name, index)  # a few levels on a small textured frame
        assert by_cpu == {i for i in frames if on_cpu(i, share)}, name
    # sized for the share (a third of 3 worlds: 1 row), not the batch; the same blocks for a short run
    # (no CPU frame among 0, 1) and a long one, so a run's first batch does not make them again;
    # more rows only where sparse frames put more of a batch on the CPU; none at share 0
    assert {name: count for name, (count, _) in rows.items()} == {"short": 1, "straight": 1, "sparse": 3, "share0": 0}
    assert rows["short"][1] is rows["straight"][1]


def test_generate_refuses_a_share_out_of_range_or_without_jpeg(tmp_path, capsys):
    from ambulo.cli import main

    with pytest.raises(ValueError, match="within 0 and 1"):
        rep.generate(rep.example_config(64, 48), tmp_path / "a", 1, cpu_jpeg_share=1.5, show_progress=False)
    assert main(["generate", "--frames", "2", "--out", str(tmp_path / "b"), "--cpu-jpeg-share", "1/3"]) != 0
    assert "--cpu-jpeg-share splits the JPEG encode" in capsys.readouterr().err
    assert main(["generate", "--frames", "2", "--out", str(tmp_path / "c"), "--image-format", "jpg",
                 "--cpu-jpeg-share", "2"]) != 0
    assert "is not a share from 0 to 1" in capsys.readouterr().err
    assert not any((tmp_path / d).exists() for d in "abc")  # refused before anything is written
