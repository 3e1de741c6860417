"""Scatter objects on a surface without overlaps, checked by MuJoCo's own collision detection.

Placement is rejection sampling (``ambulo.core.randomize.place_without_overlap``): draw every
object's pose, run ``mj_collision`` on a private ``MjData``, redraw only the objects in
penetrating contacts (with each other, the robot or static scenery; the support surface is
ignored), and repeat. Objects still colliding after ``max_tries`` rounds are parked under
the floor and logged as hidden, so a crowded region degrades instead of overlapping.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ambulo.core import EntityNames, match_names
from ambulo.core.randomize import (
    CollisionChecker,
    Columns,
    Distribution,
    as_distribution,
    match_bodies,
    park_z,
    place_without_overlap,
    subtree_geoms,
    uniform,
    uniform_int,
    write_field,
)
from ambulo.utils.math import quat_from_yaw
from ambulo.utils.rotations import quat_to_mat

from .randomizers import Randomizer

__all__ = ["CollisionChecker", "Distractors", "Scatter2D", "bottom_offset", "box_corners_in_root", "footprint_radius",
           "park_z"]


@dataclass(kw_only=True)
class Scatter2D(Randomizer):
    """Place free-jointed bodies upright at random (x, y, yaw) on a horizontal surface.

    ``surface`` names the geom(s) the objects stand on (glob on the whole name or its last
    path component, as ``match_names``); their top is ``surface_z_m``. The region is
    ((x_min, y_min), (x_max, y_max)) in metres.
    """

    prims: str
    region: tuple[tuple[float, float], tuple[float, float]]
    surface: str = "*floor*"
    surface_z_m: float = 0.0
    yaw_rad: Distribution = field(default_factory=lambda: uniform(-np.pi, np.pi))
    check_collisions: bool = True
    max_tries: int = 30
    count: Distribution | None = None
    """How many of the matched bodies to place (the rest are parked); None places all."""

    def initialize(self, engine):
        m = engine.model
        self._bodies = match_bodies(m, self.prims)
        self._bodies = [b for b in self._bodies if m.body_parentid[b] == 0]
        if not self._bodies:
            raise ValueError(f"{self.name}: no top-level body matches {self.prims!r}")
        # each object's free joint, found as an Entity finds its root's (core.names.EntityNames)
        self._qadr = [EntityNames(m, m.body(b).name).free_qpos_adr for b in self._bodies]
        for b, adr in zip(self._bodies, self._qadr):
            if adr is None:
                raise ValueError(f"{self.name}: body {m.body(b).name!r} needs a free joint to be scattered")
        self._geoms = [subtree_geoms(m, b) for b in self._bodies]
        names = [m.geom(g).name for g in range(m.ngeom)]
        surface = match_names(names, self.surface)
        if self.check_collisions and not surface:
            raise ValueError(f"{self.name}: no geom matches surface {self.surface!r}")
        # the checker makes only the contacts of these objects' geoms: the rest never decide a redraw
        self._checker = CollisionChecker(m, surface, movers=np.concatenate(self._geoms)) \
            if self.check_collisions else None
        self._bottom = [bottom_offset(m, b, g) for b, g in zip(self._bodies, self._geoms)]
        # (bodies, 7) qpos addresses of each free joint, and the height (m) its origin rests at
        self._free_index = np.asarray(self._qadr, np.int64)[:, None] + np.arange(7)
        self._rest_z_m = self.surface_z_m + np.asarray(self._bottom)
        # every body parked: one write of all their free-joint coordinates
        self._park_index = self._free_index.reshape(-1)
        (x0, y0), (x1, y1) = self.region
        self._place = Columns((uniform(x0, x1), uniform(y0, y1), self.yaw_rad))  # x, y, yaw of each object
        self._park_values = np.concatenate([[0.0, 0.0, park_z(b), 1, 0, 0, 0] for b in self._bodies])

    def sample(self, rng, ctx):
        n = len(self._bodies)
        count = n if self.count is None else min(max(int(as_distribution(self.count).sample_host(rng)), 0), n)
        active = sorted(rng.permutation(n)[:count].tolist()) if count < n else list(range(n))
        # every round's poses drawn at once (enough for max_tries full rounds), used row after
        # row: one draw per frame instead of one per round; each row as the object's whole free
        # joint (x, y, z, quaternion), so a round is one copy and one write
        pool = self._place.sample_host(rng, self.max_tries * len(active))
        pool_free = np.zeros((len(pool), 7))
        pool_free[:, :2] = pool[:, :2]
        half_yaw = 0.5 * pool[:, 2]  # the quaternion of quat_from_yaw: (cos, 0, 0, sin) of half the yaw
        pool_free[:, 3] = np.cos(half_yaw)
        pool_free[:, 6] = np.sin(half_yaw)
        used = 0
        last_row = np.zeros(n, np.int64)  # each object's latest pool row: its pose if placed
        qpos = world_qpos(ctx.engine, ctx.world).copy()
        qpos[self._park_index] = self._park_values
        free_index, rest_z_m = self._free_index, self._rest_z_m

        def draw(todo: list[int]) -> None:
            nonlocal used
            k = len(todo)
            free = pool_free[used:used + k]  # a copy would only be overwritten: z is set in place
            free[:, 2] = rest_z_m[todo]
            qpos[free_index[todo]] = free
            last_row[todo] = np.arange(used, used + k)
            used += k

        hidden = sorted(place_without_overlap(active, self._bodies, qpos, draw, self._checker, self.max_tries))
        hidden_set = set(hidden)
        placed = [i for i in active if i not in hidden_set]
        poses = pool[last_row[placed]].tolist()
        return {"active": placed, "hidden": hidden, "pose_xy_yaw": {str(i): p for i, p in zip(placed, poses)}}

    def apply(self, params, ctx):
        # every object's free joint in one write: parked, then the placed ones at their poses
        free = self._park_values.reshape(-1, 7).copy()
        if params["pose_xy_yaw"]:
            placed = np.fromiter(map(int, params["pose_xy_yaw"]), np.int64)
            pose = np.array(list(params["pose_xy_yaw"].values()), np.float64)
            free[placed, :2] = pose[:, :2]
            free[placed, 2] = self._rest_z_m[placed]
            half_yaw = 0.5 * pose[:, 2]  # quat_from_yaw's (cos, 0, 0, sin); parked rows hold 0 there
            free[placed, 3] = np.cos(half_yaw)
            free[placed, 6] = np.sin(half_yaw)
        write_field(ctx.engine.qpos, free.reshape(1, -1), rows=ctx.world, index=self._park_index)
        if self._checker is not None:
            # later scatterers (distractors) check against where these objects now are
            self._checker.data.qpos[:] = world_qpos(ctx.engine, ctx.world)

    def _write(self, qpos: np.ndarray, objects, poses, quat_wxyz=None) -> None:
        """Stand ``objects`` (indices, or one index) upright at ``poses`` (k, 3) x, y (m), yaw (rad)
        in the full configuration ``qpos``; ``quat_wxyz`` (k, 4): the yaws' quaternions, if known."""
        objects = np.atleast_1d(np.asarray(objects, np.int64))
        poses = np.asarray(poses, np.float64).reshape(-1, 3)
        free = np.empty((len(objects), 7))
        free[:, :2] = poses[:, :2]
        free[:, 2] = self._rest_z_m[objects]
        free[:, 3:] = quat_from_yaw(poses[:, 2]) if quat_wxyz is None else quat_wxyz
        qpos[self._free_index[objects]] = free

    def _park_all(self, qpos: np.ndarray) -> None:
        qpos[self._park_index] = self._park_values


