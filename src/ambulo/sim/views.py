"""Views over many prims (Isaac 4.5+'s ``isaacsim.core.prims.XFormPrim``/``RigidPrim``/``Articulation``,
the older ``XFormPrimView``/``RigidPrimView``/``ArticulationView``).

A view takes ``prim_paths_expr``: a path whose every component is a regular expression
(``/World/envs/env_.*/Robot``), or a list of them. It matches the stage's prim paths when
built (Isaac raises if none match) and the compiled model's again at every ``world.reset()``,
then wraps one single prim (``XFormPrim``, ``RigidPrim``, ``Articulation``) per match: this
is the Isaac-style API, not the RL hot path (``ambulo.core.Entity`` is).

Arrays have one row per prim: (K, ...) for K matches, ordered as the prims were added to the
stage. With ``World(num_worlds=N)`` every match exists in each world and the view holds
``count = N * K`` prims, world-major (row ``n * K + k`` is match k in world n). ``indices``
select rows; setters take one row per selected prim. Units as for single prims: stage units
for positions and linear velocities, w x y z quaternions, rad and rad/s, prismatic joints in
stage units.
"""

from __future__ import annotations

import re

import numpy as np
import torch

from ..core.paths import PrimNotFoundError
from ..utils.checks import Described, InvalidValueError, check_all_finite, check_real_dtype
from .actions import ArticulationAction, ArticulationActions
from .articulation import Articulation
from .current import current_world_or_none
from .prims import RigidPrim, XFormPrim, _NotInitialized, place_on_stage
from .states import DynamicsViewState, JointsState, XFormPrimViewState


def _prefixes(names) -> list[str]:
    """Every prim path in ``names`` and its ancestors below the root, in first-seen order."""
    seen: dict[str, None] = {}
    for name in names:
        if not name.startswith("/"):
            continue
        parts = name.rstrip("/").split("/")
        for depth in range(2, len(parts) + 1):
            seen.setdefault("/".join(parts[:depth]))
    return list(seen)


def match_prim_paths(exprs: list[str], paths: list[str]) -> list[str]:
    """The ``paths`` whose every component fully matches the expression's component."""
    found: dict[str, None] = {}
    for expr in exprs:
        patterns = [re.compile(part) for part in expr.strip("/").split("/")]
        for path in paths:
            parts = path.strip("/").split("/")
            if len(parts) == len(patterns) and all(p.fullmatch(n) for p, n in zip(patterns, parts)):
                found.setdefault(path)
    return list(found)


