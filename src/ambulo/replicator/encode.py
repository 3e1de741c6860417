"""The disk mode's per-pixel work on the device: RGB as JPEG (nvjpeg), 16-bit id images.

What a batch of frames needs before its files can be written, computed where the pixels are, for
all worlds at once: the RGB images as JPEG through torchvision's nvjpeg binding
(``torchvision.io.encode_jpeg`` of a list of CUDA tensors: one batched call), and for the JPEG
mode's depth PNGs the uint16 millimetres of ``io.depth_to_mm_u16``. The 16-bit images travel as int16 (the same bits: torch's unsigned 16-bit type lacks kernels) and are read
back as uint16, half the bytes of the int32 ids.

torchvision is optional (it must match the CUDA build of torch, so it is not a dependency):
``jpeg_available`` says whether the JPEG path can run; without it the RGB images are PNGs encoded
on the host, as on the CPU path.
"""

from __future__ import annotations

import functools

import torch

IMAGE_FORMATS = ("png", "jpg")
JPEG_QUALITY = 95
"""nvjpeg's quality for the RGB images: high enough that detectors see no block edges."""


@functools.cache
def jpeg_available(device: str = "cuda") -> bool:
    """Whether ``encode_jpeg`` can run on ``device``: torchvision imports and its nvjpeg (or, on the
    CPU, libjpeg) encoder answers."""
    try:
        from torchvision.io import encode_jpeg
    except Exception:  # not installed, or built for another torch (its operators fail to load)
        return False
    try:
        encode_jpeg([torch.zeros((3, 8, 8), dtype=torch.uint8, device=device)], quality=JPEG_QUALITY)
    except Exception:
        return False
    return True


def encode_jpegs(rgb: torch.Tensor, quality: int = JPEG_QUALITY) -> list[torch.Tensor]:
    """JPEG files of (B, H, W, 3) uint8 images, as 1-D uint8 tensors on the images' device (one
    batched ``encode_jpeg`` call: on CUDA, nvjpeg encodes the whole batch)."""
    from torchvision.io import encode_jpeg

    return encode_jpeg(list(rgb.permute(0, 3, 1, 2).contiguous()), quality=quality)


def depth_mm(depth_m: torch.Tensor) -> torch.Tensor:
    """Depth (m, float32) as uint16 millimetres held in int16: ``io.depth_to_mm_u16``'s numbers
    (rounded half to even in float32; 0 for no return, NaN, negative or beyond 65.535 m), at half
    the bytes of the metres to copy."""
    mm = torch.round(depth_m * 1000.0)
    good = (mm >= 0) & (mm <= 65535)
    return torch.where(good, mm, 0.0).to(torch.int32).to(torch.int16)


def as_u16_bits(ids: torch.Tensor) -> torch.Tensor:
    """Integer ids in [0, 65535] as int16 with uint16's bits (what a 16-bit PNG holds)."""
    return ids.to(torch.int32).to(torch.int16)


__all__ = ["IMAGE_FORMATS", "JPEG_QUALITY", "as_u16_bits", "depth_mm", "encode_jpegs", "jpeg_available"]
