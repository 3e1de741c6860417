"""Domain randomizers: declarative dataclasses, each a pure ``sample`` then an ``apply``.

``sample(rng, ctx)`` draws a frame's parameters as plain JSON data (the frame
log); ``apply(params, ctx)`` writes them into the engine's world 0. Applying a
logged dict reproduces the frame without drawing anything, which is how a
single frame is regenerated. ``every_n_frames`` keeps parameters for blocks of
frames (drawn from the block's own seed, so any frame can still start a run).

The distributions and writes are ``ambulo.core.randomize``'s, the layer the RL task events use too:
``sample`` draws from the ``numpy`` generator the producer hands it for (seed, randomizer, frame)
(``streams.frame_rng``) with NumPy (``Distribution.sample_host``: no torch dispatch on the host),
every value of a kind in one batch; ``apply`` writes each field once (``write_field``), with world
``ctx.world`` as the row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ambulo.core import Entity, match_names
from ambulo.core.randomize import (
    BodyGeoms,
    Columns,
    Distribution,
    as_distribution,
    joint_range_box,
    normal,
    uniform,
    write_field,
)
from ambulo.core.randomize.fields import entity_qpos_ids
from ambulo.robots import humanoid
from ambulo.utils.rotations import mat_to_quat
from ambulo.utils.validate import Checked


@dataclass
class SceneContext:
    """What ``sample``/``apply`` act on: the compiled model, the engine (world 0) and the cameras."""

    model: mujoco.MjModel
    engine: object
    cameras: dict
    world: int = 0


def to_json(value):
    if isinstance(value, torch.Tensor):
        return value.tolist()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    return value


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
        self._ids = np.asarray(match_names(names, self.lights), np.int64)
        if not len(self._ids):
            raise ValueError(f"{self.name}: no light matches {self.lights!r}; lights: {names}")
        self._scalars = Columns((self.intensity, self.ambient, self.azimuth_deg, self.elevation_deg))
        self._color = as_distribution(self.color)

    def sample(self, rng, ctx):
        n = len(self._ids)
        # the four scalar draws of every light in one batch, then the colours; a scene has a few
        # lights, so the rest is plain float arithmetic
        scalars = self._scalars.sample_host(rng, n)
        colors = np.broadcast_to(self._color.sample_host(rng, n).reshape(n, -1), (n, 3))
        out = []
        for (intensity, ambient, az_deg, el_deg), color in zip(scalars.tolist(), colors.tolist()):
            az, el = math.radians(az_deg), math.radians(el_deg)
            out.append({"diffuse": [intensity * c for c in color], "ambient": ambient,
                        "dir": [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)]})
        return {"lights": out}

    def apply(self, params, ctx):
        lights = params["lights"][:len(self._ids)]
        ids = self._ids[:len(lights)]
        engine = ctx.engine
        write_field(engine.model_field("light_diffuse"), [[p["diffuse"] for p in lights]], rows=ctx.world, index=ids)
        # one number for the light's three ambient components
        write_field(engine.model_field("light_ambient"), [[[p["ambient"]] for p in lights]], rows=ctx.world,
                    index=ids)
        write_field(engine.model_field("light_dir"), [[p["dir"] for p in lights]], rows=ctx.world, index=ids)


@dataclass(kw_only=True)
class ColorRandomizer(Randomizer):
    """One random colour per matched body (all geoms of its subtree), drawn in HSV."""

    prims: str
    hue: Distribution = field(default_factory=lambda: uniform(0.0, 1.0))
    saturation: Distribution = field(default_factory=lambda: uniform(0.2, 0.9))
    value: Distribution = field(default_factory=lambda: uniform(0.35, 1.0))

    def initialize(self, engine):
        self._targets = BodyGeoms.resolve(engine.model, self.prims, self.name)
        self._hsv = Columns((self.hue, self.saturation, self.value))

    def sample(self, rng, ctx):
        hsv = self._hsv.sample_host(rng, len(self._targets.bodies))
        return {"rgba": [hsv_to_rgb(h, s, v) + [1.0] for h, s, v in hsv.tolist()]}

    def apply(self, params, ctx):
        colors = np.asarray(params["rgba"], np.float64).reshape(1, -1, 4)
        self._targets.write(ctx.engine.model_field("geom_rgba"), colors, rows=ctx.world)


def hsv_to_rgb(h: float, s: float, v: float) -> list[float]:
    """RGB of one HSV colour, all in [0, 1] (a frame colours a few bodies: plain floats are cheapest)."""
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
        self._targets = BodyGeoms.resolve(engine.model, self.prims, self.name)
        self._mat_ids = np.asarray([engine.model.material(n).id for n in self._names], np.int64)
        self._base = engine.model.geom_matid.copy()

    def sample(self, rng, ctx):
        # per body: untextured with the given probability, else a uniform palette entry
        u = rng.random((len(self._targets.bodies), 2))
        pick = np.minimum((u[:, 1] * len(self._mat_ids)).astype(np.int64), len(self._mat_ids) - 1)
        return {"palette_index": np.where(u[:, 0] < self.untextured_probability, -1, pick).tolist()}

    def apply(self, params, ctx):
        t = self._targets
        pick = np.asarray(params["palette_index"], np.int64)[t.owner]
        value = np.where(pick < 0, self._base[t.targets], self._mat_ids[np.maximum(pick, 0)])
        write_field(ctx.engine.model_field("geom_matid"), value[None], rows=ctx.world, index=t.targets)


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
        self._position_m, self._rotation_deg = as_distribution(self.position_m), as_distribution(self.rotation_deg)

    def sample(self, rng, ctx):
        position_m = self._position_m.sample_host(rng).tolist()
        return {"position_m": position_m, "rotation_deg": self._rotation_deg.sample_host(rng).tolist()}

    def apply(self, params, ctx):
        cam = ctx.cameras[self.camera]
        base_pos, base_quat = self._base_offset(cam)
        # the jitter's rotation (a rotation vector, deg) as a quaternion, composed with the offset's:
        # q_jitter * q_base is R(rotvec) @ R_base, in a few float operations and one C call (the
        # matrices' Rodrigues and product were ~50 NumPy calls a frame)
        rx, ry, rz = (math.radians(a) for a in params["rotation_deg"])
        angle = math.sqrt(rx * rx + ry * ry + rz * rz)
        s = math.sin(0.5 * angle) / angle if angle > 0 else 0.5  # sin(a/2)/a -> 1/2 as a -> 0
        quat = np.empty(4)
        mujoco.mju_mulQuat(quat, np.array([math.cos(0.5 * angle), rx * s, ry * s, rz * s]), base_quat)
        pos = params["position_m"]
        cam.set_local_pose([base_pos[0] + pos[0], base_pos[1] + pos[1], base_pos[2] + pos[2]], quat,
                           convention="opengl", world_ids=[ctx.world])

    def _base_offset(self, cam) -> tuple[list[float], np.ndarray]:
        """The camera's configured offset: position (m, mount frame) as floats and its OpenGL axes as a
        (4,) quaternion, from NumPy on the CPU camera or device tensors on the TiledCamera of the
        batched GPU path; kept while the camera's offset is the same object (arrays and tensors, which
        pickle with the config, unlike the camera)."""
        offset, cached = cam._default_offset, getattr(self, "_base", None)
        if cached is None or cached[0] is not offset:
            base_pos, base_rot = (np.asarray(torch.as_tensor(v).cpu(), np.float64) for v in offset)
            cached = self._base = (offset, base_pos.tolist(), mat_to_quat(base_rot))
        return cached[1], cached[2]


@dataclass(kw_only=True)
class JointRandomizer(Randomizer):
    """Hinge/slide joint positions of the robot at ``prim_path``, uniform in a fraction of each
    joint's range; the joints are the robot's ``Entity`` joints whose names match ``joints``."""

    joints: str
    """Glob on joint names relative to ``prim_path`` (``*shoulder*``)."""
    prim_path: str = humanoid.PRIM_PATH  # the bundled humanoid, where the scenes place it
    range_fraction: float = 0.5
    """1 uses the whole limited range; unlimited joints use +-range_fraction * pi."""

    def initialize(self, engine):
        robot = Entity(engine, self.prim_path, require_drives=False)
        picked = match_names(robot.joint_names, self.joints)
        if not picked:
            raise ValueError(f"{self.name}: no hinge/slide joint of {self.prim_path} matches {self.joints!r}; "
                             f"joints: {robot.joint_names}")
        self._qpos_adr = entity_qpos_ids(robot)[picked]
        self._low, self._high = joint_range_box(robot, self.range_fraction, picked)

    def sample(self, rng, ctx):
        u = rng.random(len(self._qpos_adr))
        return {"qpos": (self._low + (self._high - self._low) * u).tolist()}

    def apply(self, params, ctx):
        write_field(ctx.engine.qpos, [params["qpos"]], rows=ctx.world, index=self._qpos_adr)
