"""Training augmentations of a whole batch on the training device: torch ops on (B, ...) tensors, no
per-image Python, so a GPU augments as fast as it trains.

The augmentations are generic camera and scene changes, not the randomizer ranges of any one
dataset (a detector trained on them is scored on randomization it never saw:
``benchmarks/detect_domain_gap.py``):

- viewpoint (``view_pitch_deg``, ``view_roll_deg``; off by default, on in ``viewpoint()``): the frame as a
  camera turned about its optical centre would see it, a homography K R K^-1 of a pinhole camera (focal
  ``view_focal_fraction`` of the image height): exact for every 3D point, depth included, so the objects stand
  where another camera pitch or height would put them in the frame (a higher camera sees a thing lower in the
  frame and the floor's horizon elsewhere; the zoom already makes it smaller); boxes become the axis-aligned
  box of their warped corners;
- geometric: horizontal flip, scale jitter with a random crop (or a black margin when the scale is
  below 1), one affine ``grid_sample`` of the pixels (bilinear) and of the instance map (nearest);
- occlusion: flat "flying distractors" over the frame, rectangles or ellipses of a random colour
  shaded across (a lit surface) and speckled (a texture): random erasing made to look like clutter,
  unlabelled, so that things of no class's look are learnt as background; an object left with under
  ``min_visible_fraction`` of its pixels is dropped;
- photometric: exposure (a gain), uneven light (a gain that falls off across the frame in a random
  direction: a low or off-centre light), gamma, contrast, per-channel gains (white balance),
  saturation and hue (a rotation in YIQ's chroma plane), sometimes grey, sometimes blurred, sensor noise.

Boxes move with the pixels exactly (flip and scale keep them axis-aligned); a box cut to under a
quarter of its area, or under 2 px a side, is dropped (its class becomes -1).

Depth (a 4th image channel, ``model.depth_channel``'s encoding, for ``inputs="rgbd"`` models) stays
consistent with the pixels: the geometric warp moves it with them (nearest sampling: a bilinear blend
of an object's and the floor's depth at its edge would be a depth nothing has), and a zoom by s divides
it by s (a pinhole camera sees a thing s times larger when it is s times nearer: with the depth left
as it was, a zoomed object would measure s times its size, and metric size is what depth is for);
an occluder gets a flat depth of its own (0.4-4 m, nearer than most of the floor); the photometric
changes leave it. A height-above-floor channel (the 5th, ``model.height_channel``, ``inputs="rgbdh"``) is a
property of the world, not of the view: the warps move it with the pixels (nearest) and change nothing else
(no zoom or turn of the camera changes how high a thing is); an occluder gets a flat height of its own
(0-1.5 m).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from ambulo.utils.validate import Checked

from .model import depth_channel, height_channel

RGB_TO_YIQ = torch.tensor([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]])
YIQ_TO_RGB = torch.linalg.inv(RGB_TO_YIQ)


@dataclass(kw_only=True)
class AugmentCfg(Checked):
    """Training-time augmentations (none at evaluation); each factor is drawn per image."""

    flip_probability: float = 0.5
    """Horizontal flip: the scenes have no left-right meaning."""
    scale_range: tuple[float, float] = (0.6, 1.5)
    """Scale jitter: objects seen nearer and farther than the data's camera put them."""
    exposure_range: tuple[float, float] = (0.5, 1.8)
    """Brightness gain, drawn log-uniformly (a darker and a brighter exposure are equally likely)."""
    gamma_range: tuple[float, float] = (0.6, 1.6)
    """Tone curve x ** gamma, log-uniform."""
    contrast_range: tuple[float, float] = (0.6, 1.4)
    channel_gain_fraction: float = 0.15
    """White balance: each channel's gain in 1 +- this."""
    saturation_range: tuple[float, float] = (0.4, 1.6)
    hue_fraction: float = 0.1
    """Hue rotation: up to this fraction of a full turn either way."""
    grey_probability: float = 0.05
    blur_probability: float = 0.3
    blur_sigma_range_px: tuple[float, float] = (0.3, 1.5)
    noise_std_range: tuple[float, float] = (0.0, 0.04)
    """Additive Gaussian noise; each image's standard deviation is drawn here."""
    erase_probability: float = 0.5
    """Chance of each of ``erase_count`` rectangles being drawn on an image."""
    erase_count: int = 3
    erase_size_range: tuple[float, float] = (0.05, 0.3)
    """Each rectangle's side as a fraction of the image's."""
    erase_ellipse_probability: float = 0.0
    """Chance of each drawn rectangle being the ellipse inscribed in it instead."""
    erase_shading: float = 0.0
    """Each shape's brightness varies by up to +- this across it, in a random direction (a lit surface)."""
    erase_speckle: float = 0.0
    """Per-pixel brightness noise of each shape (standard deviation, relative): a texture, not a flat colour."""
    light_gradient: float = 0.0
    """Uneven light: the log gain changes by up to +- this from the frame's centre to its corners along a
    random direction (0.5: a corner up to e ** 1 = 2.7 times brighter than the opposite one)."""
    min_visible_fraction: float = 0.3
    """An object covered by rectangles beyond this is dropped: no evidence is left to find it by."""
    view_pitch_deg: float = 0.0
    """Viewpoint: the camera turned up or down by up to +- this (deg) about its optical centre (0: off)."""
    view_roll_deg: float = 0.0
    """Viewpoint: the camera rolled about its optical axis by up to +- this (deg)."""
    view_focal_fraction: float = 0.866
    """The pinhole focal length of the viewpoint warp, as a fraction of the image height (0.866: 60 deg
    vertical field of view, the example dataset's head camera; a wrong value bends straight lines a little)."""


