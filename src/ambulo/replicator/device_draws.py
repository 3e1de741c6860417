"""The in-memory mode's randomization: every world's draws made and applied on the device at once.

``BatchedFrameProducer.batches(..., device_draws=True)`` hands a training loop frames that never
touch the disk, so they need not equal the CPU path's frames number for number; what they need is
to be cheap. The host draws (``HostWorlds``, ``draw_pool``) follow the CPU path's NumPy streams
frame by frame and cost ~0.6 ms of CPU a frame, twenty times the GPU's work. ``DeviceDraws``
makes the same kinds of draws for all worlds of a batch as tensor operations on the engine's device
and writes them straight into the engine's fields: no host work per frame and no host sync.

The numbers come from a counter-based hash (``uniforms``): draw s of randomizer k for frame i is a
function of (seed, k, i // every_n_frames, s) alone, so a frame is the same whatever batch,
position or device renders it (bit for bit between Warp's CPU device and CUDA), and a run is
reproducible. Each bundled randomizer has its device twin (``_TWINS``); a config with any other
randomizer is refused with a message (its host draws still work, ``device_draws=False``).

``Scatter2D``'s placement differs from the CPU path's by design: instead of MuJoCo's collision
detection on the exact shapes (a few ms of Python a frame), each object is a footprint circle
(its upright bounding box, any yaw) and the static scenery (walls, shelves, the robot at its
initial pose) axis-aligned boxes in the plane; objects are placed one after the other, each at
the first of ``max_tries`` candidate poses that overlaps nothing placed before, in every world at
once, and parked under the floor if none does. Circles are conservative: placed objects never
interpenetrate, though they keep a little more space between them than the CPU path's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import torch

from ambulo.core import match_names
from ambulo.core.randomize.distributions import Choice, Constant, Distribution, Normal, Uniform, UniformInt

from .randomizers import (
    CameraJitter,
    ColorRandomizer,
    JointRandomizer,
    LightRandomizer,
    MaterialRandomizer,
    Randomizer,
)
from .scatter import Scatter2D, footprint_radius

_MASK32 = 0xFFFFFFFF


def _mul32(x: torch.Tensor, c: int) -> torch.Tensor:
    """``x * c mod 2**32`` for int64 ``x`` in [0, 2**32): in 16-bit halves of ``c``, so no product
    leaves int64's range (a signed overflow would be undefined on the host)."""
    lo, hi = c & 0xFFFF, c >> 16
    return (x * lo + ((x * hi) & 0xFFFF) * 65536) & _MASK32


def mix32(x: torch.Tensor) -> torch.Tensor:
    """A 32-bit integer hash (Wellons' lowbias32) of int64 ``x`` in [0, 2**32): what turns a
    counter into random bits."""
    x = x ^ (x >> 16)
    x = _mul32(x, 0x7FEB352D)
    x = x ^ (x >> 15)
    x = _mul32(x, 0x846CA68B)
    return x ^ (x >> 16)


def _mix32_int(x: int) -> int:
    """``mix32`` of one Python int: the host part of a key, with no tensor op."""
    x &= _MASK32
    x ^= x >> 16
    x = (x * 0x7FEB352D) & _MASK32
    x ^= x >> 15
    x = (x * 0x846CA68B) & _MASK32
    return x ^ (x >> 16)


def key_base(seed: int, k: int) -> int:
    """The host part of randomizer ``k``'s keys for ``seed`` (``stream_keys`` mixes in the block)."""
    key = _mix32_int((seed & _MASK32) ^ 0x9E3779B9)
    key = _mix32_int(key ^ ((seed >> 32) & _MASK32))
    return _mix32_int(key ^ (k & _MASK32))


