"""Hard negatives: unlabelled primitives of the labelled classes' own families (boxes, spheres,
cylinders, ellipsoids) at sizes and proportions no class has, so that "a box of another size" is
learnt as background.

Why: the example scene's classes are primitives told apart from clutter only by their exact
geometry (``scenes.warehouse.OBJECTS``). A detector trained with a small fixed distractor pool calls
any new box, sphere or cylinder an object (issue 27: unseen clutter cost 21-28 points of mAP50).

The pool is drawn once at build from ``pool_seed`` (part of the scene); a shape is redrawn while it is
within ``margin`` of any labelled object of its family (every dimension within the factor
``1 + margin`` of the object's: a size the detector may not learn as background) or of any shape of
``excluded_pools`` (the distractor pools a test split draws: its clutter stays unseen). Dimensions
compare as yaw-invariant tuples: a box's two horizontal half-sizes sorted, then its half-height.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ambulo.scenes.warehouse import OBJECTS

from .scatter import Distractors

FAMILIES = ("box", "sphere", "cylinder", "ellipsoid")
"""The labelled classes' geom types (``OBJECTS``), in the order the pool cycles through them."""
DISTRACTOR_SHAPES = ("box", "sphere", "cylinder", "capsule", "ellipsoid")
"""``scatter.Distractors.build``'s shape cycle (its geom ``i`` has shape ``i % 5``)."""


def shape_key(kind: str, size: tuple[float, ...]) -> tuple[float, ...]:
    """The yaw-invariant dimensions (m) of a geom that decide its look: box (short, long horizontal
    half-size, half-height), sphere (radius,), cylinder/capsule (radius, half-height), ellipsoid
    (short, long horizontal semi-axis, vertical semi-axis)."""
    if kind == "sphere":
        return (float(size[0]),)
    if kind in ("cylinder", "capsule"):
        return (float(size[0]), float(size[1]))
    return (*sorted(float(s) for s in size[:2]), float(size[2]))


def distractor_pool(pool_seed: int, pool_size: int, size_m: tuple[float, float],
                    avoid: list[tuple[str, tuple]] = (), margin: float = 0.25) -> list[tuple[str, tuple]]:
    """(kind, MuJoCo size) of each shape ``scatter.Distractors`` with these fields builds (its draws
    repeated: size, then colour, per shape), or ``ClassFreeDistractors`` with ``avoid``."""
    return [(kind, size) for kind, size, _ in distractor_draws(pool_seed, pool_size, size_m, avoid, margin)]


def distractor_draws(pool_seed: int, pool_size: int, size_m: tuple[float, float],
                     avoid: list[tuple[str, tuple]] = (),
                     margin: float = 0.25) -> list[tuple[str, tuple, tuple]]:
    """(kind, MuJoCo size, rgb) of each shape of a ``scatter.Distractors`` pool: its draws (size, then
    colour, per shape); a shape within ``margin`` of one of ``avoid`` (``too_close``) gets another size
    from a stream of its own (seed (pool_seed, its index)), so every other shape and every colour stay
    exactly as ``Distractors`` draws them."""
    rng = np.random.default_rng(pool_seed)
    pool = []
    for i in range(pool_size):
        kind = DISTRACTOR_SHAPES[i % len(DISTRACTOR_SHAPES)]
        size = tuple(rng.uniform(*size_m, 3).tolist())
        rgb = tuple(rng.uniform(0.1, 1.0, 3).tolist())
        redraw = np.random.default_rng([pool_seed, i])
        for _ in range(1000):
            if not too_close(kind, size, list(avoid), margin):
                break
            size = tuple(redraw.uniform(*size_m, 3).tolist())
        else:
            raise RuntimeError(f"distractor {i} ({kind}): no size outside the margin in 1000 draws")
        pool.append((kind, size, rgb))
    return pool


