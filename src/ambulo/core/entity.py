"""Entity: one robot or rigid body tree in N worlds, as documented batched tensors.

An ``Entity`` resolves a prim path in the compiled model once (root body, free joint,
hinge/slide joints, their drive actuators, bodies of the subtree) and then reads and
writes the engine's state tensors directly: RL tasks, randomizers and the Isaac-style
``Articulation``/``RigidPrim`` all go through it. Every tensor is ``(N, ...)`` on the
engine's device, in the engine's dtype (float64 on the CPU, float32 on a GPU).

Lag: state fields (``root_pos_w`` of a free body, ``joint_pos``, ``joint_vel``, velocities of a
free root) are read from ``qpos``/``qvel`` and are current after every engine step.
Derived fields (``body_pos_w``, ``body_quat_w``, ``body_lin_vel_w``, ``joint_effort``, the
root pose of a jointed or fixed root) come from kinematics that, after
``engine.step(refresh=False)``, describe the state one substep before the last
(as after ``mj_step``); ``engine.step(refresh=True)`` or ``engine.forward()`` makes them current.

Initial state: an ``Entity`` owns its ``InitState`` (as mjlab's ``EntityCfg.init_state``): root
pose and joint positions, often a keyframe of the robot's file (``InitState.from_keyframe``).
``apply_init_state`` writes it into every world and makes it what ``engine.reset`` restores: the
one place a robot's start pose enters a simulation, with no keyframe compiled into the model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ..utils.math import projected_gravity, quat_rotate, quat_rotate_inverse, yaw_from_quat
from ..utils.validate import Checked, rule
from .drives import is_drive
from .names import EntityNames
from .rows import put_rows, take_rows
from .scene import KeyPose, RobotCfg

_IDENTITY_QUAT = (1.0, 0.0, 0.0, 0.0)


@dataclass(kw_only=True)
class InitState(Checked):
    """Where an entity starts, and what a reset restores (mjlab's ``EntityCfg.InitialStateCfg``).

    Joints it does not name, and a root it leaves None, keep the compiled model's ``qpos0``
    (the robot as the scene placed it). Velocities start at zero.
    """

    joint_pos: dict[str, float] = field(default_factory=dict, metadata=rule(signed=True))
    """Joint name (relative to the prim path) -> position, rad or m; also the entity's
    ``default_joint_pos``."""
    root_pos_m: tuple[float, float, float] | None = field(default=None, metadata=rule(signed=True))
    """Free root position in the world frame, m."""
    root_quat: tuple[float, float, float, float] | None = field(default=None, metadata=rule(signed=True))
    """Free root orientation (w, x, y, z) in the world frame."""

    @classmethod
    def from_keyframe(cls, key: KeyPose, robot: RobotCfg | None = None,
                      joint_pos: dict[str, float] | None = None) -> InitState:
        """A keyframe of the robot's file (``core.add_robot``'s ``AttachedRobot.keyframes``) in the
        world: its root pose carried by the frame ``robot`` was attached at (``pos_m``, ``quat``),
        its joint positions with ``joint_pos`` overriding some."""
        joints = {**key.joint_pos, **(joint_pos or {})}
        if key.root_pos_m is None or (robot is not None and robot.fixed_base):  # no free joint, no root state
            return cls(joint_pos=joints)
        frame_pos = np.zeros(3) if robot is None else np.asarray(robot.pos_m, dtype=np.float64)
        frame_quat = np.asarray(_IDENTITY_QUAT if robot is None else robot.quat, dtype=np.float64)
        pos, quat = np.empty(3), np.empty(4)
        mujoco.mju_rotVecQuat(pos, np.asarray(key.root_pos_m, dtype=np.float64), frame_quat)
        mujoco.mju_mulQuat(quat, frame_quat, np.asarray(key.root_quat, dtype=np.float64))
        return cls(joint_pos=joints, root_pos_m=tuple((pos + frame_pos).tolist()), root_quat=tuple(quat.tolist()))


def _index(idx: np.ndarray, device: torch.device) -> slice | torch.Tensor:
    """A slice when ``idx`` is contiguous (indexing then gives a view), else an index tensor."""
    if idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0] + idx.size))
    return torch.as_tensor(idx, dtype=torch.long, device=device)


class Entity:
    """The bodies and joints under ``prim_path`` in every world of ``engine``.

    Args:
      engine: an ``ambulo.engine.Engine`` over the compiled scene.
      prim_path: the entity's prim path (``/World/robot``): a body of that name or the root
        of the subtree of bodies named ``<prim_path>/...``.
      init_state: the entity's initial state (``InitState``): its joint positions are also
        ``default_joint_pos``; None starts it as the model's ``qpos0``. ``apply_init_state``
        writes it into the worlds.
      soft_limit_factor: fraction of each joint's range, about its middle, that is "safe".
      require_drives: every joint must have an ambulo drive (``core.drives``).
    """

    def __init__(self, engine, prim_path: str, *, init_state: InitState | None = None,
                 soft_limit_factor: float = 0.9, require_drives: bool = True):
        model: mujoco.MjModel = engine.model
        self.engine = engine
        self.prim_path = prim_path.rstrip("/")
        self.device = torch.device(engine.device)
        self.num_worlds = engine.num_worlds
        self.names = names = EntityNames(model, self.prim_path)
        """The model-only name lookup (``core.names``) this view resolves elements with."""
        self.root_body_id = names.root_body_id
        self.body_names = names.body_names
        """Names of the entity's bodies relative to the prim path, in ``body_*`` order."""
        self._body_ids_np = names.body_ids
        self._roots_np = model.body_rootid[self._body_ids_np]

        self.is_floating = names.is_floating
        """Whether the root body has a free joint (else it is fixed or jointed to a parent)."""
        self._free_qpos = names.free_qpos_adr
        self._free_dof = names.free_dof_adr
        self._root_static = (not self.is_floating
                             and int(model.body_parentid[self.root_body_id]) == 0
                             and int(model.body_jntnum[self.root_body_id]) == 0)

        joints = names.joint_ids.tolist()
        self.joint_names = names.joint_names
        """Hinge/slide joint names relative to the prim path, in ``joint_*`` order."""
        self.num_joints = len(joints)
        self._joint_ids = np.asarray(joints, dtype=np.int64)
        self._qpos_adr = model.jnt_qposadr[self._joint_ids] if joints else np.zeros(0, np.int64)
        self._dof_adr = model.jnt_dofadr[self._joint_ids] if joints else np.zeros(0, np.int64)
        actuator_of = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)
                       if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and is_drive(model.actuator(a))}
        missing = [model.joint(j).name for j in joints if j not in actuator_of]
        if missing and require_drives:
            raise ValueError(
                f"joints {missing[:5]} of {self.prim_path} have no ambulo drive; load the robot "
                "through ambulo.core.add_robot / add_reference_to_stage (which adds drives)")
        self.has_drives = not missing
        self._act_adr = np.asarray([actuator_of.get(j, -1) for j in joints], dtype=np.int64)

        self.init_state = init_state = init_state or InitState()
        """Where the entity starts (``apply_init_state``)."""
        if (init_state.root_pos_m is not None or init_state.root_quat is not None) and not self.is_floating:
            raise ValueError(f"the initial state of {self.prim_path} sets a root pose, but its root has no free "
                             "joint; place a fixed robot with RobotCfg.pos_m / quat instead")
        default = model.qpos0[self._qpos_adr].copy()
        overrides = init_state.joint_pos
        unknown = sorted(set(overrides) - set(self.joint_names))
        if unknown:
            raise ValueError(f"the initial state names unknown joints {unknown}; "
                             f"joints of {self.prim_path}: {self.joint_names}")
        for name, value in overrides.items():
            default[self.joint_names.index(name)] = value
        limited = model.jnt_limited[self._joint_ids].astype(bool)
        rng = model.jnt_range[self._joint_ids].reshape(-1, 2)
        lower, upper = np.where(limited, rng[:, 0], -np.inf), np.where(limited, rng[:, 1], np.inf)
        mid, half = 0.5 * (rng[:, 0] + rng[:, 1]), 0.5 * (rng[:, 1] - rng[:, 0]) * soft_limit_factor

        dev, f64 = self.device, dict(dtype=engine.dtype, device=self.device)
        self.body_ids = torch.as_tensor(self._body_ids_np, device=dev)
        self._root_of_body = torch.as_tensor(self._roots_np, device=dev)
        self.qpos_idx = _index(self._qpos_adr, dev)
        self.dof_idx = _index(self._dof_adr, dev)
        self.actuator_idx = _index(self._act_adr, dev) if self.has_drives else None
        self._qpos_idx_t = torch.as_tensor(self._qpos_adr, dtype=torch.long, device=dev)
        self._dof_idx_t = torch.as_tensor(self._dof_adr, dtype=torch.long, device=dev)
        self._act_idx_t = torch.as_tensor(self._act_adr, dtype=torch.long, device=dev)
        self.default_joint_pos = torch.as_tensor(default, **f64)
        """(J,) default joint positions, rad or m."""
        self.joint_pos_limits = torch.as_tensor(np.stack([lower, upper], -1), **f64).reshape(-1, 2)
        """(J, 2) lower/upper joint limits, rad or m; +-inf where unlimited."""
        if model.nu:
            act = np.maximum(self._act_adr, 0)
            force_limited = (self._act_adr >= 0) & model.actuator_forcelimited[act].astype(bool)
            force_range = model.actuator_forcerange[act].reshape(-1, 2)
        else:  # a model without actuators (a scene's props, require_drives=False): nothing limits effort
            force_limited, force_range = np.zeros(len(self._act_adr), bool), np.zeros((len(self._act_adr), 2))
        self.joint_effort_limits = torch.as_tensor(np.stack(
            [np.where(force_limited, force_range[:, 0], -np.inf),
             np.where(force_limited, force_range[:, 1], np.inf)], -1), **f64).reshape(-1, 2)
        """(J, 2) lower/upper effort of each joint's drive, N m (or N); +-inf where unlimited."""
        self.soft_joint_pos_limits = torch.as_tensor(
            np.stack([np.where(limited, mid - half, -np.inf), np.where(limited, mid + half, np.inf)], -1),
            **f64).reshape(-1, 2)
        """(J, 2) the ``soft_limit_factor`` share of each range about its middle."""
        self.data = EntityData(self)

    # -- joints by name -------------------------------------------------------------------
    def find_joints(self, names) -> list[int]:
        """Indices (into ``joint_*``) of joints by name or full-match regex (``".*_knee"``), in
        the order given; a helpful KeyError for a name that matches nothing."""
        return self.names.find_joints(names)

    def find_bodies(self, names) -> list[int]:
        """Indices (into ``body_*``) of bodies by name."""
        return self.names.find_bodies(names)

    # -- writes -----------------------------------------------------------------------------
    def apply_init_state(self) -> None:
        """Write ``init_state`` into every world (joints at ``default_joint_pos``, the root where
        it says, this entity's velocities zero), recompute the kinematics, and make the engine's
        whole state the one ``engine.reset`` restores."""
        n, f64 = self.num_worlds, dict(dtype=self.engine.dtype, device=self.device)
        self.write_joint_state(pos=self.default_joint_pos.expand(n, -1), vel=torch.zeros(n, self.num_joints, **f64))
        state = self.init_state
        if self.is_floating:
            pos = None if state.root_pos_m is None else torch.tensor(state.root_pos_m, **f64).expand(n, 3)
            quat = None if state.root_quat is None else torch.tensor(state.root_quat, **f64).expand(n, 4)
            self.write_root_pose(pos_w=pos, quat_w=quat)
            d = self._free_dof
            self.engine.qvel[:, d:d + 6] = 0.0
        self.engine.forward()
        self.engine.capture_initial_state()

    def write_root_pose(self, pos_w: torch.Tensor | None = None, quat_w: torch.Tensor | None = None,
                        env_ids: torch.Tensor | None = None) -> None:
        """Set the root position (n, 3) m and orientation (n, 4) wxyz, world frame, of ``env_ids``.

        A free root writes its joint state; a static root (a body fixed to the world) moves per
        world through the model's ``body_pos``/``body_quat``. Derived fields update at the next
        ``engine.forward()``/step.
        """
        if self.is_floating:
            a = self._free_qpos
            if pos_w is not None:
                put_rows(self.engine.qpos, slice(a, a + 3), pos_w, env_ids)
            if quat_w is not None:
                put_rows(self.engine.qpos, slice(a + 3, a + 7), quat_w, env_ids)
        elif self._root_static:
            b = slice(self.root_body_id, self.root_body_id + 1)
            if pos_w is not None:
                put_rows(self.engine.model_field("body_pos"), b, pos_w.reshape(-1, 1, 3), env_ids)
            if quat_w is not None:
                put_rows(self.engine.model_field("body_quat"), b, quat_w.reshape(-1, 1, 4), env_ids)
        else:
            raise ValueError(f"{self.prim_path} is jointed to a parent body; move its root or "
                             "set its joint positions instead")

    def write_root_velocity(self, lin_vel_w: torch.Tensor | None = None,
                            ang_vel_w: torch.Tensor | None = None,
                            env_ids: torch.Tensor | None = None) -> None:
        """Set the free root's linear (n, 3) m/s and angular (n, 3) rad/s velocity, world frame."""
        if not self.is_floating:
            raise ValueError(f"{self.prim_path} has no free joint (it is fixed or jointed)")
        d = self._free_dof
        if lin_vel_w is not None:
            put_rows(self.engine.qvel, slice(d, d + 3), lin_vel_w, env_ids)
        if ang_vel_w is not None:
            quat = take_rows(self.data.root_quat_w, env_ids)
            ang_vel_w = torch.as_tensor(ang_vel_w, dtype=quat.dtype, device=quat.device)
            # MuJoCo keeps a free joint's angular velocity in the body frame
            put_rows(self.engine.qvel, slice(d + 3, d + 6), quat_rotate_inverse(quat, ang_vel_w), env_ids)

    def write_joint_state(self, pos: torch.Tensor | None = None, vel: torch.Tensor | None = None,
                          env_ids: torch.Tensor | None = None, joint_ids=None) -> None:
        """Set joint positions (n, j) and velocities (n, j) of ``env_ids`` and ``joint_ids`` (None: all).

        ``env_ids`` (here and in every ``write_*``): None, indices (values have one row each) or
        an (N,) bool mask (values have N rows; only masked worlds change, with no host sync)."""
        qpos_idx = self.qpos_idx if joint_ids is None else self._qpos_idx_t[joint_ids]
        dof_idx = self.dof_idx if joint_ids is None else self._dof_idx_t[joint_ids]
        if pos is not None:
            put_rows(self.engine.qpos, qpos_idx, pos, env_ids)
        if vel is not None:
            put_rows(self.engine.qvel, dof_idx, vel, env_ids)

    def set_joint_targets(self, pos: torch.Tensor, vel: torch.Tensor | None = None,
                          effort: torch.Tensor | None = None) -> None:
        """Drive every joint of every world: ``tau = kp (pos - q) + kd (vel - qd) + effort``.

        ``pos``, ``vel``, ``effort``: (N, J) targets (rad, rad/s, N m). Writes the drives'
        ``ctrl = kp pos + kd vel + effort`` with each world's own gains, so gain randomization
        holds; MuJoCo integrates the damping implicitly.
        """
        bias = self.engine.model_field("actuator_biasprm")
        act = self._require_drives()
        ctrl = -bias[:, act, 1] * pos
        if vel is not None:
            ctrl -= bias[:, act, 2] * vel
        if effort is not None:
            ctrl += effort
        self.engine.ctrl[:, act] = ctrl.to(self.engine.ctrl.dtype)

    def write_gains(self, kp: torch.Tensor | None = None, kd: torch.Tensor | None = None,
                    joint_ids=None, env_ids: torch.Tensor | None = None) -> None:
        """Set drive stiffness kp (N m/rad) and damping kd (N m s/rad) per world and joint."""
        self._require_drives()
        idx = self._act_idx_t if joint_ids is None else self._act_idx_t[joint_ids]
        bias = self.engine.model_field("actuator_biasprm")
        if kp is not None:
            put_rows(bias[..., 1], idx, -kp, env_ids)
        if kd is not None:
            put_rows(bias[..., 2], idx, -kd, env_ids)

    def _require_drives(self):
        if self.actuator_idx is None:
            raise ValueError(f"{self.prim_path} has joints without ambulo drives; it cannot be driven")
        return self.actuator_idx