def no_augment() -> AugmentCfg:
    return AugmentCfg(flip_probability=0.0, scale_range=(1.0, 1.0), exposure_range=(1.0, 1.0), gamma_range=(1.0, 1.0),
                      contrast_range=(1.0, 1.0), channel_gain_fraction=0.0, saturation_range=(1.0, 1.0),
                      hue_fraction=0.0, grey_probability=0.0, blur_probability=0.0, noise_std_range=(0.0, 0.0),
                      erase_probability=0.0)


def geometry_only(flip_probability: float = 0.5, scale_range: tuple[float, float] = (0.75, 1.25)) -> AugmentCfg:
    """Flips and scale jitter, no photometric change or occlusion (the augmentations before issue 27's
    domain-gap work, kept to measure what the others add)."""
    return dataclasses.replace(no_augment(), flip_probability=flip_probability, scale_range=scale_range)


def generic() -> AugmentCfg:
    """The defaults plus clutter-like occluders (ellipses and rectangles, shaded, speckled) and uneven
    light: the generic sim-to-real set (``--augment generic``)."""
    return AugmentCfg(erase_ellipse_probability=0.5, erase_shading=0.4, erase_speckle=0.08, light_gradient=0.5)


def viewpoint(pitch_deg: float = 12.0, roll_deg: float = 5.0) -> AugmentCfg:
    """The defaults plus the viewpoint warp (``--augment viewpoint``): the camera pitched by up to
    +- ``pitch_deg`` and rolled by up to +- ``roll_deg``, so that where things stand in the frame (and,
    with depth, how far the floor is at each row) stops telling the camera's pose the training data had."""
    return AugmentCfg(view_pitch_deg=pitch_deg, view_roll_deg=roll_deg)


def _uniform(lo: float, hi: float, shape: tuple[int, ...], g: torch.Generator, device) -> torch.Tensor:
    return lo + (hi - lo) * torch.rand(shape, generator=g, device=device)


def _log_uniform(lo: float, hi: float, shape: tuple[int, ...], g: torch.Generator, device) -> torch.Tensor:
    return torch.exp(_uniform(math.log(lo), math.log(hi), shape, g, device))