def too_close(kind: str, size: tuple[float, ...], others: list[tuple[str, tuple]], margin: float) -> bool:
    """Whether the shape is within ``margin`` of one of ``others`` (kind, size) of its kind: every
    dimension within the factor 1 + margin (module docstring)."""
    key = np.array(shape_key(kind, size))
    for other_kind, other_size in others:
        if other_kind == kind and np.all(np.abs(np.log(key / np.array(shape_key(other_kind, other_size))))
                                         < np.log1p(margin)):
            return True
    return False


def class_shapes() -> list[tuple[str, tuple]]:
    """(kind, MuJoCo size) of every labelled object of the example scene."""
    return [(kind, tuple(size) + (0.0,) * (3 - len(size))) for _, kind, size in OBJECTS]


@dataclass(kw_only=True)
class HardNegatives(Distractors):
    """``Distractors`` whose pool is the classes' families at other sizes (module docstring)."""

    prims: str = "/World/hard_negatives/*"
    pool_size: int = 32
    pool_seed: int = 2027
    size_m: tuple[float, float] = (0.04, 0.40)
    """Each dimension's range (half-sizes, radii; m): the classes' 0.06-0.30 and beyond either side."""
    margin: float = 0.25
    """A drawn shape within this relative distance of a class's (or an excluded pool's) is redrawn."""
    excluded_pools: list[list[tuple[str, tuple]]] = field(default_factory=list)
    """Pools (``distractor_pool``) whose shapes training must not see: a test split's clutter."""

    def pool(self) -> list[tuple[str, tuple]]:
        """(kind, MuJoCo size) of each shape of the pool, drawn as the module docstring says."""
        rng = np.random.default_rng(self.pool_seed)
        avoid = class_shapes() + [shape for pool in self.excluded_pools for shape in pool]
        shapes = []
        for i in range(self.pool_size):
            kind = FAMILIES[i % len(FAMILIES)]
            for _ in range(1000):
                size = tuple(rng.uniform(*self.size_m, 3).tolist())
                if kind == "ellipsoid" and rng.random() < 0.5:  # half of them round in plan, as the cone is
                    size = (size[0], size[0], size[2])
                if not too_close(kind, size, avoid, self.margin):
                    break
            else:
                raise RuntimeError(f"{self.name}: no {kind} outside the margin in 1000 draws")
            shapes.append((kind, size))
        return shapes

    def build(self, spec):
        rng = np.random.default_rng(self.pool_seed + 1)
        root = self.prims.rstrip("*").rstrip("/")
        for i, (kind, size) in enumerate(self.pool()):
            body = spec.worldbody.add_body(name=f"{root}/negative_{i}", pos=[0, 0, -10.0 - 3.0 * i])
            body.add_freejoint()
            body.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}"), size=list(size),
                          rgba=[*rng.uniform(0.1, 1.0, 3), 1.0])


@dataclass(kw_only=True)
class ClassFreeDistractors(Distractors):
    """``Distractors`` without the classes' geometries: a pool shape within ``margin`` of a labelled
    object of its family (``too_close`` to ``class_shapes``) is redrawn (``distractor_draws``).

    Why: such a shape is a class by geometry (split (b)'s spheres of radius 0.147-0.181 m against the
    balls' 0.12 and 0.18 m), so calling it one is right, not a domain gap; clutter is everything else.
    The margin is the one ``HardNegatives`` keeps from the classes."""

    margin: float = 0.25

    def pool(self) -> list[tuple[str, tuple, tuple]]:
        """(kind, MuJoCo size, rgb) of each shape of the pool (class docstring)."""
        return distractor_draws(self.pool_seed, self.pool_size, self.size_m, class_shapes(), self.margin)

    def build(self, spec):
        root = self.prims.rstrip("*").rstrip("/")
        for i, (kind, size, rgb) in enumerate(self.pool()):
            body = spec.worldbody.add_body(name=f"{root}/distractor_{i}", pos=[0, 0, -10.0 - 3.0 * i])
            body.add_freejoint()
            body.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}"), size=list(size), rgba=[*rgb, 1.0])


__all__ = ["FAMILIES", "ClassFreeDistractors", "HardNegatives", "class_shapes", "distractor_draws",
           "distractor_pool", "shape_key", "too_close"]