class XFormPrimView(XFormPrim):
    """Poses of the prims matching ``prim_paths_expr``.

    Args:
      prim_paths_expr: a path of per-component regular expressions, or a list of them.
      name: scene registry name.
      positions / translations: (K, 3) stage units, world / parent frame; orientations (K, 4)
        w x y z: placed on the stage now (for referenced files, where their prims go).
      scales, visibilities: only their defaults (1, visible) are supported.
    """

    _single = XFormPrim

    def __init__(self, prim_paths_expr, name: str = "xform_prim_view", positions=None, translations=None,
                 orientations=None, scales=None, visibilities=None, reset_xform_properties: bool = True):
        exprs = [prim_paths_expr] if isinstance(prim_paths_expr, str) else list(prim_paths_expr)
        bad = [e for e in exprs if not isinstance(e, str) or not e.startswith("/")]
        if not exprs or bad:
            raise ValueError(f"prim_paths_expr must be absolute path expressions like '/World/envs/env_.*/Robot'; "
                             f"got {prim_paths_expr!r}")
        if scales is not None and not np.allclose(np.asarray(scales, dtype=float), 1.0):
            raise ValueError("view scales are not supported: bodies keep the size they were built with")
        if visibilities is not None and not np.asarray(visibilities, dtype=bool).all():
            raise ValueError("invisible view prims are not supported: build them as Visual* objects or hide them")
        self._exprs = exprs
        self.prim_path = exprs[0]
        self.name = name
        self._world = _NotInitialized(self.prim_path)
        self.entity = None
        self._prims: list = []
        self._paths = self._match_stage()
        if not self._paths:
            raise PrimNotFoundError(f"no prim matches {prim_paths_expr!r}; "
                                    + (_glob_hint(exprs, self._stage_names()) or "create the prims first (add_reference_to_"
                                       "stage, Dynamic* objects), each path component is a regular expression"))
        def row(values, k: int):
            return None if values is None else np.asarray(values, dtype=float).reshape(len(self._paths), -1)[k]

        for k, path in enumerate(self._paths):
            place_on_stage(path, row(positions, k), row(translations, k), row(orientations, k))

    def _stage_names(self) -> list[str]:
        world = current_world_or_none()
        if world is None:
            return []
        names = [e.name for group in (world.stage.bodies, world.stage.frames) for e in group]
        return names + [str(p.GetPath()) for p in world.usd.stage.Traverse()]

    def _match_stage(self) -> list[str]:
        return match_prim_paths(self._exprs, _prefixes(self._stage_names()))

    # -- lifecycle -----------------------------------------------------------------
    def initialize(self, world=None, physics_sim_view=None) -> None:
        """Match the compiled model and initialize one single prim per match (``world.reset()`` does)."""
        if world is None or not hasattr(world, "engine"):
            world = current_world_or_none()
        model = world.model
        names = [model.body(i).name for i in range(model.nbody)]
        paths = match_prim_paths(self._exprs, _prefixes(names))
        if not paths:
            raise PrimNotFoundError(f"no body of the compiled scene matches {self._exprs}; "
                                    + (_glob_hint(self._exprs, names) or "check the expression against the prim "
                                       "paths (each component is a regular expression)"))
        prims = [self._make(path) for path in paths]
        for prim in prims:
            prim.initialize(world)
        self._world, self._paths, self._prims = world, paths, prims

    def _make(self, path: str):
        return self._single(path, name=f"{self.name}:{path}")

    def post_reset(self) -> None:
        for prim in self._prims:
            prim.post_reset()

    def is_valid(self, indices=None) -> bool:
        return bool(self._prims)

    @property
    def _data(self):
        raise RuntimeError(f"{type(self).__name__} {self.name!r} holds many prims: use the plural members "
                           "(get_world_poses, set_joint_positions, ...)")

    # -- the prims -------------------------------------------------------------------
    @property
    def prim_paths(self) -> list[str]:
        """The K matched paths (each is one prim in every world)."""
        return list(self._paths)

    @property
    def count(self) -> int:
        """Prims in the view: K matches times the World's worlds."""
        worlds = self._world.num_worlds if self._prims else 1
        return len(self._paths) * worlds

    @property
    def prims(self) -> list:
        """The ``Usd.Prim`` of each matched path."""
        world = self._world if self._prims else current_world_or_none()
        stage = world.synced_usd().stage
        return [stage.GetPrimAtPath(p) for p in self._paths]

    def _require(self) -> None:
        if not self._prims:
            raise RuntimeError(f"view {self.name!r} is not initialized: add it to world.scene and call world.reset()")

    # -- gather / scatter -------------------------------------------------------------
    def _rows(self, indices) -> torch.Tensor:
        """``indices`` (None: all) as a long tensor of rows in 0..count-1."""
        self._require()
        if indices is None:
            return torch.arange(self.count)
        rows = torch.as_tensor(np.asarray(indices.cpu() if torch.is_tensor(indices) else indices)).reshape(-1)
        if rows.is_floating_point() or rows.dtype == torch.bool:
            raise InvalidValueError("indices", indices, "not whole numbers", f"pass rows 0..{self.count - 1}")
        if rows.numel() and (rows.min() < 0 or rows.max() >= self.count):
            raise InvalidValueError("indices", indices, f"out of range for {self.count} prims",
                                    f"pass rows 0..{self.count - 1}")
        return rows.long()

    def _gather(self, read, rows: torch.Tensor) -> torch.Tensor:
        """Stack ``read(prim)`` ((N, ...) each) into (count, ...) world-major, then take ``rows``."""
        stacked = torch.stack([read(prim) for prim in self._prims], dim=1)
        return stacked.reshape(-1, *stacked.shape[2:])[rows.to(stacked.device)]

    def _scatter(self, write, rows: torch.Tensor, *values: torch.Tensor) -> None:
        """Call ``write(prim, env_ids, *rows_of_values)`` for every prim with selected rows."""
        k_count = len(self._prims)
        for k, prim in enumerate(self._prims):
            sel = (rows % k_count == k).nonzero().reshape(-1)
            if sel.numel():
                env_ids = (rows[sel] // k_count).to(prim.entity.device)
                write(prim, env_ids, *[None if v is None else v[sel.to(v.device)] for v in values])
        self._prims[0].entity.engine.forward()

    def _values(self, value, rows: torch.Tensor, trailing: tuple[int, ...], what: str, scale=1.0):
        """User values for the selected rows as a (M, *trailing) tensor (engine dtype) times ``scale``."""
        if value is None:
            return None
        want = (len(rows), *trailing)
        fix = f"pass finite real numbers of shape {want}: one row per selected prim"
        check_real_dtype(what, value, fix)
        array = value if torch.is_tensor(value) else np.asarray(value, dtype=np.float64)
        check_all_finite(what, torch.as_tensor(array), fix)
        entity = self._prims[0].entity
        tensor = torch.as_tensor(array, dtype=entity.engine.dtype, device=entity.device)
        if tuple(tensor.shape) == trailing:
            tensor = tensor.expand(want)
        if tuple(tensor.shape) != want:
            raise InvalidValueError(what, Described(f"of shape {tuple(tensor.shape)}"), f"expected {want}", fix)
        return tensor * scale

    def _out(self, tensor: torch.Tensor):
        value = tensor.detach().clone()
        return value.cpu().numpy() if self._world.backend == "numpy" else value

    @property
    def _m(self) -> float:
        """Metres per stage unit."""
        return float(self._world.stage_units_in_meters)

    # -- poses -----------------------------------------------------------------------
    def get_world_poses(self, indices=None, clone: bool = True, usd: bool = True):
        """(positions (M, 3) stage units, orientations (M, 4) w x y z), world frame."""
        rows = self._rows(indices)
        pos = self._gather(lambda p: p.entity.data.root_pos_w, rows)
        quat = self._gather(lambda p: p.entity.data.root_quat_w, rows)
        return self._out(pos / self._m), self._out(quat)

    def set_world_poses(self, positions=None, orientations=None, indices=None, usd: bool = True) -> None:
        """Move the selected prims: (M, 3) stage units, (M, 4) w x y z (normalized), world frame."""
        rows = self._rows(indices)
        pos = self._values(positions, rows, (3,), "positions", self._m)
        quat = self._quats(orientations, rows)
        self._scatter(lambda p, env, pv, qv: p.entity.write_root_pose(pv, qv, env), rows, pos, quat)

    def get_local_poses(self, indices=None):
        """(translations (M, 3) stage units, orientations (M, 4)) relative to each parent prim."""
        rows = self._rows(indices)
        self._require()
        parts = [prim.get_local_pose() for prim in self._prims]
        as_t = [(torch.as_tensor(t).reshape(-1, 3), torch.as_tensor(q).reshape(-1, 4)) for t, q in parts]
        pos = torch.stack([t for t, _ in as_t], 1).reshape(-1, 3)[rows]
        quat = torch.stack([q for _, q in as_t], 1).reshape(-1, 4)[rows]
        return self._out(pos), self._out(quat)

    def set_local_poses(self, translations=None, orientations=None, indices=None) -> None:
        """Move the selected prims by poses relative to their parent prims."""
        rows = self._rows(indices)
        pos = self._values(translations, rows, (3,), "translations", self._m)
        quat = self._quats(orientations, rows)

        def write(prim, env, pv, qv):
            parent = prim._parent_pose()
            if parent is not None:
                from ..utils.math import quat_mul, quat_rotate

                p_pos, p_quat = parent[0][env], parent[1][env]
                pv = None if pv is None else p_pos + quat_rotate(p_quat, pv)
                qv = None if qv is None else quat_mul(p_quat, qv)
            prim.entity.write_root_pose(pv, qv, env)

        self._scatter(write, rows, pos, quat)

    def _quats(self, orientations, rows):
        quat = self._values(orientations, rows, (4,), "orientations")
        if quat is not None:
            if bool((quat.norm(dim=-1) < 1e-9).any()):
                raise InvalidValueError("orientations", Described("with a zero quaternion"), "it is no rotation",
                                        "pass (w, x, y, z) quaternions such as (1, 0, 0, 0)")
            quat = quat / quat.norm(dim=-1, keepdim=True)
        return quat

    # -- default state ------------------------------------------------------------------
    def _default_pose_rows(self, rows):
        pos = self._gather(lambda p: p._default_pose[0] if p._default_pose[0] is not None else p._initial_pose[0], rows)
        quat = self._gather(lambda p: p._default_pose[1] if p._default_pose[1] is not None else p._initial_pose[1], rows)
        return pos, quat

    def get_default_state(self) -> XFormPrimViewState:
        """The poses ``world.reset()`` restores (set_default_state, else those at initialization)."""
        pos, quat = self._default_pose_rows(self._rows(None))
        return XFormPrimViewState(self._out(pos / self._m), self._out(quat))

    def set_default_state(self, positions=None, orientations=None, indices=None) -> None:
        """Poses (M, 3) stage units and (M, 4) restored by every ``world.reset()``."""
        rows = self._rows(indices)
        pos, quat = self._values(positions, rows, (3,), "positions", self._m), self._quats(orientations, rows)

        def write(prim, env, pv, qv):
            old_pos, old_quat = prim._default_pose
            new_pos = (prim._initial_pose[0] if old_pos is None else old_pos).clone()
            new_quat = (prim._initial_pose[1] if old_quat is None else old_quat).clone()
            if pv is not None:
                new_pos[env] = pv
            if qv is not None:
                new_quat[env] = qv
            prim._default_pose = (new_pos, new_quat)

        self._scatter(write, rows, pos, quat)


class RigidPrimView(XFormPrimView):
    """Poses and velocities of the rigid bodies matching ``prim_paths_expr`` (see ``XFormPrimView``)."""

    _single = RigidPrim

    def __init__(self, prim_paths_expr, name: str = "rigid_prim_view", **kwargs):
        super().__init__(prim_paths_expr, name, **kwargs)

    def get_linear_velocities(self, indices=None, clone: bool = True):
        """(M, 3) stage units/s, world frame."""
        return self._out(self._gather(lambda p: p.entity.data.root_lin_vel_w, self._rows(indices)) / self._m)

    def get_angular_velocities(self, indices=None, clone: bool = True):
        """(M, 3) rad/s, world frame."""
        return self._out(self._gather(lambda p: p.entity.data.root_ang_vel_w, self._rows(indices)))

    def get_velocities(self, indices=None, clone: bool = True):
        """(M, 6): linear (stage units/s) then angular (rad/s) velocity, world frame."""
        rows = self._rows(indices)
        lin = self._gather(lambda p: p.entity.data.root_lin_vel_w, rows) / self._m
        return self._out(torch.cat([lin, self._gather(lambda p: p.entity.data.root_ang_vel_w, rows)], -1))

    def set_velocities(self, velocities, indices=None) -> None:
        """Set (M, 6) linear (stage units/s) and angular (rad/s) velocities, world frame."""
        rows = self._rows(indices)
        value = self._values(velocities, rows, (6,), "velocities")
        self._write_velocities(rows, value[:, :3] * self._m, value[:, 3:])

    def set_linear_velocities(self, velocities, indices=None) -> None:
        rows = self._rows(indices)
        self._write_velocities(rows, self._values(velocities, rows, (3,), "linear velocities", self._m), None)

    def set_angular_velocities(self, velocities, indices=None) -> None:
        rows = self._rows(indices)
        self._write_velocities(rows, None, self._values(velocities, rows, (3,), "angular velocities"))

    def _write_velocities(self, rows, lin, ang) -> None:
        self._scatter(lambda p, env, lv, av: p.entity.write_root_velocity(lv, av, env), rows, lin, ang)

    def get_masses(self, indices=None):
        """(M,) kg."""
        return self._out(self._gather(lambda p: p.entity.data.body_mass[:, 0], self._rows(indices)))

    def get_current_dynamic_state(self) -> DynamicsViewState:
        positions, orientations = self.get_world_poses()
        return DynamicsViewState(positions, orientations, self.get_linear_velocities(), self.get_angular_velocities())

    def get_default_state(self) -> DynamicsViewState:
        """Poses and velocities ``world.reset()`` restores."""
        rows = self._rows(None)
        pos, quat = self._default_pose_rows(rows)

        def velocity(i):
            return lambda p: (p._default_velocity[i] if p._default_velocity[i] is not None
                              else torch.zeros_like(p._initial_pose[0]))

        return DynamicsViewState(self._out(pos / self._m), self._out(quat),
                                 self._out(self._gather(velocity(0), rows) / self._m),
                                 self._out(self._gather(velocity(1), rows)))


class ArticulationView(RigidPrimView):
    """The articulations matching ``prim_paths_expr``: root poses and velocities (see
    ``RigidPrimView``) plus joints, (M, J) arrays in ``dof_names`` order for the M selected
    prims and the J joints of ``joint_indices`` (default all). Every match must have the
    same joints."""

    _single = Articulation

    def __init__(self, prim_paths_expr, name: str = "articulation_prim_view", **kwargs):
        XFormPrimView.__init__(self, prim_paths_expr, name, **kwargs)

    def initialize(self, world=None, physics_sim_view=None) -> None:
        super().initialize(world, physics_sim_view)
        names = self._prims[0].dof_names
        for prim in self._prims[1:]:
            if prim.dof_names != names:
                raise ValueError(f"view {self.name!r} mixes articulations with different joints: {prim.prim_path} "
                                 f"has {prim.dof_names}, {self._prims[0].prim_path} {names}; narrow the expression")

    @property
    def num_dof(self) -> int | None:
        return self._prims[0].num_dof if self._prims else None

    @property
    def dof_names(self) -> list[str] | None:
        return list(self._prims[0].dof_names) if self._prims else None

    @property
    def num_bodies(self) -> int | None:
        return self._prims[0].num_bodies if self._prims else None

    @property
    def body_names(self) -> list[str] | None:
        return self._prims[0].body_names if self._prims else None

    def get_dof_index(self, dof_name: str) -> int:
        self._require()
        return self._prims[0].get_dof_index(dof_name)

    def get_dof_limits(self):
        """(count, num_dof, 2) lower/upper limits (rad; prismatic stage units)."""
        rows = self._rows(None)
        limits = self._gather(lambda p: (p.entity.joint_pos_limits / p._dof_scale.unsqueeze(-1)).expand(
            p._world.num_worlds, -1, -1), rows)
        return self._out(limits)

    # -- joints ---------------------------------------------------------------------------
    def _joints(self, joint_indices) -> torch.Tensor:
        self._require()
        return self._prims[0]._indices(joint_indices)

    def _get_joints(self, field: str, indices, joint_indices):
        rows, idx = self._rows(indices), self._joints(joint_indices)
        read = (lambda p: getattr(p.entity.data, field)[:, idx] / p._dof_scale[idx]) if field != "joint_effort" \
            else (lambda p: p.entity.data.joint_effort[:, idx])
        return self._out(self._gather(read, rows))

    def get_joint_positions(self, indices=None, joint_indices=None, clone: bool = True):
        """(M, J) rad (prismatic stage units)."""
        return self._get_joints("joint_pos", indices, joint_indices)

    def get_joint_velocities(self, indices=None, joint_indices=None, clone: bool = True):
        """(M, J) rad/s (prismatic stage units/s)."""
        return self._get_joints("joint_vel", indices, joint_indices)

    def get_measured_joint_efforts(self, indices=None, joint_indices=None, clone: bool = True):
        """(M, J) N m (prismatic N) the drives exert."""
        return self._get_joints("joint_effort", indices, joint_indices)

    def get_joints_state(self) -> JointsState:
        return JointsState(self.get_joint_positions(), self.get_joint_velocities(), None)

    def _joint_values(self, value, indices, joint_indices, what: str, scaled: bool):
        rows, idx = self._rows(indices), self._joints(joint_indices)
        scale = self._prims[0]._dof_scale[idx] if scaled else 1.0
        return rows, idx, self._values(value, rows, (len(idx),), what, scale)

    def set_joint_positions(self, positions, indices=None, joint_indices=None) -> None:
        """Teleport joints of the selected prims: (M, J) rad (prismatic stage units)."""
        rows, idx, value = self._joint_values(positions, indices, joint_indices, "joint positions", True)
        self._scatter(lambda p, env, v: p.entity.write_joint_state(pos=v, env_ids=env, joint_ids=idx), rows, value)

    def set_joint_velocities(self, velocities, indices=None, joint_indices=None) -> None:
        rows, idx, value = self._joint_values(velocities, indices, joint_indices, "joint velocities", True)
        self._scatter(lambda p, env, v: p.entity.write_joint_state(vel=v, env_ids=env, joint_ids=idx), rows, value)

    def _set_targets(self, key: str, value, indices, joint_indices, scaled: bool) -> None:
        rows, idx, value = self._joint_values(value, indices, joint_indices, f"joint {key}", scaled)
        self._scatter(lambda p, env, v: p._controller._command(joint_idx=idx, env_ids=env, **{key: v}), rows, value)

    def set_joint_position_targets(self, positions, indices=None, joint_indices=None) -> None:
        """Drive targets (M, J) rad (prismatic stage units), held by each joint's PD drive."""
        self._set_targets("positions", positions, indices, joint_indices, True)

    def set_joint_velocity_targets(self, velocities, indices=None, joint_indices=None) -> None:
        """Drive velocity targets (M, J) rad/s (prismatic stage units/s)."""
        self._set_targets("velocities", velocities, indices, joint_indices, True)

    def set_joint_efforts(self, efforts, indices=None, joint_indices=None) -> None:
        """Feed-forward efforts (M, J) N m (prismatic N), clipped to the drives' limits."""
        self._set_targets("efforts", efforts, indices, joint_indices, False)

    def apply_action(self, control_actions, indices=None) -> None:
        """Apply an ``ArticulationActions`` ((M, J) arrays; None leaves a quantity as it is)."""
        if not isinstance(control_actions, (ArticulationActions, ArticulationAction)):
            raise TypeError(f"apply_action takes ArticulationActions, got {type(control_actions).__name__}")
        joints = control_actions.joint_indices
        for key, value, scaled in (("positions", control_actions.joint_positions, True),
                                   ("velocities", control_actions.joint_velocities, True),
                                   ("efforts", control_actions.joint_efforts, False)):
            if value is not None:
                self._set_targets(key, value, indices, joints, scaled)

    def get_applied_actions(self, clone: bool = True) -> ArticulationActions:
        """The targets in effect, (count, num_dof) each (efforts after clipping)."""
        rows = self._rows(None)
        pos = self._gather(lambda p: p._controller._q_target / p._dof_scale, rows)
        vel = self._gather(lambda p: p._controller._qd_target / p._dof_scale, rows)
        eff = self._gather(lambda p: p._controller._tau_ff, rows)
        return ArticulationActions(self._out(pos), self._out(vel), self._out(eff), None)

    def get_default_state(self) -> XFormPrimViewState:
        return XFormPrimView.get_default_state(self)



def _glob_hint(exprs: list[str], names: list[str]) -> str:
    """``'cube_*' is a regular expression here: did you mean '/World/cube_.*' (3 prims)?`` when a
    shell-style ``*`` in ``exprs`` (Isaac's expressions are regular expressions per component, so
    ``cube_*`` means "cube" and underscores) would match as ``.*``; '' otherwise."""
    globbed = [re.sub(r"(?<![.\\])\*", ".*", e) for e in exprs]
    if globbed == exprs:
        return ""
    matches = match_prim_paths(globbed, _prefixes(names))
    if not matches:
        return ""
    shown = globbed[0] if len(globbed) == 1 else globbed
    return (f"each path component is a regular expression, where '*' repeats the character before it: "
            f"did you mean {shown!r} ({len(matches)} prims)?")

__all__ = ["ArticulationView", "RigidPrimView", "XFormPrimView", "match_prim_paths"]