def geometric(images: torch.Tensor, instances: torch.Tensor, boxes: torch.Tensor, classes: torch.Tensor,
              cfg: AugmentCfg, g: torch.Generator) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Flip and scale-crop of images (B, 3 or 4, h, w) float (the 4th channel a depth: module
    docstring), instance maps (B, h, w) uint8, boxes (B, M, 4)
    px and classes (B, M) (module docstring). Output pixel x comes from input pixel (x - t) / s, or
    w - (x - t) / s flipped, with t = (1 - s) * extent * u: a window inside a larger image, or the
    image inside a larger window."""
    b, _, h, w = images.shape
    dev = images.device
    flip = torch.rand(b, generator=g, device=dev) < cfg.flip_probability
    s = _uniform(*cfg.scale_range, (b,), g, dev)
    tx = (1 - s) * w * torch.rand(b, generator=g, device=dev)
    ty = (1 - s) * h * torch.rand(b, generator=g, device=dev)
    # the inverse map in grid_sample's normalised coordinates (align_corners=False: x_n = 2 x / w - 1)
    sign = 1.0 - 2.0 * flip.float()
    theta = torch.zeros(b, 2, 3, device=dev)
    theta[:, 0, 0] = sign / s
    theta[:, 0, 2] = sign * (1 / s - 2 * tx / (w * s) - 1)
    theta[:, 1, 1] = 1 / s
    theta[:, 1, 2] = 1 / s - 2 * ty / (h * s) - 1
    grid = F.affine_grid(theta, [b, 1, h, w], align_corners=False)
    colour = F.grid_sample(images[:, :3], grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    if images.shape[1] > 3:  # depth: nearest, and nearer by the zoom; height: nearest (module docstring)
        extra = F.grid_sample(images[:, 3:], grid, mode="nearest", padding_mode="zeros", align_corners=False)
        colour = torch.cat([colour, (extra[:, :1] / s[:, None, None, None]).clamp(0, 1), extra[:, 1:]], dim=1)
    images = colour
    instances = F.grid_sample(instances[:, None].float(), grid, mode="nearest", padding_mode="zeros",
                              align_corners=False)[:, 0].round().to(torch.uint8)
    x0 = torch.where(flip[:, None], w - boxes[..., 2], boxes[..., 0])
    x1 = torch.where(flip[:, None], w - boxes[..., 0], boxes[..., 2])
    moved = torch.stack([x0, boxes[..., 1], x1, boxes[..., 3]], dim=-1) * s[:, None, None]
    moved = moved + torch.stack([tx, ty, tx, ty], dim=-1)[:, None, :]
    area = (moved[..., 2] - moved[..., 0]) * (moved[..., 3] - moved[..., 1])
    limit = torch.tensor([w, h, w, h], dtype=moved.dtype, device=dev)
    moved = torch.minimum(moved.clamp(min=0), limit)
    bw, bh = moved[..., 2] - moved[..., 0], moved[..., 3] - moved[..., 1]
    keep = (bw >= 2) & (bh >= 2) & (bw * bh >= 0.25 * area)
    return images, instances, moved, torch.where(keep, classes, -1)


def view_rotation(pitch_rad: torch.Tensor, roll_rad: torch.Tensor) -> torch.Tensor:
    """(B, 3, 3) the rotations of a camera (x right, y down, z forward: the optical frame) pitched down by
    ``pitch_rad`` (B,) (a positive pitch moves the scene up the frame), then rolled by ``roll_rad`` (B,)
    about z; they map a point's coordinates in the old camera's frame to the new one's."""
    cp, sp, cr, sr = torch.cos(pitch_rad), torch.sin(pitch_rad), torch.cos(roll_rad), torch.sin(roll_rad)
    one, zero = torch.ones_like(cp), torch.zeros_like(cp)
    # the new camera's z axis is the old (0, sin, cos) (turned down): old-frame point p -> new-frame Rx p
    pitch = torch.stack([one, zero, zero, zero, cp, -sp, zero, sp, cp], dim=-1).reshape(-1, 3, 3)
    roll = torch.stack([cr, -sr, zero, sr, cr, zero, zero, zero, one], dim=-1).reshape(-1, 3, 3)
    return roll @ pitch