class EntityData:
    """Live batched state of an ``Entity``: each property reads the engine's tensors."""

    def __init__(self, entity: Entity):
        self._e = entity

    # -- root -------------------------------------------------------------------------------
    @property
    def root_pos_w(self) -> torch.Tensor:
        """(N, 3) root body origin in the world frame, m."""
        e = self._e
        if e.is_floating:
            return e.engine.qpos[:, e._free_qpos:e._free_qpos + 3]
        return e.engine.xpos[:, e.root_body_id]

    @property
    def root_quat_w(self) -> torch.Tensor:
        """(N, 4) root body orientation (w, x, y, z) in the world frame."""
        e = self._e
        if e.is_floating:
            return e.engine.qpos[:, e._free_qpos + 3:e._free_qpos + 7]
        return e.engine.xquat[:, e.root_body_id]

    @property
    def root_lin_vel_w(self) -> torch.Tensor:
        """(N, 3) velocity of the root body origin in the world frame, m/s."""
        e = self._e
        if e.is_floating:
            return e.engine.qvel[:, e._free_dof:e._free_dof + 3]
        return self._origin_lin_vel_w(e.body_ids[:1], e._root_of_body[:1])[:, 0]

    @property
    def root_ang_vel_b(self) -> torch.Tensor:
        """(N, 3) root angular velocity in the root body frame, rad/s."""
        e = self._e
        if e.is_floating:
            return e.engine.qvel[:, e._free_dof + 3:e._free_dof + 6]
        return quat_rotate_inverse(self.root_quat_w, self.root_ang_vel_w)

    @property
    def root_ang_vel_w(self) -> torch.Tensor:
        """(N, 3) root angular velocity in the world frame, rad/s."""
        e = self._e
        if e.is_floating:
            return quat_rotate(self.root_quat_w, self.root_ang_vel_b)
        return e.engine.cvel[:, e.root_body_id, :3]

    @property
    def root_lin_vel_b(self) -> torch.Tensor:
        """(N, 3) velocity of the root origin in the root body frame, m/s."""
        return quat_rotate_inverse(self.root_quat_w, self.root_lin_vel_w)

    @property
    def projected_gravity_b(self) -> torch.Tensor:
        """(N, 3) unit gravity direction in the root body frame: (0, 0, -1) when upright."""
        return projected_gravity(self.root_quat_w)

    @property
    def heading_w(self) -> torch.Tensor:
        """(N,) yaw of the root about world z, rad."""
        return yaw_from_quat(self.root_quat_w)

    # -- joints -----------------------------------------------------------------------------
    @property
    def joint_pos(self) -> torch.Tensor:
        """(N, J) joint positions, rad or m."""
        return self._e.engine.qpos[:, self._e.qpos_idx]

    @property
    def joint_vel(self) -> torch.Tensor:
        """(N, J) joint velocities, rad/s or m/s."""
        return self._e.engine.qvel[:, self._e.dof_idx]

    @property
    def joint_pos_rel(self) -> torch.Tensor:
        """(N, J) joint positions relative to ``default_joint_pos``, rad or m."""
        return self.joint_pos - self._e.default_joint_pos

    @property
    def joint_effort(self) -> torch.Tensor:
        """(N, J) torque the drives exert on the joints (after force limits), N m (derived, lags)."""
        return self._e.engine.qfrc_actuator[:, self._e.dof_idx]

    @property
    def joint_stiffness(self) -> torch.Tensor:
        """(N, J) drive stiffness kp per world, N m/rad (a copy)."""
        return -self._e.engine.model_field("actuator_biasprm")[:, self._e._require_drives(), 1]

    @property
    def joint_damping(self) -> torch.Tensor:
        """(N, J) drive damping kd per world, N m s/rad (a copy)."""
        return -self._e.engine.model_field("actuator_biasprm")[:, self._e._require_drives(), 2]

    # -- bodies (derived: lag one substep after a step without refresh) ---------------------
    @property
    def body_pos_w(self) -> torch.Tensor:
        """(N, B, 3) body frame origins in the world frame, m."""
        return self._e.engine.xpos[:, self._e.body_ids]

    @property
    def body_quat_w(self) -> torch.Tensor:
        """(N, B, 4) body orientations (w, x, y, z), world frame."""
        return self._e.engine.xquat[:, self._e.body_ids]

    @property
    def body_ang_vel_w(self) -> torch.Tensor:
        """(N, B, 3) body angular velocities, world frame, rad/s."""
        return self._e.engine.cvel[:, self._e.body_ids, :3]

    @property
    def body_lin_vel_w(self) -> torch.Tensor:
        """(N, B, 3) velocities of the body frame origins, world frame, m/s.

        MuJoCo's ``cvel`` is a spatial velocity expressed at the subtree centre of mass of
        the kinematic tree's root, so the origin's velocity is v + w x (p_body - p_com).
        """
        return self._origin_lin_vel_w(self._e.body_ids, self._e._root_of_body)

    def _origin_lin_vel_w(self, ids: torch.Tensor, roots: torch.Tensor) -> torch.Tensor:
        engine = self._e.engine
        cvel = engine.cvel[:, ids]
        offset = engine.xpos[:, ids] - engine.subtree_com[:, roots]
        return cvel[..., 3:] + torch.cross(cvel[..., :3], offset, dim=-1)

    @property
    def body_mass(self) -> torch.Tensor:
        """(N, B) body masses per world, kg (a copy)."""
        return self._e.engine.model_field("body_mass")[:, self._e.body_ids]


__all__ = ["Entity", "EntityData", "InitState"]
