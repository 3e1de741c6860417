"""Model-field and state writes for some worlds: one write per field, no per-world loop.

Every operation here takes a row selector ``rows`` (``core.rows``: None for every world, a long
tensor of world indices, an (N,) bool mask on a GPU) or a plain int for one world (the
replicator's world 0), and element indices along the field's second axis (geoms, bodies,
dofs, lights, ``qpos`` addresses). Values have one leading row per selected world (N for a
mask) and broadcast over the rest: ``(n, k, *tail)`` for ``k`` elements.

``randomize_field`` draws from a ``Distribution`` and writes absolute values, or offsets
(``"add"``) or factors (``"scale"``) of the compiled model's nominal values, so drawing
again never compounds. The named operations (``body_mass``, ``geom_friction``, ...) resolve
their elements through an ``Entity`` (its bodies, joints and their dofs), as the RL task
events and the replicator's randomizers both do. After changing masses, inertias or CoMs,
call ``engine.set_const()`` so derived quantities follow.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import torch

from ..paths import match_names
from ..rows import num_rows, put_rows
from .distributions import Distribution

Rows = None | int | torch.Tensor
"""None (every world), one world's index, a long tensor of indices or an (N,) bool mask."""

OPERATIONS = ("abs", "add", "scale")


def index_array(index, count: int) -> np.ndarray:
    """``index`` (None, a slice, a list, an array or a tensor of element ids) as an int64 array
    of the ids it selects among ``count`` elements."""
    if index is None:
        return np.arange(count, dtype=np.int64)
    if isinstance(index, slice):
        return np.arange(count, dtype=np.int64)[index]
    if isinstance(index, torch.Tensor):
        return index.detach().cpu().numpy().astype(np.int64).reshape(-1)
    return np.asarray(index, dtype=np.int64).reshape(-1)


def count_rows(rows: Rows, num_worlds: int) -> int:
    """How many value rows a write for ``rows`` takes."""
    return 1 if isinstance(rows, (int, np.integer)) else num_rows(rows, num_worlds)


def write_field(field: torch.Tensor, values, *, rows: Rows = None, index=None) -> None:
    """``field[rows, index] = values`` in one write, for an ``(N, E, *tail)`` model field or an
    ``(N, E)`` state tensor (``qpos``): ``values`` broadcast to ``(n, k, *tail)``.

    Host tensors are written through a NumPy view (a tenth of torch's cost for the small writes
    of one frame); device tensors through ``core.rows.put_rows`` (masks with ``torch.where``)."""
    if type(index) is np.ndarray and index.dtype == np.int64 and index.ndim == 1:
        cols = index  # already what index_array makes (a randomizer's ids, resolved once)
    else:
        cols = slice(None) if index is None else index_array(index, field.shape[1])
    if field.device.type == "cpu" and not (isinstance(rows, torch.Tensor) and rows.dtype == torch.bool):
        array = field.numpy()
        value = values.detach().cpu().numpy() if isinstance(values, torch.Tensor) else values
        if rows is None:
            array[:, cols] = value
        elif isinstance(rows, (int, np.integer)):
            array[int(rows):int(rows) + 1, cols] = value
        else:
            ids = rows.numpy()
            array[ids[:, None] if isinstance(cols, np.ndarray) else ids, cols] = value
        return
    if isinstance(rows, (int, np.integer)):
        rows = torch.tensor([int(rows)], device=field.device)
    if isinstance(cols, np.ndarray):
        cols = torch.as_tensor(cols, device=field.device)
    put_rows(field, cols, torch.as_tensor(values, device=field.device), rows)


def nominal_values(engine, name: str, index, *, column: int | None = None,
                   dtype: torch.dtype | None = None) -> torch.Tensor:
    """The compiled model's value of field ``name`` for ``index`` (k, *tail), on the engine's
    device: what ``"add"`` and ``"scale"`` offset from."""
    array = np.asarray(getattr(engine.model, name))
    array = array[index_array(index, array.shape[0])]
    if column is not None:
        array = array[..., column]
    return torch.as_tensor(array, dtype=dtype or engine.dtype, device=torch.device(engine.device))


