"""Domain randomizers: declarative dataclasses, each a pure ``sample`` then an ``apply``.

``sample(rng, ctx)`` draws a frame's parameters as plain JSON data (the frame
log); ``apply(params, ctx)`` writes them into the engine's world 0. Applying a
logged dict reproduces the frame without drawing anything, which is how a
single frame is regenerated. ``every_n_frames`` keeps parameters for blocks of
frames (drawn from the block's own seed, so any frame can still start a run).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ambulo.core import match_names
from ambulo.utils.rotations import mat_to_quat, rot_about_axes
from ambulo.utils.validate import Checked

from .distributions import Distribution, as_distribution, draw_rows, normal, uniform


@dataclass
class SceneContext:
    """What ``sample``/``apply`` act on: the compiled model, the engine (world 0) and the cameras."""

    model: mujoco.MjModel
    engine: object
    cameras: dict
    world: int = 0


def match_bodies(model: mujoco.MjModel, pattern: str) -> list[int]:
    """Body ids (not the world body) whose name matches glob ``pattern`` (whole name or last
    path component)."""
    return [b + 1 for b in match_names([model.body(b).name for b in range(1, model.nbody)], pattern)]


def subtree_geoms(model: mujoco.MjModel, body: int) -> np.ndarray:
    """Geoms of ``body`` and all its descendants."""
    inside = np.zeros(model.nbody, bool)
    inside[body] = True
    for b in range(body + 1, model.nbody):  # parents precede children
        inside[b] = inside[model.body_parentid[b]]
    return np.flatnonzero(inside[model.geom_bodyid])


def to_json(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    return value


def _geoms_by_body(ngeom: int, geoms_per_body: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Every geom of the bodies' subtrees once, and the body whose value it takes: the last
    body listing it, as a loop writing body after body would leave it."""
    owner = np.full(ngeom, -1, np.int64)
    for k, geoms in enumerate(geoms_per_body):
        owner[geoms] = k
    targets = np.flatnonzero(owner >= 0)
    return targets, owner[targets]


def _put(field: torch.Tensor, world: int, index, values) -> None:
    """``field[world, index] = values`` in one write: through a NumPy view for host tensors
    (a tenth of torch's cost per call), else on the field's device."""
    if field.device.type == "cpu":
        field.numpy()[world, index] = values
        return
    field[world, torch.as_tensor(np.asarray(index), device=field.device)] = torch.as_tensor(
        np.asarray(values), dtype=field.dtype, device=field.device)


@dataclass(kw_only=True)
class Randomizer(Checked):
    """Base: a name for the frame log and how often new values are drawn.

    A lifecycle component (``ambulo.core.Component``): ``build(spec)`` adds what it needs to
    the scene, ``initialize(engine)`` resolves names in ``engine.model``; ``update`` and
    ``reset`` do nothing (a frame's parameters are applied by the generator).
    """

    name: str = ""
    every_n_frames: int = 1

    def build(self, spec: mujoco.MjSpec) -> None:
        """Add what the randomizer needs to the scene before compilation (default: nothing)."""

    def initialize(self, engine) -> None:
        """Resolve names to ids in ``engine.model``."""

    def update(self, dt_s: float) -> None:
        """Nothing: randomizers act per frame through ``apply``."""

    def reset(self, world_ids=None) -> None:
        """Nothing: the generator applies each frame's parameters after a reset."""

    def sample(self, rng: np.random.Generator, ctx: SceneContext) -> dict:
        raise NotImplementedError

    def apply(self, params: dict, ctx: SceneContext) -> None:
        raise NotImplementedError


