"""The per-frame work of Replicator nodes, as ``ambulo.replicator`` randomizers.

Each node is a ``Randomizer``: ``sample(rng, ctx)`` draws its values for one frame (one per
target prim, as Replicator samples a distribution per prim) and returns them as JSON data;
``apply(params, ctx)`` writes them into the engine (free-joint qpos for poses, per-world
``geom_rgba``/``geom_size``/light fields, the camera's pose). ``FrameProducer`` calls them in
declaration order with a generator seeded by (global seed, node, frame // interval).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from ambulo.core.randomize import (
    CollisionChecker,
    as_generator,
    park_z,
    place_without_overlap,
    subtree_geoms,
    write_field,
)
from ambulo.replicator import Randomizer
from ambulo.replicator.randomizers import to_json
from ambulo.sensors.frames import look_at_gl
from ambulo.utils.rotations import mat_to_quat, quat_to_mat

from .distribution import draw
from .shapes import euler_xyz_deg_to_mat, geom_parts

_SCATTER_TRIES = 30


def _rows(values, n: int, width: int) -> np.ndarray:
    """``n`` draws as an (n, width) array; one number per draw is repeated across the row."""
    arr = np.asarray(values, float).reshape(n, -1)
    return np.broadcast_to(arr, (n, width)).copy() if arr.shape[1] == 1 else arr


class _FreeBodies:
    """Free-joint qpos addresses and subtree geoms of the shape prims a node targets."""

    def resolve(self, model, paths: list[str]) -> None:
        self._qadr, self._geoms = {}, {}
        for path in paths:
            body = model.body(path).id
            self._qadr[path] = int(model.jnt_qposadr[model.body_jntadr[body]])
            self._geoms[path] = subtree_geoms(model, body)

    def body_position(self, ctx, path: str) -> np.ndarray:
        adr = self._qadr[path]
        return ctx.engine.qpos[ctx.world, adr:adr + 3].numpy().copy()


@dataclass(kw_only=True)
class PoseNode(Randomizer, _FreeBodies):
    """``rep.modify.pose``: position, rotation (XYZ deg), scale of shapes; pose/aim of the camera."""

    targets: list[str]
    kinds: dict[str, str]
    camera_pose: dict[str, Any] = field(default_factory=dict)
    """The camera as created: position (3,), rot_gl (3, 3), look_at (point, prim path or None),
    and its sensor's name."""
    position: Any = None
    rotation: Any = None
    scale: Any = None
    look_at: Any = None

    def initialize(self, engine):
        shapes = [t for t in self.targets if self.kinds[t] != "camera"]
        aims = [a for a in (self.look_at, self.camera_pose.get("look_at")) if isinstance(a, str)]
        self.resolve(engine.model, shapes + aims)

    def sample(self, rng, ctx):
        g, n, out = as_generator(rng), len(self.targets), {}
        for key in ("position", "rotation", "scale"):
            value = getattr(self, key)
            if value is not None:
                out[key] = _rows(draw(value, g, n), n, 3)
        if self.look_at is not None and not isinstance(self.look_at, str):
            out["look_at"] = _rows(draw(self.look_at, g, n), n, 3)
        return to_json(out)

    def apply(self, params, ctx):
        qpos = ctx.engine.qpos[ctx.world]
        for i, path in enumerate(self.targets):
            if self.kinds[path] == "camera":
                self._apply_camera(i, params, ctx)
                continue
            adr = self._qadr[path]
            if "position" in params:
                qpos[adr:adr + 3] = torch.tensor(params["position"][i], dtype=qpos.dtype)
            if "rotation" in params:
                quat = mat_to_quat(euler_xyz_deg_to_mat(params["rotation"][i]))
                qpos[adr + 3:adr + 7] = torch.tensor(quat, dtype=qpos.dtype)
            if "scale" in params:
                self._apply_scale(ctx, path, params["scale"][i])

    def _apply_scale(self, ctx, path: str, scale) -> None:
        """Per-world sizes of the prim's geoms; a torus's capsules also move out along its ring."""
        parts = geom_parts(self.kinds[path], scale)
        sizes = ctx.engine.model_field("geom_size")
        sizes[ctx.world, self._geoms[path]] = torch.tensor(np.stack([p.size for p in parts]), dtype=sizes.dtype)
        if len(parts) > 1:
            pos = ctx.engine.model_field("geom_pos")
            pos[ctx.world, self._geoms[path]] = torch.tensor(np.stack([p.pos_m for p in parts]), dtype=pos.dtype)

    def _apply_camera(self, i, params, ctx):
        """Aim: this node's look_at or rotation; else the created look_at (re-aimed from a new
        position), else the created rotation."""
        base = self.camera_pose
        pos = np.asarray(params["position"][i]) if "position" in params else base["position"]
        if "look_at" in params:
            rot = look_at_gl(pos, params["look_at"][i])
        elif isinstance(self.look_at, str):
            rot = look_at_gl(pos, self.body_position(ctx, self.look_at))
        elif "rotation" in params:
            rot = euler_xyz_deg_to_mat(params["rotation"][i])
        elif base.get("look_at") is not None:
            aim = base["look_at"]
            rot = look_at_gl(pos, self.body_position(ctx, aim) if isinstance(aim, str) else aim)
        else:
            rot = base["rot_gl"]
        ctx.cameras[base["sensor"]].set_world_pose(pos, rot, world_ids=[ctx.world])