def randomize_field(engine, name: str, distribution: Distribution, generator: torch.Generator, *,
                    index=None, column: int | None = None, rows: Rows = None, operation: str = "abs",
                    shared: bool = False, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Draw and write model field ``name`` for ``rows`` and elements ``index`` (None: all).

    Args:
      column: one trailing component (``geom_friction``'s 0 is sliding friction); None: all.
      operation: ``"abs"`` writes the draws, ``"add"`` nominal + draws, ``"scale"`` nominal * draws.
      shared: one draw per world for every element (MuJoCo takes the larger friction of two
        geoms, so a world's floor and feet need the same value); else one per element.
      dtype: the dtype draws are cast to before the arithmetic (``Distribution.sample``).

    Returns the written values, ``(n, k or 1, *value shape)`` before broadcasting.
    """
    if operation not in OPERATIONS:
        raise ValueError(f"operation {operation!r}: use one of {OPERATIONS}")
    field = engine.model_field(name)
    if column is not None:
        field = field[..., column]
    ids = index_array(index, field.shape[1])
    n = count_rows(rows, field.shape[0])
    per_row = 1 if shared else len(ids)
    draws = distribution.sample(generator, n * per_row, dtype=dtype)
    values = draws.reshape(n, per_row, *draws.shape[1:])
    if operation != "abs":
        nominal = nominal_values(engine, name, ids, column=column, dtype=field.dtype)
        values = values.to(nominal.device, field.dtype)
        values = nominal + values if operation == "add" else nominal * values
    write_field(field, values, rows=rows, index=None if index is None else ids)
    return values


# -- over an Entity ---------------------------------------------------------------------------
def entity_body_ids(entity, bodies=None) -> np.ndarray:
    """Model ids of ``entity``'s bodies named by ``bodies`` (names or full-match regexes; None: all)."""
    ids = entity.body_ids.detach().cpu().numpy()
    return ids if bodies is None else ids[entity.find_bodies(bodies)]


def entity_dof_ids(entity, joints=None) -> np.ndarray:
    """``qvel``/dof addresses of ``entity``'s hinge/slide joints named by ``joints`` (None: all)."""
    ids = index_array(entity.dof_idx, entity.engine.model.nv)
    return ids if joints is None else ids[entity.find_joints(joints)]


def entity_qpos_ids(entity, joints=None) -> np.ndarray:
    """``qpos`` addresses of ``entity``'s hinge/slide joints named by ``joints`` (None: all)."""
    ids = index_array(entity.qpos_idx, entity.engine.model.nq)
    return ids if joints is None else ids[entity.find_joints(joints)]


def body_mass(entity, distribution: Distribution, generator: torch.Generator, *, bodies=None,
              rows: Rows = None, operation: str = "add", dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Per-world mass (kg) of ``entity``'s ``bodies``: nominal + draw by default (added payload)."""
    return randomize_field(entity.engine, "body_mass", distribution, generator,
                           index=entity_body_ids(entity, bodies), rows=rows, operation=operation, dtype=dtype)


def body_com_offset(entity, distribution: Distribution, generator: torch.Generator, *, bodies=None,
                    rows: Rows = None, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Per-world centre of mass of ``bodies``: nominal ``body_ipos`` (m, body frame) plus a (3,) draw."""
    return randomize_field(entity.engine, "body_ipos", distribution, generator,
                           index=entity_body_ids(entity, bodies), rows=rows, operation="add", dtype=dtype)


def geom_friction(engine, distribution: Distribution, generator: torch.Generator, *, geoms=None,
                  rows: Rows = None, shared: bool = True, operation: str = "abs",
                  dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Per-world sliding friction of ``geoms`` (model ids; None: every geom, so a world's contacts
    all see its draw: MuJoCo takes the larger friction of the two geoms)."""
    return randomize_field(engine, "geom_friction", distribution, generator, index=geoms, column=0,
                           rows=rows, shared=shared, operation=operation, dtype=dtype)


DOF_FIELDS = ("dof_damping", "dof_armature", "dof_frictionloss")


def joint_dof_field(entity, name: str, distribution: Distribution, generator: torch.Generator, *,
                    joints=None, rows: Rows = None, operation: str = "scale",
                    dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Per-world passive joint property ``name`` (one of ``DOF_FIELDS``) of ``entity``'s ``joints``:
    nominal * draw by default."""
    if name not in DOF_FIELDS:
        raise ValueError(f"joint property {name!r}: use one of {DOF_FIELDS}")
    return randomize_field(entity.engine, name, distribution, generator, index=entity_dof_ids(entity, joints),
                           rows=rows, operation=operation, dtype=dtype)


def joint_range_box(entity, fraction: float, joints=None) -> tuple[np.ndarray, np.ndarray]:
    """(k,) low and high joint positions (rad or m): the middle ``fraction`` of each limited
    joint's range; ``+-fraction * pi`` for an unlimited one."""
    limits = entity.joint_pos_limits.detach().cpu().numpy().reshape(-1, 2)
    if joints is not None:
        limits = limits[np.asarray(joints, dtype=np.int64)]
    lo, hi = limits[:, 0], limits[:, 1]
    limited = np.isfinite(lo) & np.isfinite(hi)
    mid = np.where(limited, (lo + hi) / 2, 0.0)
    half = np.where(limited, (hi - lo) / 2, np.pi)
    return mid - fraction * half, mid + fraction * half


def write_free_poses(engine, qpos_adr, pos_m, quat_wxyz, *, rows: Rows = None) -> None:
    """Set the free joints at ``qpos_adr`` (k,) to positions ``pos_m`` (n, k, 3), world frame, and
    orientations ``quat_wxyz`` (n, k, 4), in one ``qpos`` write."""
    adr = np.asarray(qpos_adr, dtype=np.int64).reshape(-1)
    index = (adr[:, None] + np.arange(7)).reshape(-1)
    if isinstance(pos_m, torch.Tensor) or isinstance(quat_wxyz, torch.Tensor):
        pose = torch.cat([torch.as_tensor(pos_m), torch.as_tensor(quat_wxyz).to(torch.as_tensor(pos_m))], -1)
    else:
        pose = np.concatenate([np.asarray(pos_m, np.float64), np.asarray(quat_wxyz, np.float64)], -1)
    write_field(engine.qpos, pose.reshape(pose.shape[0], -1), rows=rows, index=index)


# -- bodies matched by name and the geoms they draw with -----------------------------------------
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


@dataclass(frozen=True)
class BodyGeoms:
    """Bodies matched by a pattern and the geoms of their subtrees, resolved once.

    ``targets`` lists every such geom once and ``owner`` the body (index into ``bodies``) whose
    value it takes, the last body listing it (as writing body after body would leave it), so
    one value per body is written to every geom as ``values[owner]`` in one write.
    """

    bodies: list[int]
    geoms: list[np.ndarray]
    targets: np.ndarray
    owner: np.ndarray

    @classmethod
    def resolve(cls, model: mujoco.MjModel, pattern: str, what: str = "") -> BodyGeoms:
        bodies = match_bodies(model, pattern)
        if not bodies:
            raise ValueError(f"{what or 'randomizer'}: no body matches {pattern!r}")
        geoms = [subtree_geoms(model, b) for b in bodies]
        targets, owner = geoms_by_body(model.ngeom, geoms)
        return cls(bodies, geoms, targets, owner)

    def write(self, field: torch.Tensor, per_body, *, rows: Rows = None) -> None:
        """Write ``per_body`` (n, B, *tail) values, one per body, to all its geoms of ``field``."""
        values = per_body.detach().cpu().numpy() if isinstance(per_body, torch.Tensor) else np.asarray(per_body)
        write_field(field, values[:, self.owner], rows=rows, index=self.targets)


def geoms_by_body(ngeom: int, geoms_per_body: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Every geom of the bodies' subtrees once, and the body whose value it takes: the last
    body listing it, as a loop writing body after body would leave it."""
    owner = np.full(ngeom, -1, np.int64)
    for k, geoms in enumerate(geoms_per_body):
        owner[geoms] = k
    targets = np.flatnonzero(owner >= 0)
    return targets, owner[targets]


__all__ = ["DOF_FIELDS", "OPERATIONS", "BodyGeoms", "Rows", "body_com_offset", "body_mass", "count_rows",
           "entity_body_ids", "entity_dof_ids", "entity_qpos_ids", "geom_friction", "geoms_by_body",
           "index_array", "joint_dof_field", "joint_range_box", "match_bodies", "nominal_values",
           "randomize_field", "subtree_geoms", "write_field", "write_free_poses"]
