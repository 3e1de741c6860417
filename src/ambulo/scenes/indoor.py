"""A seeded indoor scene to test perception on: a room with a central island, furniture along
the walls, textured surfaces rich enough for ORB features, moving boxes, and the bundled humanoid.

Built with the one scene builder (``ambulo.core.scene``: ``new_scene``, ``add_ground``,
``add_light``, ``add_robot``), z up, metres, bodies named by prim path. Every static solid is
also returned as an oriented box (``SolidBox``) so tests and benchmarks can build exact ground
truth (Open3D's ``RaycastingScene``, an analytic occupancy grid) from the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ambulo.core import GroundCfg, RobotCfg, add_ground, add_light, add_robot, new_scene
from ambulo.robots import humanoid
from ambulo.utils.validate import Checked


@dataclass(frozen=True)
class SolidBox:
    """An oriented box in the world: what the scene renders and what ground truth is built from."""

    name: str
    center_m: tuple[float, float, float]
    """World position of the box centre, m."""
    half_m: tuple[float, float, float]
    """Half extents along the box's own x, y, z, m."""
    yaw_rad: float = 0.0
    """Rotation about world z."""

    def rotation(self) -> np.ndarray:
        """(3, 3) float64 box axes in the world."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def contains(self, points_w: np.ndarray) -> np.ndarray:
        """(N,) bool: which of the (N, 3) world points lie inside the box."""
        local = (np.asarray(points_w, float) - self.center_m) @ self.rotation()
        return np.all(np.abs(local) <= self.half_m, axis=-1)


def with_floor(solids: list[SolidBox], floor_half_m: float | None) -> list[SolidBox]:
    """``solids`` plus, unless ``floor_half_m`` is None, a floor slab 10 cm thick whose top face is z = 0
    (what the ground truth of a scene is built from: meshes for Open3D, boxes for the ray caster)."""
    if floor_half_m is None:
        return list(solids)
    return [*solids, SolidBox("floor", (0.0, 0.0, -0.05), (floor_half_m, floor_half_m, 0.05))]


@dataclass(kw_only=True)
class IndoorSceneCfg(Checked):
    """Size, clutter and seed of the indoor scene."""

    seed: int = 0
    """Seeds furniture placement, textures and box motion: the same seed, the same scene."""
    room_m: tuple[float, float] = (8.0, 6.0)
    """Inner room extent along x and y, m; the room is centred on the origin."""
    wall_height_m: float = 2.5
    num_furniture: int = 8
    """Cabinets, tables and shelves placed along the walls."""
    num_moving_boxes: int = 2
    """Boxes (mocap bodies) that slide back and forth; see ``IndoorScene.box_positions``."""
    texture_px: int = 512
    """Side of each procedural texture image, px."""
    with_robot: bool = True
    """Add the bundled humanoid at ``robots.humanoid.PRIM_PATH`` (its head carries the camera)."""


@dataclass
class IndoorScene:
    """What ``build_indoor_scene`` made: the spec and its geometry in numbers."""

    spec: mujoco.MjSpec
    cfg: IndoorSceneCfg
    solids: list[SolidBox]
    """Static boxes (walls, island, furniture); the floor is the plane z = 0."""
    moving: list[SolidBox]
    """Moving boxes at their start poses; the body of box k is ``moving[k].name``."""
    motion: np.ndarray = field(repr=False)
    """(K, 4) per moving box: x amplitude, y amplitude (m), speed (m/s), phase (in [0, 1) of a period)."""

    def box_positions(self, t_s: float) -> np.ndarray:
        """(K, 3) world centres of the moving boxes at time ``t_s``: a seeded back-and-forth slide at
        constant speed (a triangle wave, as a box pushed along an aisle and back)."""
        out = np.array([b.center_m for b in self.moving], float).reshape(-1, 3)
        if len(out):
            amp = np.hypot(self.motion[:, 0], self.motion[:, 1])
            period = 4 * amp / self.motion[:, 2]
            phase = np.mod(t_s / period + self.motion[:, 3], 1.0)
            s = np.where(phase < 0.5, 4 * phase - 1, 3 - 4 * phase)  # -1 .. 1 .. -1
            out[:, 0] += self.motion[:, 0] * s
            out[:, 1] += self.motion[:, 1] * s
        return out


def noise_texture(rng: np.random.Generator, size: int) -> np.ndarray:
    """(size, size, 3) uint8: multi-octave value noise between two random colours, with random
    rectangles and dots on top: corners and blobs at every scale, so FAST/ORB find features and
    descriptors stay distinctive (a checkerboard repeats and matches ambiguously)."""
    img = np.zeros((size, size))
    for octave in (4, 8, 16, 32, 64):
        grid = rng.random((octave + 1, octave + 1))
        idx = np.linspace(0, octave, size)
        i0 = np.minimum(idx.astype(int), octave - 1)
        f = idx - i0
        rows = grid[i0] * (1 - f)[:, None] + grid[i0 + 1] * f[:, None]
        img += (rows[:, i0] * (1 - f) + rows[:, i0 + 1] * f) * (8.0 / octave) ** 0.5
    img = (img - img.min()) / np.ptp(img)
    c1, c2 = rng.random(3), rng.random(3)
    rgb = c1 * (1 - img[..., None]) + c2 * img[..., None]
    for _ in range(40):
        x0, y0 = rng.integers(0, size, 2)
        w, h = rng.integers(size // 40, size // 8, 2)
        rgb[y0:y0 + h, x0:x0 + w] = rng.random(3)
    ys, xs = rng.integers(0, size, (2, 400))
    rgb[ys, xs] = rng.random((400, 3))
    return (np.clip(rgb, 0, 1) * 255).astype(np.uint8)


def _add_textures(spec: mujoco.MjSpec, rng: np.random.Generator, size: int, count: int) -> list[str]:
    """``count`` materials with noise textures: index 0 is a 2D one for the floor plane, the rest
    cube-mapped for boxes (a 2D texture on a box is projected along z and streaks on its sides)."""
    import imageio.v3 as iio

    names = []
    for k in range(count):
        name = f"/World/Looks/noise_{k}"
        kind = mujoco.mjtTexture.mjTEXTURE_2D if k == 0 else mujoco.mjtTexture.mjTEXTURE_CUBE
        # an in-memory PNG asset, not a raw buffer: the same pixels, and the spec still writes
        # as XML (``MjSpec.to_xml`` has no buffer textures; ``ambulo.sim.World`` fingerprints its
        # stage with it, so the scene can be built into a World's stage)
        file = f"ambulo_indoor_noise_{k}.png"
        spec.assets[file] = iio.imwrite("<bytes>", noise_texture(rng, size), extension=".png", compress_level=1)
        spec.add_texture(name=name + "/tex", type=kind, file=file)
        # one texture tile per 1.5 m on every surface, whatever its size (world-uniform mapping)
        mat = spec.add_material(name=name, texuniform=k == 0, texrepeat=[1 / 1.5, 1 / 1.5])
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = name + "/tex"
        names.append(name)
    return names


def _room_solids(cfg: IndoorSceneCfg, rng: np.random.Generator) -> list[SolidBox]:
    sx, sy = cfg.room_m[0] / 2, cfg.room_m[1] / 2
    h, t = cfg.wall_height_m / 2, 0.1
    solids = [SolidBox("/World/walls/east", (sx + t, 0, h), (t, sy + 2 * t, h)),
              SolidBox("/World/walls/west", (-sx - t, 0, h), (t, sy + 2 * t, h)),
              SolidBox("/World/walls/north", (0, sy + t, h), (sx, t, h)),
              SolidBox("/World/walls/south", (0, -sy - t, h), (sx, t, h)),
              # the island the walking loop goes around: a counter and a tall shelf
              SolidBox("/World/island/counter", (-0.6, 0, 0.45), (1.0, 0.35, 0.45), 0.0),
              SolidBox("/World/island/shelf", (1.0, 0.1, 0.8), (0.3, 0.25, 0.8), 0.0)]
    sides = [(sx, sy, 0), (sx, sy, 1), (sx, sy, 2), (sx, sy, 3)]
    for k in range(cfg.num_furniture):
        kind = rng.integers(0, 3)  # cabinet, table, shelf
        half = {0: (0.4, 0.25, 0.45), 1: (0.5, 0.35, 0.375), 2: (0.3, 0.2, 0.9)}[int(kind)]
        half = tuple(float(v * rng.uniform(0.8, 1.2)) for v in half)
        side = sides[k % 4][2]
        along = float(rng.uniform(-0.7, 0.7))
        if side in (0, 1):  # north / south walls: long side along x
            y = (sy - half[1] - 0.02) * (1 if side == 0 else -1)
            center, yaw = (along * (sx - half[0]), y, half[2]), 0.0
        else:  # east / west walls: rotate so the long side runs along y
            x = (sx - half[1] - 0.02) * (1 if side == 2 else -1)
            center, yaw = (x, along * (sy - half[0]), half[2]), math.pi / 2
        solids.append(SolidBox(f"/World/furniture/item_{k}", center, half, yaw))
    return solids


def build_indoor_scene(cfg: IndoorSceneCfg | None = None, *, spec: mujoco.MjSpec | None = None) -> IndoorScene:
    """The seeded indoor scene (see the module docstring); the same ``cfg`` gives the same scene.

    ``spec``: build into this (empty) stage instead of a new one, e.g. an ``ambulo.sim.World``'s
    (``world.stage.mjspec``), so that the humanoid in it is simulated under the World API."""
    cfg = cfg or IndoorSceneCfg()
    rng = np.random.default_rng(cfg.seed)
    spec = new_scene("ambulo_indoor") if spec is None else spec
    spec.visual.headlight.active = 0
    spec.visual.quality.numslices, spec.visual.quality.numstacks = 16, 8
    add_ground(spec, GroundCfg(prim_path="/World/floor", size_m=max(cfg.room_m) + 2.0, render_grid_m=1.0,
                               sky=False, sun=False))
    looks = _add_textures(spec, rng, cfg.texture_px, 5)
    spec.material("/World/floor/material").textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = looks[0] + "/tex"
    floor_mat = spec.material("/World/floor/material")
    floor_mat.texuniform, floor_mat.texrepeat = True, [1 / 1.5, 1 / 1.5]
    add_light(spec, "/World/sun", kind="distant", direction=(0.3, 0.2, -1.0), intensity=0.5, ambient=0.35)
    add_light(spec, "/World/lamp", kind="sphere", position=(0.0, 0.0, cfg.wall_height_m - 0.1), intensity=0.35)
    solids = _room_solids(cfg, rng)
    for k, box in enumerate(solids):
        body = spec.worldbody.add_body(name=box.name, pos=list(box.center_m),
                                       quat=[math.cos(box.yaw_rad / 2), 0, 0, math.sin(box.yaw_rad / 2)])
        body.add_geom(name=box.name + "/geom", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(box.half_m),
                      material=looks[1 + k % (len(looks) - 1)])
    moving, motion = [], []
    for k in range(cfg.num_moving_boxes):
        half = (0.2, 0.2, 0.2)
        center = (float(rng.uniform(-2.5, 2.5)), float(rng.choice([-1.0, 1.0]) * rng.uniform(2.0, 2.3)), half[2])
        box = SolidBox(f"/World/moving/box_{k}", center, half)
        body = spec.worldbody.add_body(name=box.name, pos=list(center), mocap=True)
        # plain cardboard colour: a moving box is an obstacle to map, and when it fills the view a
        # densely textured one would carry most of the features visual odometry tracks
        body.add_geom(name=box.name + "/geom", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(half),
                      rgba=[0.62, 0.47, 0.3, 1.0], contype=0, conaffinity=0)
        moving.append(box)
        motion.append((rng.uniform(0.4, 0.8), 0.0, rng.uniform(0.3, 0.6), rng.uniform(0, 1)))
    if cfg.with_robot:
        add_robot(spec, RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH))
    return IndoorScene(spec=spec, cfg=cfg, solids=solids, moving=moving,
                       motion=np.array(motion, float).reshape(-1, 4))


def scene_names() -> list[str]:
    """Scenes ``ambulo map`` knows."""
    return ["indoor"]


__all__ = ["IndoorScene", "IndoorSceneCfg", "SolidBox", "build_indoor_scene", "with_floor",
           "noise_texture", "scene_names"]