@dataclass(kw_only=True)
class LightRandomizer(Randomizer):
    """Light colour, intensity and direction (azimuth/elevation of the light's aim)."""

    lights: str = "*"
    intensity: Distribution = field(default_factory=lambda: uniform(0.35, 0.9))
    color: Distribution = field(default_factory=lambda: uniform((0.8, 0.8, 0.75), (1.0, 1.0, 1.0)))
    ambient: Distribution = field(default_factory=lambda: uniform(0.15, 0.3))
    azimuth_deg: Distribution = field(default_factory=lambda: uniform(-180.0, 180.0))
    elevation_deg: Distribution = field(default_factory=lambda: uniform(30.0, 75.0))

    def initialize(self, engine):
        names = [engine.model.light(i).name for i in range(engine.model.nlight)]
        self._ids = match_names(names, self.lights)
        if not self._ids:
            raise ValueError(f"{self.name}: no light matches {self.lights!r}; lights: {names}")

    def sample(self, rng, ctx):
        out = []
        for _ in self._ids:
            intensity = float(as_distribution(self.intensity).sample(rng))
            color = as_distribution(self.color).sample(rng)
            az, el = np.radians(as_distribution(self.azimuth_deg).sample(rng)), np.radians(
                as_distribution(self.elevation_deg).sample(rng))
            direction = [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)]
            out.append({"diffuse": intensity * np.asarray(color), "ambient": float(as_distribution(self.ambient).sample(rng)),
                        "dir": direction})
        return to_json({"lights": out})

    def apply(self, params, ctx):
        lights = params["lights"][:len(self._ids)]
        ids = self._ids[:len(lights)]
        _put(ctx.engine.model_field("light_diffuse"), ctx.world, ids, [p["diffuse"] for p in lights])
        # one number for the light's three ambient components
        _put(ctx.engine.model_field("light_ambient"), ctx.world, ids, [[p["ambient"]] for p in lights])
        _put(ctx.engine.model_field("light_dir"), ctx.world, ids, [p["dir"] for p in lights])


@dataclass(kw_only=True)
class ColorRandomizer(Randomizer):
    """One random colour per matched body (all geoms of its subtree), drawn in HSV."""

    prims: str
    hue: Distribution = field(default_factory=lambda: uniform(0.0, 1.0))
    saturation: Distribution = field(default_factory=lambda: uniform(0.2, 0.9))
    value: Distribution = field(default_factory=lambda: uniform(0.35, 1.0))

    def initialize(self, engine):
        self._bodies = match_bodies(engine.model, self.prims)
        if not self._bodies:
            raise ValueError(f"{self.name}: no body matches {self.prims!r}")
        self._geoms = [subtree_geoms(engine.model, b) for b in self._bodies]
        self._targets, self._body_of = _geoms_by_body(engine.model.ngeom, self._geoms)

    def sample(self, rng, ctx):
        hsv = draw_rows(rng, (self.hue, self.saturation, self.value), len(self._bodies))
        return {"rgba": [_hsv_to_rgb(h, s, v) + [1.0] for h, s, v in hsv]}

    def apply(self, params, ctx):
        colors = np.asarray(params["rgba"], np.float64).reshape(-1, 4)
        if len(colors) == len(self._geoms):  # one write for every geom (what the per-body loop wrote)
            _put(ctx.engine.model_field("geom_rgba"), ctx.world, self._targets, colors[self._body_of])
            return
        rgba = ctx.engine.model_field("geom_rgba")
        for geoms, color in zip(self._geoms, params["rgba"]):
            rgba[ctx.world, geoms] = torch.tensor(color, dtype=rgba.dtype)


