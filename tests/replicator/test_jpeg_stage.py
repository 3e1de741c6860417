"""``jpeg_stage.JpegStage``: the disk mode's JPEG encode a batch behind the render, on its own thread.

Batches must be handed on in the order they were put (the commits rely on batch order), each
batch's files end to end in its block with their sizes, the images encoded as they were when
taken (not as the camera's buffer is after the next render), and an encoder's error must free
that batch's block and every later one's, so the render's thread never waits for a block forever.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import torch

from ambulo.replicator.jpeg_stage import JpegStage


def _encode_slow_first(images: torch.Tensor) -> list[torch.Tensor]:
    """A stand-in encoder: each image's 'file' is its first pixel's bytes repeated (length varies
    by image); the first batch is slow, so a thread that reorders would show it."""
    if int(images[0, 0, 0, 0]) == 0:
        time.sleep(0.2)
    return [img[0, 0].repeat(1 + int(img[0, 0, 0]) % 3) for img in images]


def _batch(first: int) -> torch.Tensor:
    """(2, 4, 5, 3) uint8 images whose first pixels are first, first + 1."""
    images = torch.zeros((2, 4, 5, 3), dtype=torch.uint8)
    images[:, 0, 0] = torch.tensor([[first] * 3, [first + 1] * 3], dtype=torch.uint8)
    return images


def test_batches_are_encoded_into_their_blocks_and_handed_on_in_order():
    stage = JpegStage("cpu", _encode_slow_first)
    blocks = [np.full(64, 255, np.uint8) for _ in range(3)]
    handed = []
    camera = _batch(0)
    for b in range(3):
        taken = stage.take(camera)
        camera[:, 0, 0] = 200  # the next render overwrites the camera's buffer at once
        stage.put(taken, lambda size, a=blocks[b]: a[:size], then=lambda sizes, b=b: handed.append((b, sizes)),
                  drop=lambda: handed.append("dropped"))
        camera = _batch(10 * (b + 1))
    stage.close()
    assert not stage.failed and [b for b, _ in handed] == [0, 1, 2]
    for b, sizes in handed:
        first = 10 * b
        want = np.concatenate([np.full(3 * (1 + v % 3), v, np.uint8) for v in (first, first + 1)])
        assert sizes == [3 * (1 + first % 3), 3 * (1 + (first + 1) % 3)]
        np.testing.assert_array_equal(blocks[b][:sum(sizes)], want)
    assert stage.encode_s >= 0.2


def test_an_encoder_error_drops_that_batch_and_the_later_ones():
    calls = []

    def encode(images):
        calls.append(int(images[0, 0, 0, 0]))
        if len(calls) == 2:
            raise RuntimeError("nvjpeg failed")
        return [img.reshape(-1)[:3] for img in images]

    stage = JpegStage("cpu", encode)
    events = []
    freed = threading.Event()
    for b in range(3):
        stage.put(stage.take(_batch(b)), lambda size: np.zeros(size, np.uint8),
                  then=lambda sizes, b=b: events.append(("then", b)),
                  drop=lambda b=b: events.append(("drop", b)) or (b == 2 and freed.set()))
    assert freed.wait(10)
    stage.close()
    assert events == [("then", 0), ("drop", 1), ("drop", 2)] and calls == [0, 1]  # nothing encoded after
    assert isinstance(stage.failed[0], RuntimeError)