def stream_keys(seed: int, ks, blocks) -> torch.Tensor:
    """(R, B) int64 keys of randomizers ``ks`` (R ints) for their frame blocks ``blocks`` (R tensors
    (B,) int64) of ``seed``, in one hash pass: row r is randomizer ``ks[r]``'s."""
    return mix32(torch.stack([(b & _MASK32) ^ key_base(seed, k) for k, b in zip(ks, blocks, strict=True)]))


_SLOTS: dict[tuple, torch.Tensor] = {}


def uniforms(keys: torch.Tensor, first: int, count: int) -> torch.Tensor:
    """(B, count) float32 uniforms in [0, 1): draws ``first .. first + count - 1`` of each key's
    stream (24 bits each: float32's mantissa, so every value is exact)."""
    cache_key = (keys.device, first, count)  # the same few slot ranges every batch: hashed once
    slots = _SLOTS.get(cache_key)
    if slots is None:
        slots = _SLOTS[cache_key] = mix32(torch.arange(first, first + count, dtype=torch.int64,
                                                       device=keys.device) + 0x632BE5AB)
    bits = mix32(keys[:, None] ^ slots[None, :])
    return (bits >> 8).to(torch.float32) * (1.0 / (1 << 24))


class Stream:
    """One randomizer's draws for a batch of frames: consecutive slots of ``uniforms``. ``keys``:
    a row of ``stream_keys``, (B,); ``prefetch``: slots drawn at once up front (the count the randomizer
    took last batch: one hash pass instead of one per ``take``; the same numbers either way)."""

    def __init__(self, keys: torch.Tensor, prefetch: int = 0):
        self.keys = keys
        self.used = 0
        self._drawn = uniforms(keys, 0, prefetch) if prefetch else None

    def take(self, count: int) -> torch.Tensor:
        start, self.used = self.used, self.used + count
        if self._drawn is not None and self.used <= self._drawn.shape[1]:
            return self._drawn[:, start:self.used]
        return uniforms(self.keys, start, count)


def _params(given, dist, device: torch.device, cache: dict):
    """``dist``'s parameters as float32 tensors on ``device``, made once per distribution: a copy to a
    GPU from pageable memory each batch would wait for the device. A uniform's or a normal's are the
    distribution's own (``param_tensors``: (low, high) or (mean, std), and the value shape); the others'
    are kept in ``cache`` by ``given`` (the randomizer's own object, a distribution or a number)."""
    if isinstance(dist, Uniform | Normal):
        return dist.param_tensors(device, torch.float32)
    key = id(given)
    hit = cache.get(key)
    if hit is not None and hit[0] is given:
        return hit[1]
    if isinstance(dist, Choice):
        weights = np.ones(len(dist.options)) if dist.weights is None else np.asarray(dist.weights, np.float64)
        params = (torch.as_tensor(np.asarray(dist.options, np.float64), dtype=torch.float32, device=device),
                  torch.as_tensor(np.cumsum(weights) / weights.sum(), dtype=torch.float32, device=device))
    elif isinstance(dist, Constant):
        params = torch.as_tensor(np.asarray(dist.value, np.float64), dtype=torch.float32, device=device)
    else:
        params = None
    cache[key] = (given, params)
    return params


def sample(dist, stream: Stream, num: int, cache: dict | None = None) -> torch.Tensor:
    """(B, num, *S) float32 draws of ``dist`` (a ``core.randomize`` distribution or a number) for
    every frame of ``stream``; ``UniformInt`` gives int64. ``cache`` keeps the parameters' tensors."""
    given, dist = dist, dist if isinstance(dist, Distribution) else Constant(dist)
    b = len(stream.keys)
    params = _params(given, dist, stream.keys.device, {} if cache is None else cache)
    if isinstance(dist, Uniform | Normal):
        a, c, shape = params
        size = num * math.prod(shape)
        if isinstance(dist, Uniform):
            u = stream.take(size).view(b, num, *shape)
            return a + (c - a) * u
        u = stream.take(2 * size).view(b, 2, num, *shape)  # Box-Muller: two uniforms a value
        z = torch.sqrt(-2.0 * torch.log1p(-u[:, 0])) * torch.cos((2.0 * math.pi) * u[:, 1])
        return a + c * z
    if isinstance(dist, UniformInt):
        span = int(dist.high) - int(dist.low) + 1
        return int(dist.low) + torch.floor(stream.take(num) * span).long().clamp_(max=span - 1)
    if isinstance(dist, Choice):
        options, edges = params
        index = torch.searchsorted(edges, stream.take(num), right=True).clamp_(max=len(edges) - 1)
        return options[index]
    if isinstance(dist, Constant):
        return params.expand(b, num, *params.shape)
    raise ValueError(f"no device sampler for {type(dist).__name__}; use uniform, normal, uniform_int, choice "
                     "or constant, or draw on the host (device_draws=False)")