def _hsv_to_rgb(h: float, s: float, v: float) -> list[float]:
    i = int(h * 6.0) % 6
    f = h * 6.0 - int(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    return [[v, t, p], [q, v, p], [p, v, t], [p, q, v], [t, p, v], [v, p, q]][i]


@dataclass(kw_only=True)
class MaterialRandomizer(Randomizer):
    """Textured materials (checker, gradient, noise) assigned per matched body.

    ``_build`` adds a palette of ``palette_size`` procedural textures whose
    colours come from ``palette_seed`` (the palette is part of the scene, the
    same for every frame); each frame picks a palette entry or none per body.
    """

    prims: str
    palette_size: int = 8
    palette_seed: int = 0
    untextured_probability: float = 0.3

    def build(self, spec):
        rng = np.random.default_rng(self.palette_seed)
        builtins = [mujoco.mjtBuiltin.mjBUILTIN_CHECKER, mujoco.mjtBuiltin.mjBUILTIN_GRADIENT]
        self._names = []
        for i in range(self.palette_size):
            name = f"{self.name or 'material'}_palette_{i}"
            spec.add_texture(name=name, type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=builtins[i % 2],
                             rgb1=rng.uniform(0.1, 1.0, 3).tolist(), rgb2=rng.uniform(0.1, 1.0, 3).tolist(),
                             width=64, height=64, mark=mujoco.mjtMark.mjMARK_RANDOM if i % 3 == 2 else 0,
                             random=0.1, markrgb=rng.uniform(0, 1, 3).tolist())
            mat = spec.add_material(name=name, texrepeat=[2, 2], texuniform=True,
                                    specular=float(rng.uniform(0.1, 0.6)), shininess=float(rng.uniform(0.1, 0.8)))
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = name
            self._names.append(name)

    def initialize(self, engine):
        self._bodies = match_bodies(engine.model, self.prims)
        if not self._bodies:
            raise ValueError(f"{self.name}: no body matches {self.prims!r}")
        self._geoms = [subtree_geoms(engine.model, b) for b in self._bodies]
        self._mat_ids = [engine.model.material(n).id for n in self._names]
        self._base = engine.model.geom_matid.copy()
        self._targets, self._body_of = _geoms_by_body(engine.model.ngeom, self._geoms)

    def sample(self, rng, ctx):
        picks = []
        for _ in self._bodies:
            plain = rng.uniform() < self.untextured_probability
            picks.append(-1 if plain else int(rng.integers(len(self._mat_ids))))
        return {"palette_index": picks}

    def apply(self, params, ctx):
        picks = np.asarray(params["palette_index"], np.int64)
        if len(picks) == len(self._geoms):  # one write for every geom (what the per-body loop wrote)
            pick = picks[self._body_of]
            value = np.where(pick < 0, self._base[self._targets], np.asarray(self._mat_ids)[np.maximum(pick, 0)])
            _put(ctx.engine.model_field("geom_matid"), ctx.world, self._targets, value)
            return
        matid = ctx.engine.model_field("geom_matid")
        for geoms, pick in zip(self._geoms, params["palette_index"]):
            value = self._base[geoms] if pick < 0 else np.full(len(geoms), self._mat_ids[pick])
            matid[ctx.world, geoms] = torch.as_tensor(value, dtype=matid.dtype)


@dataclass(kw_only=True)
class CameraJitter(Randomizer):
    """Perturb a camera around its mount offset: position (m, mount frame) and rotation (deg)."""

    camera: str
    position_m: Distribution = field(default_factory=lambda: normal((0, 0, 0), (0.02, 0.02, 0.02)))
    rotation_deg: Distribution = field(default_factory=lambda: normal((0, 0, 0), (3.0, 3.0, 3.0)))

    def initialize(self, engine):
        cameras = [engine.model.camera(i).name for i in range(engine.model.ncam)]
        if self.camera not in cameras:
            raise ValueError(f"{self.name}: no camera {self.camera!r}; cameras: {cameras}")

    def sample(self, rng, ctx):
        return to_json({"position_m": as_distribution(self.position_m).sample(rng),
                        "rotation_deg": as_distribution(self.rotation_deg).sample(rng)})

    def apply(self, params, ctx):
        cam = ctx.cameras[self.camera]
        base_pos, base_rot = cam._default_offset
        rot = rot_about_axes(np.radians(params["rotation_deg"])) @ base_rot
        cam.set_local_pose(base_pos + np.asarray(params["position_m"]), mat_to_quat(rot),
                           convention="opengl", world_ids=[ctx.world])


@dataclass(kw_only=True)
class JointRandomizer(Randomizer):
    """Hinge/slide joint positions drawn uniformly from a fraction of each joint's range."""

    joints: str
    range_fraction: float = 0.5
    """1 uses the whole limited range; unlimited joints use +-range_fraction * pi."""

    def initialize(self, engine):
        m = engine.model
        kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        matched = set(match_names([m.joint(j).name for j in range(m.njnt)], self.joints))
        self._joints = [j for j in range(m.njnt) if m.jnt_type[j] in kinds and j in matched]
        if not self._joints:
            raise ValueError(f"{self.name}: no hinge/slide joint matches {self.joints!r}")
        self._adr = m.jnt_qposadr[self._joints]
        lo, hi = m.jnt_range[self._joints].T
        limited = m.jnt_limited[self._joints].astype(bool)
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        self._low = np.where(limited, mid - self.range_fraction * half, -self.range_fraction * np.pi)
        self._high = np.where(limited, mid + self.range_fraction * half, self.range_fraction * np.pi)

    def sample(self, rng, ctx):
        return {"qpos": rng.uniform(self._low, self._high).tolist()}

    def apply(self, params, ctx):
        _put(ctx.engine.qpos, ctx.world, self._adr, params["qpos"])


def quat_yaw(yaw: float) -> list[float]:
    return [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))]