@dataclass(kw_only=True)
class ColorNode(Randomizer, _FreeBodies):
    """``rep.randomizer.color`` / ``materials`` / displayColor: one RGB per prim (all its geoms)."""

    targets: list[str]
    colors: Any

    def initialize(self, engine):
        self.resolve(engine.model, self.targets)

    def sample(self, rng, ctx):
        return to_json({"rgb": _rows(draw(self.colors, rng, len(self.targets)), len(self.targets), 3)})

    def apply(self, params, ctx):
        rgba = ctx.engine.model_field("geom_rgba")
        for path, rgb in zip(self.targets, params["rgb"]):
            rgba[ctx.world, self._geoms[path]] = torch.tensor([*np.clip(rgb, 0.0, 1.0), 1.0], dtype=rgba.dtype)


def light_level(intensity: float) -> float:
    """Replicator intensity (nits) -> ambulo's 0-1 light level: the default 1000 is 0.7 (ambulo's
    default sun, ``ambulo.core.scene.add_ground``); brighter lights saturate at 1."""
    return float(np.clip(0.7 * intensity / 1000.0, 0.0, 1.0))


def blackbody_rgb(kelvin) -> np.ndarray:
    """(..., 3) RGB 0-1 of a blackbody at ``kelvin`` (1000-40000 K), brightest channel 1 near and
    below 6600 K: Tanner Helland's fit to the Planckian locus in sRGB (within a few % of it),
    the tint USD's ``colorTemperature`` gives a light."""
    t = np.clip(np.asarray(kelvin, float), 1000.0, 40000.0) / 100.0
    warm = t <= 66
    r = np.where(warm, 255.0, 329.698727446 * np.maximum(t - 60, 1e-9) ** -0.1332047592)
    g = np.where(warm, 99.4708025861 * np.log(t) - 161.1195681661,
                 288.1221695283 * np.maximum(t - 60, 1e-9) ** -0.0755148492)
    b = np.where(t >= 66, 255.0, np.where(t <= 19, 0.0, 138.5177312231 * np.log(np.maximum(t - 10, 1e-9))
                                           - 305.0447927307))
    return np.clip(np.stack([r, g, b], -1) / 255.0, 0.0, 1.0)


