"""The CPU's share of the disk mode's JPEG encode: which frames the draw processes encode, and how.

torchvision's nvjpeg binding encodes a batch's images one at a time under a global lock, waiting
for the device twice an image: on the H200, 0.45-0.50 ms a 640x480 frame on the JPEG thread
(``jpeg_stage``), while the host's cores are mostly idle. ``batched_disk`` therefore hands a share
of each batch's frames to the draw processes raw (the block's ``rgb_cpu``), and they encode them
with libjpeg-turbo (Pillow) while nvjpeg encodes the rest. Measured on the H200 in one run
(``benchmarks/results/h200-2026-11-29-session9.md``): to disk with fsync 1,657 -> 1,783 frames/s at
1/3; into ``/dev/shm`` ~2,000 either way, so the JPEG thread is one bound among others (the render
thread's draws, block waits, commits), not the only one.

Which frames go to the CPU depends on the frame index alone (``on_cpu``), never on the batch, the
host or the timing: a killed and resumed run writes the same bytes as a straight run with the same
share. A share n/d (a fraction, exact) puts frame i on the CPU when floor((i+1)·n/d) > floor(i·n/d):
spread evenly, n of every d consecutive frames (1/3: frames 2, 5, 8, ...). Share 0: every frame on
nvjpeg (the files before the share existed).

The CPU's files decode to the same picture within a grey level or so, not to the same bytes as
nvjpeg's: the same quality (``encode.JPEG_QUALITY``) and chroma sampling (4:4:4, what torchvision's
CUDA encoder sets: ``nvjpegEncoderParamsSetSamplingFactors(..., NVJPEG_CSS_444)``), another encoder.
"""

from __future__ import annotations

import io
from fractions import Fraction

import numpy as np

from .encode import JPEG_QUALITY

DEFAULT_CPU_JPEG_SHARE = Fraction(1, 3)
"""The GPU path's default: nvjpeg encodes 2/3 of the frames, the draw processes the rest (Pillow
4:4:4: 1.6-2.2 ms a 640x480 frame on one core of the H200 host); +8 % to disk there (see above)."""

MAX_DENOMINATOR = 64
"""A share is rounded to the nearest fraction with a denominator up to this (1/3 stays exact)."""


def share_fraction(share: float | Fraction | str) -> Fraction:
    """``share`` (0 to 1; a float, a Fraction or text such as '1/3') as the exact fraction ``on_cpu``
    uses. Raises ValueError out of range."""
    fraction = Fraction(share).limit_denominator(MAX_DENOMINATOR)
    if not 0 <= fraction <= 1:
        raise ValueError(f"the CPU's JPEG share must be within 0 and 1, got {share}")
    return fraction


def on_cpu(index: int, share: Fraction) -> bool:
    """Whether frame ``index``'s JPEG is encoded on the CPU under ``share`` (see the module docstring)."""
    n, d = share.numerator, share.denominator
    return (index + 1) * n // d > index * n // d


def cpu_worlds(chunk: list[int], share: Fraction) -> list[int]:
    """The positions in ``chunk`` (a batch's frame indices, one a world) of the frames the CPU encodes."""
    if share == 0:
        return []
    return [world for world, index in enumerate(chunk) if on_cpu(index, share)]


def encode_jpeg_cpu(rgb: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """A JPEG file of an (H, W, 3) uint8 image: libjpeg-turbo through Pillow, 4:4:4 chroma as
    torchvision's nvjpeg encoder (Pillow's default at this quality would be 4:2:0), baseline, no
    optimized Huffman tables (nvjpeg's defaults too). 3-4 ms a 640x480 frame on one loaded core
    of the development VM; Pillow releases the GIL while it encodes."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).save(buffer, format="JPEG", quality=quality, subsampling=0)
    return buffer.getvalue()


__all__ = ["DEFAULT_CPU_JPEG_SHARE", "MAX_DENOMINATOR", "cpu_worlds", "encode_jpeg_cpu", "on_cpu", "share_fraction"]