def world_qpos(engine, world: int) -> np.ndarray:
    """World ``world``'s ``qpos`` (nq,) as NumPy: a view of a host tensor (no torch indexing op, whose
    dispatch is most of a small read's cost), a copy of a device one."""
    qpos = engine.qpos
    return qpos.numpy()[world] if qpos.device.type == "cpu" else qpos[world].cpu().numpy()


_BOX_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
"""(8, 3) the corners of the unit cube [-1, 1]^3."""


def box_corners_in_root(m: mujoco.MjModel, body: int, geoms) -> np.ndarray:
    """(8 G, 3) the corners of ``geoms``' bounding boxes (``geom_aabb``) in ``body``'s frame, m: the
    geometry an upright object is placed by (``bottom_offset``, ``footprint_radius``)."""
    boxes = m.geom_aabb[geoms].reshape(-1, 2, 3)  # (G, 2, 3): centre and half sizes in the geom's frame
    return np.concatenate([(_BOX_CORNERS * half + centre) @ _geom_rot_in_root(m, g, body).T
                           + _geom_pos_in_root(m, g, body) for g, (centre, half) in zip(geoms, boxes)]
                          or [np.zeros((0, 3))])


def bottom_offset(m: mujoco.MjModel, body: int, geoms) -> float:
    """Depth (m) of the body's lowest bounding-box corner below its origin, when upright.

    Yaw does not change heights, so one number per body sets its resting z.
    """
    return -float(box_corners_in_root(m, body, geoms)[:, 2].min(initial=np.inf))


def footprint_radius(m: mujoco.MjModel, body: int, geoms) -> float:
    """Radius (m) of the circle about ``body``'s origin that holds its upright bounding box at any yaw."""
    return float(np.linalg.norm(box_corners_in_root(m, body, geoms)[:, :2], axis=1).max(initial=0.0))


def _geom_rot_in_root(m, geom: int, root: int) -> np.ndarray:
    rot = quat_to_mat(m.geom_quat[geom])
    b = m.geom_bodyid[geom]
    while b != root:
        rot = quat_to_mat(m.body_quat[b]) @ rot
        b = m.body_parentid[b]
    return rot


def _geom_pos_in_root(m, geom: int, root: int) -> np.ndarray:
    pos = m.geom_pos[geom].copy()
    b = m.geom_bodyid[geom]
    while b != root:
        pos = m.body_pos[b] + quat_to_mat(m.body_quat[b]) @ pos
        b = m.body_parentid[b]
    return pos


@dataclass(kw_only=True)
class Distractors(Scatter2D):
    """Unlabelled clutter: a pool of random primitives added at build, a random number placed per frame.

    Shapes, sizes and colours of the pool come from ``pool_seed`` (part of the
    scene); each frame draws how many are placed and where, avoiding everything
    placed before it.
    """

    prims: str = "/World/distractors/*"
    pool_size: int = 8
    pool_seed: int = 1
    size_m: tuple[float, float] = (0.05, 0.25)
    count: Distribution | None = field(default_factory=lambda: uniform_int(2, 6))

    def build(self, spec):
        rng = np.random.default_rng(self.pool_seed)
        shapes = [mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER,
                  mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_ELLIPSOID]
        root = self.prims.rstrip("*").rstrip("/")
        for i in range(self.pool_size):
            body = spec.worldbody.add_body(name=f"{root}/distractor_{i}", pos=[0, 0, -10.0 - 3.0 * i])
            body.add_freejoint()
            size = rng.uniform(*self.size_m, 3)
            body.add_geom(type=shapes[i % len(shapes)], size=size, rgba=[*rng.uniform(0.1, 1.0, 3), 1.0])