def hsv_to_rgb(hsv: torch.Tensor) -> torch.Tensor:
    """(..., 3) HSV in [0, 1] -> (..., 3) RGB: ``randomizers.hsv_to_rgb`` on tensors."""
    h, s, v = hsv.unbind(-1)
    sector = torch.floor(h * 6.0)
    f = h * 6.0 - sector
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    table = torch.stack([torch.stack(c, -1) for c in
                         ((v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q))], -2)
    index = torch.remainder(sector.long(), 6)[..., None, None].expand(*h.shape, 1, 3)
    return table.gather(-2, index)[..., 0, :]


def rotvec_to_mat(rotvec: torch.Tensor) -> torch.Tensor:
    """(..., 3) rotation vectors (axis * angle, rad) -> (..., 3, 3) (Rodrigues), as
    ``utils.rotations.rot_about_axes`` on tensors."""
    angle = rotvec.norm(dim=-1, keepdim=True)
    axis = rotvec / angle.clamp_min(1e-30)
    x, y, z = axis.unbind(-1)
    zero = torch.zeros_like(x)
    k = torch.stack((zero, -z, y, z, zero, -x, -y, x, zero), -1).view(*x.shape, 3, 3)
    sin, cos = torch.sin(angle)[..., None], torch.cos(angle)[..., None]
    eye = torch.eye(3, dtype=rotvec.dtype, device=rotvec.device)
    return eye + sin * k + (1 - cos) * (k @ k)


@dataclass
class Footprints:
    """What a batch's scatterers avoid, in the plane (m): static boxes and the circles placed so far."""

    boxes: torch.Tensor
    """(O, 4) centre x, y and half extents x, y of the static scenery's boxes."""
    placed: torch.Tensor
    """(B, M, 3) x, y, radius of each object placed this frame (radius 0: a free slot)."""
    count: int = 0

    def static_overlaps(self, xy: torch.Tensor, radius: torch.Tensor) -> torch.Tensor:
        """(...) whether circles of ``radius`` (broadcast to ``xy[..., 0]``) at ``xy`` (..., 2)
        overlap the static boxes."""
        centre, half = self.boxes[:, :2], self.boxes[:, 2:]
        gap = ((xy[..., None, :] - centre).abs() - half).clamp_min(0.0)  # (..., O, 2)
        return ((gap * gap).sum(-1) < (radius * radius)[..., None]).any(-1)

    def placed_overlaps(self, xy: torch.Tensor, radius: float) -> torch.Tensor:
        """(B, T) whether a circle of ``radius`` at candidates ``xy`` (B, T, 2) overlaps a circle
        placed before."""
        placed = self.placed[:, None, :self.count]  # (B, 1, M, 3)
        d = xy[:, :, None, :] - placed[..., :2]
        reach = placed[..., 2] + radius
        return (((d * d).sum(-1) < reach * reach) & (placed[..., 2] > 0)).any(-1)


