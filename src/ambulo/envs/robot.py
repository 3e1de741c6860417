"""PdRobot: index tables of a floating-base robot driven by ambulo's implicit PD actuators.

ambulo robot files give each actuated joint one ``general`` actuator with
``gainprm="1" biastype="affine" biasprm="0 -KP -KD"``, so the actuator force is
``ctrl - KP q - KD qd``: writing ``ctrl = KP q_target`` tracks ``q_target`` with stiffness
KP and damping KD, and MuJoCo integrates the damping implicitly. KP and KD are read back
from ``actuator_biasprm`` (a gear g scales position and force, hence ``ctrl = KP g q_target``).
"""

from __future__ import annotations

import mujoco
import numpy as np
import torch

from ..sim.drives import is_drive


def _index(idx: np.ndarray, device: torch.device) -> slice | torch.Tensor:
    """A slice when ``idx`` is contiguous (a zero-copy view when indexing), else an index tensor."""
    if idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0] + idx.size))
    return torch.as_tensor(idx, device=device)


class PdRobot:
    """Where a robot's base and joints live in the engine's state, and its PD gains.

    Args:
      model: the compiled scene.
      base_body: full name of the root body, which must carry a free joint.
      default_joint_pos: joint name (without ``prefix``) -> default position, rad.
      prefix: the robot's name prefix in the scene.
      soft_limit_factor: fraction of each joint's range, about its middle, that is "safe".
    """

    def __init__(self, model: mujoco.MjModel, base_body: str, default_joint_pos: dict[str, float],
                 prefix: str = "", soft_limit_factor: float = 0.9):
        self.base_body = model.body(base_body).id
        jnt = model.body_jntadr[self.base_body]
        if jnt < 0 or int(model.jnt_type[jnt]) != mujoco.mjtJoint.mjJNT_FREE.value:
            raise ValueError(f"body {base_body!r} has no free joint; the base must be floating")
        qadr, dadr = int(model.jnt_qposadr[jnt]), int(model.jnt_dofadr[jnt])
        self.pos_slice = slice(qadr, qadr + 3)
        self.quat_slice = slice(qadr + 3, qadr + 7)
        self.lin_vel_slice = slice(dadr, dadr + 3)
        self.ang_vel_slice = slice(dadr + 3, dadr + 6)

        if not all(is_drive(model.actuator(a)) for a in range(model.nu)):
            raise ValueError(
                "every actuator must be an implicit-PD joint drive: <general joint=... gainprm='1' "
                "biastype='affine' biasprm='0 -KP -KD'/>")
        joints = model.actuator_trnid[:, 0]
        self.num_joints = len(joints)
        self.joint_names = [model.joint(j).name.removeprefix(prefix) for j in joints]
        self._qpos_idx = model.jnt_qposadr[joints]
        self._dof_idx = model.jnt_dofadr[joints]
        gear = model.actuator_gear[:, 0]
        self.kp = -model.actuator_biasprm[:, 1].copy()
        """(J,) position gain per joint, N m / rad."""
        self.kd = -model.actuator_biasprm[:, 2].copy()
        """(J,) damping gain per joint, N m s / rad."""
        self._ctrl_gain = self.kp * gear

        default = model.qpos0[self._qpos_idx].copy()
        unknown = sorted(set(default_joint_pos) - set(self.joint_names))
        if unknown:
            raise ValueError(f"default_joint_pos names unknown joints {unknown}; "
                             f"actuated joints: {self.joint_names}")
        for name, value in default_joint_pos.items():
            default[self.joint_names.index(name)] = value
        self._default = default
        limited = model.jnt_limited[joints].astype(bool)
        rng = model.jnt_range[joints]
        lower = np.where(limited, rng[:, 0], -np.inf)
        upper = np.where(limited, rng[:, 1], np.inf)
        mid, half = 0.5 * (rng[:, 0] + rng[:, 1]), 0.5 * (rng[:, 1] - rng[:, 0]) * soft_limit_factor
        self._lower, self._upper = lower, upper
        self._soft = (np.where(limited, mid - half, -np.inf), np.where(limited, mid + half, np.inf))
        self.to_device(torch.device("cpu"))

    def to_device(self, device: torch.device) -> None:
        """Build the index and gain tensors on ``device``."""
        f64 = dict(dtype=torch.float64, device=device)
        self.qpos_idx = _index(self._qpos_idx, device)
        self.dof_idx = _index(self._dof_idx, device)
        self._qpos_idx_t = torch.as_tensor(self._qpos_idx, device=device)
        self.default_joint_pos = torch.as_tensor(self._default, **f64)
        """(J,) default joint positions, rad."""
        self.ctrl_gain = torch.as_tensor(self._ctrl_gain, **f64)
        self.joint_lower = torch.as_tensor(self._lower, **f64)
        self.joint_upper = torch.as_tensor(self._upper, **f64)
        self.soft_lower = torch.as_tensor(self._soft[0], **f64)
        self.soft_upper = torch.as_tensor(self._soft[1], **f64)

    # -- reads -------------------------------------------------------------------------
    def base_quat_w(self, engine) -> torch.Tensor:
        """(N, 4) base orientation (w, x, y, z), world frame."""
        return engine.qpos[:, self.quat_slice]

    def joint_pos(self, engine) -> torch.Tensor:
        """(N, J) actuated joint positions, rad."""
        return engine.qpos[:, self.qpos_idx]

    def joint_pos_rel(self, engine) -> torch.Tensor:
        """(N, J) actuated joint positions relative to the default pose, rad."""
        return engine.qpos[:, self.qpos_idx] - self.default_joint_pos

    def joint_vel(self, engine) -> torch.Tensor:
        """(N, J) actuated joint velocities, rad/s."""
        return engine.qvel[:, self.dof_idx]

    # -- writes ------------------------------------------------------------------------
    def set_joint_targets(self, engine, offset: torch.Tensor) -> None:
        """Track ``default + offset`` ((N, J) rad) with the PD actuators (zero target velocity)."""
        torch.mul(self.default_joint_pos + offset, self.ctrl_gain, out=engine.ctrl)

    def write_base_quat(self, engine, env_ids: torch.Tensor, quat: torch.Tensor) -> None:
        engine.qpos[env_ids, self.quat_slice] = quat

    def write_joint_pos(self, engine, env_ids: torch.Tensor, offset: torch.Tensor) -> None:
        """Set joints of ``env_ids`` to ``default + offset`` clamped to their limits."""
        pos = torch.clamp(self.default_joint_pos + offset, self.joint_lower, self.joint_upper)
        engine.qpos[env_ids.unsqueeze(1), self._qpos_idx_t.unsqueeze(0)] = pos