def rotate_view(images: torch.Tensor, instances: torch.Tensor, boxes: torch.Tensor, classes: torch.Tensor,
                rotation: torch.Tensor, focal_px: float
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The frames a pinhole camera (focal ``focal_px``, principal point the image centre) turned by
    ``rotation`` (B, 3, 3), old camera frame -> new, about its optical centre would see: images (B, 3 or 4,
    h, w) (colour bilinear; depth nearest, each pixel's z scaled to the new camera's: z' = z (R K^-1 q)_z),
    instance maps (B, h, w) nearest, boxes (B, M, 4) px the axis-aligned box of their warped corners, cut to the
    frame (a box left under a quarter of its warped area, or under 2 px a side, loses its class)."""
    b, _, h, w = images.shape
    dev, dtype = images.device, images.dtype
    k = torch.tensor([[focal_px, 0.0, w / 2], [0.0, focal_px, h / 2], [0.0, 0.0, 1.0]], device=dev, dtype=dtype)
    forward = k @ rotation.to(dtype) @ torch.linalg.inv(k)  # (B, 3, 3): old pixel -> new pixel (homogeneous)
    inverse = torch.linalg.inv(forward)
    ys, xs = torch.meshgrid(torch.arange(h, device=dev, dtype=dtype) + 0.5,
                            torch.arange(w, device=dev, dtype=dtype) + 0.5, indexing="ij")
    pixels = torch.stack([xs, ys, torch.ones_like(xs)], dim=-1).reshape(1, -1, 3)  # (1, h w, 3) new pixel centres
    source = pixels @ inverse.transpose(1, 2)  # (B, h w, 3) homogeneous old pixels
    source_xy = source[..., :2] / source[..., 2:]
    grid = torch.stack([2 * source_xy[..., 0] / w - 1, 2 * source_xy[..., 1] / h - 1], dim=-1).reshape(b, h, w, 2)
    warped = F.grid_sample(images[:, :3], grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    if images.shape[1] > 3:
        extra = F.grid_sample(images[:, 3:], grid, mode="nearest", padding_mode="zeros", align_corners=False)
        # a height (a 5th channel) is the world's, unchanged; a point z K^-1 q of the old camera has the new z (R z K^-1 q)_z = z (R K^-1 q)_z; rays through the
        # image stay in front of a camera turned by less than half the field of view
        ray = torch.cat([source_xy, torch.ones_like(source_xy[..., :1])], dim=-1) @ torch.linalg.inv(k).T
        factor = (ray @ rotation.to(dtype)[:, 2:].transpose(1, 2)).reshape(b, 1, h, w)
        warped = torch.cat([warped, (extra[:, :1] * factor).clamp(0, 1), extra[:, 1:]], dim=1)
    instances = F.grid_sample(instances[:, None].float(), grid, mode="nearest", padding_mode="zeros",
                              align_corners=False)[:, 0].round().to(torch.uint8)
    corners = torch.stack([boxes[..., [0, 1]], boxes[..., [2, 1]], boxes[..., [0, 3]], boxes[..., [2, 3]]], dim=2)
    corners = torch.cat([corners, torch.ones_like(corners[..., :1])], dim=-1)  # (B, M, 4, 3)
    moved = corners @ forward[:, None].transpose(2, 3)
    moved = moved[..., :2] / moved[..., 2:]
    moved = torch.cat([moved.amin(dim=2), moved.amax(dim=2)], dim=-1)  # (B, M, 4) x0 y0 x1 y1
    area = (moved[..., 2] - moved[..., 0]) * (moved[..., 3] - moved[..., 1])
    limit = torch.tensor([w, h, w, h], dtype=moved.dtype, device=dev)
    moved = torch.minimum(moved.clamp(min=0), limit)
    bw, bh = moved[..., 2] - moved[..., 0], moved[..., 3] - moved[..., 1]
    keep = (bw >= 2) & (bh >= 2) & (bw * bh >= 0.25 * area)
    return warped, instances, moved, torch.where(keep, classes, -1)


def erase(images: torch.Tensor, instances: torch.Tensor, classes: torch.Tensor, cfg: AugmentCfg,
          g: torch.Generator) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Random-colour rectangles or ellipses (shaded, speckled: ``AugmentCfg``) over images (B, 3 or 4, h, w)
    float (a depth channel gets each shape's own flat depth, 0.4-4 m); their pixels leave the instance maps, and objects with under ``cfg.min_visible_fraction`` of
    their pixels left lose their class."""
    b, _, h, w = images.shape
    r, dev = cfg.erase_count, images.device
    if r == 0 or cfg.erase_probability == 0:
        return images, instances, classes
    drawn = torch.rand(b, r, generator=g, device=dev) < cfg.erase_probability
    half_w = _uniform(*cfg.erase_size_range, (b, r), g, dev) * w / 2
    half_h = _uniform(*cfg.erase_size_range, (b, r), g, dev) * h / 2
    cx, cy = _uniform(0, w, (b, r), g, dev), _uniform(0, h, (b, r), g, dev)
    colour = torch.rand(b, r, 3, generator=g, device=dev)
    ellipse = torch.rand(b, r, generator=g, device=dev) < cfg.erase_ellipse_probability
    angle = _uniform(0, 2 * math.pi, (b, r), g, dev)
    shading = _uniform(-cfg.erase_shading, cfg.erase_shading, (b, r), g, dev)
    u = ((torch.arange(w, device=dev) + 0.5) - cx[..., None]) / half_w[..., None]  # (B, R, w): -1..1 across
    v = ((torch.arange(h, device=dev) + 0.5) - cy[..., None]) / half_h[..., None]  # (B, R, h)
    in_box = (u.abs() <= 1)[:, :, None, :] & (v.abs() <= 1)[:, :, :, None]
    in_ellipse = u[:, :, None, :] ** 2 + v[:, :, :, None] ** 2 <= 1
    inside = torch.where(ellipse[..., None, None], in_ellipse, in_box) & drawn[..., None, None]  # (B, R, h, w)
    # the last shape drawn is on top
    top = torch.where(inside, torch.arange(1, r + 1, device=dev)[None, :, None, None], 0).amax(dim=1)  # (B, h, w)
    covered = top > 0
    index = (top - 1).clamp(min=0)
    paint = colour.gather(1, index.flatten(1)[..., None].expand(-1, -1, 3)).transpose(1, 2).reshape(b, 3, h, w)
    if cfg.erase_shading > 0:  # brightness 1 + shading * (position along the shape's light direction)
        along = torch.cos(angle)[..., None, None] * u[:, :, None, :] + torch.sin(angle)[..., None, None] * v[:, :, :, None]
        shade = 1 + (shading[..., None, None] * along.clamp(-1, 1)).gather(1, index[:, None])[:, 0]  # (B, h, w)
        paint = paint * shade[:, None]
    if cfg.erase_speckle > 0:
        paint = paint * (1 + cfg.erase_speckle * torch.randn((b, 1, h, w), generator=g, device=dev))
    if images.shape[1] > 3:
        depth = depth_channel(_uniform(0.4, 4.0, (b, r), g, dev))
        depth = depth.gather(1, index.flatten(1)).reshape(b, 1, h, w)
        paint = torch.cat([paint.clamp(0, 1), depth], dim=1)
    if images.shape[1] > 4:  # a height channel: each shape's own flat height
        height = height_channel(_uniform(0.0, 1.5, (b, r), g, dev))
        paint = torch.cat([paint, height.gather(1, index.flatten(1)).reshape(b, 1, h, w)], dim=1)
    images = torch.where(covered[:, None], paint.clamp(0, 1), images)
    m = classes.shape[1]
    before = _pixels_per_instance(instances, m)
    instances = torch.where(covered, 0, instances)
    after = _pixels_per_instance(instances, m)
    hidden = (before > 0) & (after < cfg.min_visible_fraction * before)
    return images, instances, torch.where(hidden, -1, classes)


def _pixels_per_instance(instances: torch.Tensor, m: int) -> torch.Tensor:
    """(B, m) pixel counts of instances 1..m of each map (B, h, w)."""
    b = instances.shape[0]
    index = instances.long() + 256 * torch.arange(b, device=instances.device)[:, None, None]
    counts = torch.bincount(index.flatten(), minlength=256 * b).reshape(b, 256)
    return counts[:, 1:m + 1]


def photometric(images: torch.Tensor, cfg: AugmentCfg, g: torch.Generator) -> torch.Tensor:
    """Exposure, gamma, contrast, white balance, saturation, hue, grey, blur and noise of images
    (B, 3, h, w) in [0, 1] (module docstring); the result is in [0, 1]."""
    b, _, h, w = images.shape
    dev = images.device
    x = images * _log_uniform(*cfg.exposure_range, (b, 1, 1, 1), g, dev)
    if cfg.light_gradient > 0:
        angle = _uniform(0, 2 * math.pi, (b, 1, 1), g, dev)
        slope = _uniform(-cfg.light_gradient, cfg.light_gradient, (b, 1, 1), g, dev)
        u = (torch.arange(w, device=dev) + 0.5) / w * 2 - 1  # -1..1 across the frame
        v = (torch.arange(h, device=dev) + 0.5) / h * 2 - 1
        along = (torch.cos(angle) * u[None, None, :] + torch.sin(angle) * v[None, :, None]) / math.sqrt(2)
        x = x * torch.exp(slope * along)[:, None]
    x = x.clamp(0, 1) ** _log_uniform(*cfg.gamma_range, (b, 1, 1, 1), g, dev)
    mean = x.mean(dim=(1, 2, 3), keepdim=True)
    x = mean + _uniform(*cfg.contrast_range, (b, 1, 1, 1), g, dev) * (x - mean)
    # white balance, saturation and hue as one 3x3 colour matrix per image: RGB -> YIQ, scale and
    # rotate the chroma plane (I, Q), back to RGB
    angle = _uniform(-cfg.hue_fraction, cfg.hue_fraction, (b,), g, dev) * 2 * math.pi
    saturation = _uniform(*cfg.saturation_range, (b,), g, dev)
    saturation = torch.where(torch.rand(b, generator=g, device=dev) < cfg.grey_probability, 0.0, saturation)
    chroma = torch.zeros(b, 3, 3, device=dev)
    chroma[:, 0, 0] = 1.0
    chroma[:, 1, 1], chroma[:, 1, 2] = saturation * torch.cos(angle), -saturation * torch.sin(angle)
    chroma[:, 2, 1], chroma[:, 2, 2] = saturation * torch.sin(angle), saturation * torch.cos(angle)
    gains = 1 + _uniform(-cfg.channel_gain_fraction, cfg.channel_gain_fraction, (b, 3), g, dev)
    colour = YIQ_TO_RGB.to(dev) @ chroma @ RGB_TO_YIQ.to(dev) * gains[:, None, :]  # gains act on the input's channels
    x = torch.einsum("bij,bjhw->bihw", colour, x)
    if cfg.blur_probability > 0:
        x = _blur(x, cfg, g)
    noise_std = _uniform(*cfg.noise_std_range, (b, 1, 1, 1), g, dev)
    x = x + noise_std * torch.randn(x.shape, generator=g, device=dev)
    return x.clamp(0, 1)


def _blur(x: torch.Tensor, cfg: AugmentCfg, g: torch.Generator) -> torch.Tensor:
    """Gaussian blur of the images drawn with ``cfg.blur_probability``: one separable convolution of
    the whole batch with a kernel per image (the others' kernel is a unit impulse)."""
    b, c, h, w = x.shape
    dev = x.device
    radius = math.ceil(3 * cfg.blur_sigma_range_px[1])
    sigma = _uniform(*cfg.blur_sigma_range_px, (b,), g, dev)
    taps = torch.arange(-radius, radius + 1, device=dev, dtype=x.dtype)
    kernel = torch.exp(-0.5 * (taps / sigma[:, None]) ** 2)
    kernel = kernel / kernel.sum(dim=1, keepdim=True)
    impulse = (taps == 0).to(x.dtype)
    kernel = torch.where((torch.rand(b, generator=g, device=dev) < cfg.blur_probability)[:, None], kernel, impulse)
    kernel = kernel.repeat_interleave(c, dim=0)  # (B * 3, taps): the same for an image's channels
    flat = F.pad(x.reshape(1, b * c, h, w), (radius, radius, radius, radius), mode="replicate")
    flat = F.conv2d(flat, kernel[:, None, None, :], groups=b * c)
    flat = F.conv2d(flat, kernel[:, None, :, None], groups=b * c)
    return flat.reshape(b, c, h, w)


def batch_images(batch: dict[str, torch.Tensor]) -> torch.Tensor:
    """The model's input (B, 3, h, w) float in [0, 1] of a padded batch's uint8 images, with its
    ``depths`` (B, h, w) int16 mm (``frames``) as a 4th channel (``model.depth_channel``) when it has them,
    and its ``heights`` (B, h, w) int16 mm as a 5th (``model.height_channel``)."""
    images = batch["images"].float() / 255
    if "depths" in batch:
        images = torch.cat([images, depth_channel(batch["depths"].float()[:, None] / 1000.0)], dim=1)
    if "heights" in batch:
        images = torch.cat([images, height_channel(batch["heights"].float()[:, None] / 1000.0)], dim=1)
    return images


def augment_batch(batch: dict[str, torch.Tensor], cfg: AugmentCfg, g: torch.Generator) -> dict[str, torch.Tensor]:
    """A padded batch (``frames.pad_collate``: uint8 images and instance maps, boxes, classes, maybe depths)
    on one device -> the same with float images in [0, 1] (B, 3, h, w), or (B, 4, h, w) with the depth
    channel for a batch with depths, augmented (module docstring)."""
    images, instances, boxes, classes = batch_images(batch), batch["instances"], batch["boxes"], batch["classes"]
    if cfg.view_pitch_deg > 0 or cfg.view_roll_deg > 0:  # off: the draws of the other augmentations as before
        b, dev = images.shape[0], images.device
        pitch = torch.deg2rad(_uniform(-cfg.view_pitch_deg, cfg.view_pitch_deg, (b,), g, dev))
        roll = torch.deg2rad(_uniform(-cfg.view_roll_deg, cfg.view_roll_deg, (b,), g, dev))
        images, instances, boxes, classes = rotate_view(images, instances, boxes, classes, view_rotation(pitch, roll),
                                                        cfg.view_focal_fraction * images.shape[2])
    images, instances, boxes, classes = geometric(images, instances, boxes, classes, cfg, g)
    images, instances, classes = erase(images, instances, classes, cfg, g)
    images = torch.cat([photometric(images[:, :3], cfg, g), images[:, 3:]], dim=1)  # depth: unchanged
    return {"images": images, "instances": instances, "boxes": boxes, "classes": classes}


__all__ = ["AugmentCfg", "augment_batch", "batch_images", "erase", "generic", "geometric", "geometry_only", "no_augment",
           "photometric", "rotate_view", "view_rotation", "viewpoint"]