class _Twin:
    """A randomizer's device twin: ``apply(stream, count, footprints)`` draws from ``stream`` and
    writes worlds ``[0, count)`` of the engine's fields (scatterers also read and add ``footprints``)."""

    def __init__(self, r: Randomizer, engine, camera, model: mujoco.MjModel):
        self.r, self.engine, self.camera, self.model = r, engine, camera, model
        self.device = engine.device
        self._cache: dict = {}
        self.slots_used = 0
        """Uniforms the last ``apply`` took: drawn at once the next time (``Stream``'s prefetch)."""

    def sample(self, dist, stream: Stream, num: int) -> torch.Tensor:
        return sample(dist, stream, num, self._cache)

    def tensor(self, values, dtype=torch.int64) -> torch.Tensor:
        return torch.as_tensor(np.asarray(values), dtype=dtype, device=self.device)


class _Joints(_Twin):
    def __init__(self, *args):
        super().__init__(*args)
        self.adr = self.tensor(self.r._qpos_adr)
        self.low, self.high = (self.tensor(v, torch.float32) for v in (self.r._low, self.r._high))

    def apply(self, stream, count, footprints):
        u = stream.take(len(self.adr))
        self.engine.qpos[:count, self.adr] = self.low + (self.high - self.low) * u


class _Colors(_Twin):
    def __init__(self, *args):
        super().__init__(*args)
        t = self.r._targets
        self.targets, self.owner, self.bodies = self.tensor(t.targets), self.tensor(t.owner), len(t.bodies)

    def apply(self, stream, count, footprints):
        r = self.r
        hsv = torch.stack([self.sample(d, stream, self.bodies) for d in (r.hue, r.saturation, r.value)], -1)
        rgb = hsv_to_rgb(hsv)[:, self.owner]  # (B, geoms, 3)
        rgba = torch.cat((rgb, torch.ones_like(rgb[..., :1])), -1)
        self.engine.model_field("geom_rgba")[:count, self.targets] = rgba


class _Materials(_Twin):
    def __init__(self, *args):
        super().__init__(*args)
        t = self.r._targets
        self.targets, self.owner, self.bodies = self.tensor(t.targets), self.tensor(t.owner), len(t.bodies)
        self.mat_ids = self.tensor(self.r._mat_ids)
        self.base = self.tensor(self.r._base[t.targets])

    def apply(self, stream, count, footprints):
        u = stream.take(2 * self.bodies).view(-1, self.bodies, 2)
        n = len(self.mat_ids)
        pick = torch.floor(u[..., 1] * n).long().clamp_(max=n - 1)
        pick = torch.where(u[..., 0] < self.r.untextured_probability, -1, pick)[:, self.owner]
        value = torch.where(pick < 0, self.base, self.mat_ids[pick.clamp_min(0)])
        field = self.engine.model_field("geom_matid")
        field[:count, self.targets] = value.to(field.dtype)


class _Lights(_Twin):
    def __init__(self, *args):
        super().__init__(*args)
        self.ids = self.tensor(self.r._ids)

    def apply(self, stream, count, footprints):
        r, n = self.r, len(self.ids)
        intensity, ambient, az_deg, el_deg = (self.sample(d, stream, n).reshape(-1, n)
                                              for d in (r.intensity, r.ambient, r.azimuth_deg, r.elevation_deg))
        color = self.sample(r.color, stream, n).reshape(len(intensity), n, -1).expand(-1, n, 3)
        az, el = torch.deg2rad(az_deg), torch.deg2rad(el_deg)
        direction = torch.stack((torch.cos(el) * torch.cos(az), torch.cos(el) * torch.sin(az), -torch.sin(el)), -1)
        e = self.engine
        e.model_field("light_diffuse")[:count, self.ids] = intensity[..., None] * color
        e.model_field("light_ambient")[:count, self.ids] = ambient[..., None].expand(-1, n, 3)
        e.model_field("light_dir")[:count, self.ids] = direction


