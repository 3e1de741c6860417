"""Domain randomization of a navigation world, switched by one flag (``RandomizationCfg.enabled``).

What changes, and where (all cheap; nothing is re-rendered or re-compiled during an episode):

- at build (the ``MjSpec``, before it compiles): sliding friction of every environment geom,
  the mass of every robot geom (so each body's mass and inertia), the intensity and colour of
  every light, and every material's colour tint, pattern scale (``texrepeat``) and specularity;
  every image texture (a PNG among the spec's assets, as the apartments' procedural ones are)
  redrawn with its own contrast and brightness, so the surfaces the odometry tracks range from
  faint to bold;
- during the episode: pushes, a horizontal velocity added to the pelvis at random times;
- in the sensors: depth noise growing with range, depth drop-outs, RGB pixel noise.

Every draw comes from one generator seeded with the world's seed, so a seed replays its world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import torch

from ..utils.validate import Checked


@dataclass(kw_only=True)
class RandomizationCfg(Checked):
    """Ranges of the randomization; all ignored unless ``enabled``."""

    enabled: bool = False
    friction_scale_range: tuple[float, float] = (0.6, 1.3)
    """Factor on each environment geom's sliding friction (the floor's 1.0 becomes 0.6..1.3)."""
    robot_mass_scale_range: tuple[float, float] = (0.9, 1.1)
    """Factor on each robot geom's mass, drawn per geom."""
    light_scale_range: tuple[float, float] = (0.6, 1.4)
    """Factor on each light's diffuse intensity."""
    light_colour_range: tuple[float, float] = (0.85, 1.15)
    """Factor on each colour channel of each light (warm to cool lamps)."""
    tint_range: tuple[float, float] = (0.7, 1.3)
    """Factor on each colour channel of each material."""
    texture_scale_range: tuple[float, float] = (0.75, 1.33)
    """Factor on each material's texture repeats: its pattern 0.75-1.33 times as fine."""
    specular_range: tuple[float, float] = (0.0, 0.5)
    """Each material's specular reflectance, drawn."""
    texture_contrast_range: tuple[float, float] = (0.6, 1.4)
    """Factor on each image texture's deviation from its mean colour (its contrast)."""
    texture_brightness_range: tuple[float, float] = (0.8, 1.15)
    """Factor on each image texture's brightness."""
    push_interval_s_range: tuple[float, float] = (4.0, 8.0)
    """Time between two pushes, s."""
    push_speed_m_s: float = 0.3
    """Horizontal speed a push adds to the pelvis, m/s (direction uniform)."""
    depth_noise_fraction: float = 0.01
    """Depth noise std as a fraction of the range (1 % of z)."""
    depth_dropout_probability: float = 0.01
    """Chance that a depth pixel reads 0 (no return)."""
    rgb_noise_std: float = 3.0
    """Std of the additive RGB noise, in 0..255 levels."""


class Randomizer:
    """Applies ``RandomizationCfg`` to one world (module docstring)."""

    def __init__(self, cfg: RandomizationCfg, seed: int):
        self.cfg = cfg
        self.rng = np.random.default_rng([int(seed), 24])
        self._next_push_s = math.inf
        self.pushes: list[tuple[float, float, float]] = []
        """(time s, vx m/s, vy m/s) of every push so far."""

    def edit_spec(self, spec: mujoco.MjSpec, robot_prefix: str) -> None:
        """Friction, robot masses, lights and tints, drawn into the spec before it compiles."""
        if not self.cfg.enabled:
            return
        c, rng = self.cfg, self.rng
        robot_bodies = [b for b in spec.bodies if b.name.startswith(robot_prefix + "/")]
        robot_geoms = {id(g) for b in robot_bodies for g in b.geoms}
        for g in spec.geoms:
            if id(g) in robot_geoms:
                if g.mass > 0:
                    g.mass = float(g.mass * rng.uniform(*c.robot_mass_scale_range))
            else:
                friction = list(g.friction)
                friction[0] *= float(rng.uniform(*c.friction_scale_range))
                g.friction = friction
        for light in spec.lights:
            scale = rng.uniform(*c.light_scale_range) * rng.uniform(*c.light_colour_range, size=3)
            light.diffuse = list(np.clip(np.asarray(light.diffuse) * scale, 0.0, 1.0))
        for material in spec.materials:
            rgba = np.asarray(material.rgba, float)
            rgba[:3] = np.clip(rgba[:3] * rng.uniform(*c.tint_range, size=3), 0.0, 1.0)
            material.rgba = list(rgba)
            material.texrepeat = list(np.asarray(material.texrepeat, float) * rng.uniform(*c.texture_scale_range))
            material.specular = float(rng.uniform(*c.specular_range))
        self._redraw_textures(spec)

    def _redraw_textures(self, spec: mujoco.MjSpec) -> None:
        """Each PNG texture among ``spec.assets`` with its contrast and brightness drawn, stored
        under a new file name (MuJoCo caches decoded assets by name, so the old one must not be
        reused); builtin textures and files on disk are left as they are."""
        import imageio.v3 as iio

        c, rng, assets = self.cfg, self.rng, spec.assets
        for texture in spec.textures:
            data = assets.get(texture.file) if texture.file.lower().endswith(".png") else None
            if data is None:
                continue
            image = iio.imread(data).astype(np.float32)
            mean = image.mean(axis=(0, 1), keepdims=True)
            contrast, brightness = rng.uniform(*c.texture_contrast_range), rng.uniform(*c.texture_brightness_range)
            image = np.clip((mean + (image - mean) * contrast) * brightness, 0, 255).astype(np.uint8)
            file = texture.file[:-4] + f"_dr{int(rng.integers(1 << 30))}.png"
            spec.assets[file] = iio.imwrite("<bytes>", image, extension=".png", compress_level=1)
            if sum(t.file == texture.file for t in spec.textures) == 1:
                del spec.assets[texture.file]
            texture.file = file

    def initialize(self, world) -> None:
        self.pushes = []
        self._next_push_s = self._draw_interval() if self.cfg.enabled else math.inf

    def _draw_interval(self) -> float:
        return float(self.rng.uniform(*self.cfg.push_interval_s_range))

    def before_step(self, world) -> None:
        """A push when one is due (a float compare per step otherwise)."""
        if world.engine.field("time")[0] < self._next_push_s:
            return
        now = world.time_s
        angle = float(self.rng.uniform(-math.pi, math.pi))
        push = self.cfg.push_speed_m_s * np.array([math.cos(angle), math.sin(angle)])
        vel = world.robot.data.root_lin_vel_w.clone()
        vel[:, :2] += torch.as_tensor(push, dtype=vel.dtype)
        world.robot.write_root_velocity(lin_vel_w=vel)
        self.pushes.append((now, float(push[0]), float(push[1])))
        self._next_push_s = now + self._draw_interval()

    def noisy_images(self, rgb: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensor noise on one frame (returned as new arrays when enabled, as given otherwise)."""
        if not self.cfg.enabled:
            return rgb, depth
        c, rng = self.cfg, self.rng
        depth = depth * (1.0 + c.depth_noise_fraction * rng.standard_normal(depth.shape).astype(np.float32))
        depth[rng.random(depth.shape) < c.depth_dropout_probability] = 0.0
        noisy = rgb.astype(np.float32) + c.rgb_noise_std * rng.standard_normal(rgb.shape).astype(np.float32)
        return np.clip(noisy, 0, 255).astype(np.uint8), depth.astype(np.float32)


__all__ = ["RandomizationCfg", "Randomizer"]