@dataclass(kw_only=True)
class LightNode(Randomizer):
    """Lights' drawn attributes (``rep.create.light`` with distributions, ``rep.modify.attribute``):
    per-world light diffuse (ambient for dome), position (``light_pos``) and direction (``light_dir``)."""

    targets: list[str]
    base: dict[str, dict]
    """Per light: light_type, intensity, color, temperature (K or None) as created."""
    intensity: Any = None
    color: Any = None
    temperature: Any = None
    position: Any = None
    rotation: Any = None

    def initialize(self, engine):
        self._ids = [engine.model.light(path).id for path in self.targets]

    def sample(self, rng, ctx):
        g, n, out = as_generator(rng), len(self.targets), {}
        for key in ("intensity", "temperature"):
            if getattr(self, key) is not None:
                out[key] = np.asarray(draw(getattr(self, key), g, n), float).reshape(n)
        for key in ("color", "position", "rotation"):
            if getattr(self, key) is not None:
                out[key] = _rows(draw(getattr(self, key), g, n), n, 3)
        return to_json(out)

    def apply(self, params, ctx):
        diffuse, ambient = ctx.engine.model_field("light_diffuse"), ctx.engine.model_field("light_ambient")
        for i, (path, lid) in enumerate(zip(self.targets, self._ids)):
            base = self.base[path]
            level = light_level(params["intensity"][i] if "intensity" in params else base["intensity"])
            color = np.asarray(params["color"][i] if "color" in params else base["color"], float)
            kelvin = params["temperature"][i] if "temperature" in params else base.get("temperature")
            if kelvin is not None:
                color = color * blackbody_rgb(kelvin)
            field_ = ambient if base["light_type"] == "dome" else diffuse
            field_[ctx.world, lid] = torch.tensor(level * np.clip(color, 0, 1), dtype=field_.dtype)
            if "position" in params:
                pos = ctx.engine.model_field("light_pos")
                pos[ctx.world, lid] = torch.tensor(params["position"][i], dtype=pos.dtype)
            if "rotation" in params:  # USD lights shine along their -z
                direction = euler_xyz_deg_to_mat(params["rotation"][i]) @ np.array([0.0, 0.0, -1.0])
                dir_ = ctx.engine.model_field("light_dir")
                dir_[ctx.world, lid] = torch.tensor(direction, dtype=dir_.dtype)


@dataclass(kw_only=True)
class ScatterNode(Randomizer, _FreeBodies):
    """``rep.randomizer.scatter_2d``: prim origins at uniform points of the planes' top faces."""

    targets: list[str]
    surfaces: list[str]
    offset: float = 0.0
    check_for_collisions: bool = False

    def initialize(self, engine):
        m = engine.model
        self.resolve(m, self.targets + self.surfaces)
        surface_geoms = np.concatenate([self._geoms[s] for s in self.surfaces])
        self._checker = CollisionChecker(m, surface_geoms) if self.check_for_collisions else None
        self._bodies = {t: m.body(t).id for t in self.targets}

    def sample(self, rng, ctx):
        g = as_generator(rng)
        qpos = ctx.engine.qpos[ctx.world].numpy().copy()
        sizes = ctx.engine.model_field("geom_size")[ctx.world].numpy()
        adr = np.asarray([self._qadr[p] for p in self.surfaces])
        origins = qpos[adr[:, None] + np.arange(3)]  # (P, 3) plane centres, world frame
        rots = quat_to_mat(qpos[adr[:, None] + np.arange(3, 7)])  # (P, 3, 3)
        halves = sizes[[self._geoms[p][0] for p in self.surfaces], :2]  # (P, 2) half extents, m
        areas = torch.as_tensor(4 * halves[:, 0] * halves[:, 1])
        target_adr = np.asarray([self._qadr[t] for t in self.targets])
        positions = np.zeros((len(self.targets), 3))

        def place(todo: list[int]) -> None:
            """A plane per prim (by area), then a uniform point of its top face, ``offset`` above it."""
            k = len(todo)
            plane = torch.multinomial(areas, k, replacement=True, generator=g).numpy()
            u = torch.rand((k, 2), generator=g, dtype=torch.float64).numpy()
            local = np.concatenate([(2 * u - 1) * halves[plane], np.full((k, 1), self.offset)], 1)
            positions[todo] = origins[plane] + np.einsum("kij,kj->ki", rots[plane], local)
            qpos[target_adr[todo][:, None] + np.arange(3)] = positions[todo]

        roots = [self._bodies[t] for t in self.targets]
        hidden = place_without_overlap(range(len(self.targets)), roots, qpos, place, self._checker, _SCATTER_TRIES)
        for i in hidden:  # still overlapping: out of view, as ambulo's Scatter2D does
            positions[i] = [0.0, 0.0, park_z(roots[i])]
        return {"position": {t: positions[i].tolist() for i, t in enumerate(self.targets)},
                "hidden": [self.targets[i] for i in hidden]}

    def apply(self, params, ctx):
        paths = list(params["position"])
        index = (np.asarray([self._qadr[p] for p in paths])[:, None] + np.arange(3)).reshape(-1)
        write_field(ctx.engine.qpos, [np.asarray([params["position"][p] for p in paths]).reshape(-1)],
                    rows=ctx.world, index=index)