class _Jitter(_Twin):
    def __init__(self, *args):
        super().__init__(*args)
        pos, rot = self.camera._default_offset
        self.base_pos, self.base_rot = pos.to(self.device, torch.float32), rot.to(self.device, torch.float32)

    def apply(self, stream, count, footprints):
        r = self.r
        position = self.sample(r.position_m, stream, 1).reshape(-1, 3)
        rotation = torch.deg2rad(self.sample(r.rotation_deg, stream, 1).reshape(-1, 3))
        cam = self.camera
        cam._offset_pos[:count] = self.base_pos + position
        cam._offset_rot_gl[:count] = rotvec_to_mat(rotation) @ self.base_rot


class _Scatter(_Twin):
    def __init__(self, *args):
        super().__init__(*args)
        r, m = self.r, self.model
        self.n = len(r._bodies)
        self.free_index = self.tensor(r._free_index)  # (n, 7) qpos addresses
        self.rest_z = self.tensor(r._rest_z_m, torch.float32)
        self.park = self.tensor(r._park_values.reshape(-1, 7), torch.float32)
        self.radius = [footprint_radius(m, b, g) for b, g in zip(r._bodies, r._geoms)]
        self.radii = self.tensor(self.radius, torch.float32)
        (x0, y0), (x1, y1) = r.region
        self.low = self.tensor([x0, y0], torch.float32)
        self.span = self.tensor([x1 - x0, y1 - y0], torch.float32)

    def apply(self, stream, count, footprints):
        r, n = self.r, self.n
        b = len(stream.keys)
        if r.count is None:
            active = torch.ones((b, n), dtype=torch.bool, device=self.device)
        else:
            wanted = self.sample(r.count, stream, 1).reshape(-1, 1).long().clamp(0, n)
            rank = stream.take(n).argsort(-1).argsort(-1)  # a random order of the bodies, per world
            active = rank < wanted
        tries = max(1, r.max_tries)
        # every candidate pose of every body in two draws: (B, n, tries) positions and yaws
        xy = self.low + self.span * stream.take(2 * n * tries).view(b, n, tries, 2)
        yaw = self.sample(r.yaw_rad, stream, n * tries).reshape(b, n, tries)
        blocked = footprints.static_overlaps(xy, self.radii[:, None]) if r.check_collisions \
            else torch.zeros_like(yaw, dtype=torch.bool)
        picks, placed = [], []
        for j in range(n):  # in order: each body avoids those placed before it
            hit = blocked[:, j]
            if r.check_collisions and footprints.count:
                hit = hit | footprints.placed_overlaps(xy[:, j], self.radius[j])
            ok = ~hit
            first = ok.to(torch.uint8).argmax(-1, keepdim=True)  # the first candidate that fits (0 if none)
            fits = ok.any(-1) & active[:, j]
            slot = footprints.placed[:, footprints.count]
            slot[:, :2] = xy[:, j].gather(1, first[..., None].expand(b, 1, 2))[:, 0]
            slot[:, 2] = torch.where(fits, self.radius[j], 0.0)
            footprints.count += 1
            picks.append(first)
            placed.append(fits)
        first, fits = torch.stack(picks, 1), torch.stack(placed, 1)  # (B, n, 1), (B, n)
        xy = xy.gather(2, first[..., None].expand(b, n, 1, 2))[:, :, 0]
        yaw = yaw.gather(2, first)[..., 0]
        zero = torch.zeros_like(yaw)
        pose = torch.stack((xy[..., 0], xy[..., 1], self.rest_z.expand(b, n), torch.cos(0.5 * yaw), zero, zero,
                            torch.sin(0.5 * yaw)), -1)
        free = torch.where(fits[..., None], pose, self.park)
        self.engine.qpos[:count, self.free_index.reshape(-1)] = free.reshape(b, -1)


def static_boxes(model: mujoco.MjModel, qpos: np.ndarray, scatterers: list[Scatter2D]) -> np.ndarray:
    """(O, 4) plane boxes (centre x, y, half x, y) of every geom the scatterers must avoid: all but
    their own bodies' and their surfaces' geoms and planes, posed at ``qpos``, that reach below the
    tallest object's top above the surfaces (a lamp overhead is not in the way)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    movers = {int(g) for r in scatterers for geoms in r._geoms for g in geoms}
    names = [model.geom(g).name for g in range(model.ngeom)]
    surfaces = {int(g) for r in scatterers for g in match_names(names, r.surface)}
    top = max(r.surface_z_m + 2 * float(model.geom_aabb[g, 5]) for r in scatterers for gs in r._geoms for g in gs)
    bottom = min(r.surface_z_m for r in scatterers)
    out = []
    for g in range(model.ngeom):
        if g in movers or g in surfaces or model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        rot = data.geom_xmat[g].reshape(3, 3)
        centre = data.geom_xpos[g] + rot @ model.geom_aabb[g, :3]
        half = np.abs(rot) @ model.geom_aabb[g, 3:]
        if centre[2] - half[2] < top and centre[2] + half[2] > bottom + 1e-3:
            out.append([centre[0], centre[1], half[0], half[1]])
    return np.asarray(out, np.float64).reshape(-1, 4)


_TWINS = {JointRandomizer: _Joints, ColorRandomizer: _Colors, MaterialRandomizer: _Materials,
          LightRandomizer: _Lights, CameraJitter: _Jitter, Scatter2D: _Scatter}
"""Each bundled randomizer's device twin (subclasses use their base's: ``Distractors`` is a ``Scatter2D``)."""


class DeviceDraws:
    """Draws and applies a config's randomizers for all worlds of a batch on the engine's device
    (see the module docstring). Built from a ``BatchedFrameProducer``'s engine and camera."""

    def __init__(self, randomizers: list[Randomizer], engine, camera, model: mujoco.MjModel):
        self.randomizers = list(randomizers)
        self.twins = []
        for r in self.randomizers:
            twin = next((t for kind, t in _TWINS.items() if isinstance(r, kind)), None)
            if twin is None:
                raise ValueError(f"randomizer {r.name or type(r).__name__!r} ({type(r).__name__}) has no device "
                                 "twin; batches(device_draws=True) supports "
                                 f"{', '.join(k.__name__ for k in _TWINS)}: draw on the host (device_draws=False)")
            self.twins.append(twin(r, engine, camera, model))
        scatterers = [r for r in self.randomizers if isinstance(r, Scatter2D)]
        boxes = static_boxes(model, engine.initial_state["qpos"][0].detach().cpu().double().numpy(), scatterers) \
            if scatterers else np.zeros((0, 4))
        self._boxes = torch.as_tensor(boxes, dtype=torch.float32, device=engine.device)
        self._movers = sum(len(r._bodies) for r in scatterers)
        self.engine = engine

    def apply(self, seed: int, index: torch.Tensor) -> None:
        """World w gets frame ``index[w]``'s draws ((B,) int64 on the engine's device), written into
        the engine's fields and the camera's offsets; after ``Simulation.reset`` of the state."""
        count = len(index)
        footprints = Footprints(self._boxes, torch.zeros((count, self._movers, 3), device=index.device))
        # every randomizer's keys in one hash pass: (R, B), row k from (seed, k, frame block)
        blocks = [index if r.every_n_frames <= 1 else index // r.every_n_frames for r in self.randomizers]
        keys = stream_keys(seed, range(len(blocks)), blocks)
        for k, twin in enumerate(self.twins):
            stream = Stream(keys[k], prefetch=twin.slots_used)
            twin.apply(stream, count, footprints)
            twin.slots_used = stream.used


__all__ = ["DeviceDraws", "Footprints", "Stream", "hsv_to_rgb", "key_base", "mix32",
           "rotvec_to_mat", "sample", "static_boxes", "stream_keys", "uniforms"]
