"""Joint drives: one actuator per joint realising Isaac's implicit PD drive.

Convention (the "ambulo drive"): a ``general`` actuator on the joint with
``gainprm[0] = 1``, affine bias ``biasprm = (0, -kp, -kd)``, unlimited ctrl. With
``ctrl = kp * q_target + kd * qd_target + tau_ff`` the joint torque is

    tau = kp (q_target - q) + kd (qd_target - qd) + tau_ff,

and because the velocity term lives in the actuator's bias, MuJoCo's implicitfast
integrator treats the damping implicitly -- the "implicit PD" of Isaac's drives,
stable at gains an explicit PD would blow up with. Gains are per world
(``actuator_biasprm`` is an expandable model field) so they can be randomized.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

from ..utils.validate import Checked
from .names import DOF_JOINT_TYPES

_JOINT = mujoco.mjtTrn.mjTRN_JOINT
_AFFINE = mujoco.mjtBias.mjBIAS_AFFINE
_NO_BIAS = mujoco.mjtBias.mjBIAS_NONE
_FIXED = mujoco.mjtGain.mjGAIN_FIXED


@dataclass(kw_only=True)
class DriveDefaults(Checked):
    """Gains given to joints that arrive without a drive (URDF, USD, bare MJCF)."""

    stiffness: float = 100.0
    """kp, N*m/rad (or N/m for slide joints)."""
    damping: float = 5.0
    """kd, N*m*s/rad."""


def is_drive(actuator) -> bool:
    """Whether a spec or model actuator follows the ambulo drive convention."""
    return (
        actuator.trntype == _JOINT
        and actuator.gaintype == _FIXED
        and actuator.biastype == _AFFINE
        and actuator.gainprm[0] == 1.0
        and actuator.biasprm[0] == 0.0
    )


def ensure_drives(spec: mujoco.MjSpec, defaults: DriveDefaults) -> None:
    """Give every hinge/slide joint exactly one ambulo drive.

    Position servos (``<position kp kv>``) are converted in place, keeping their
    gains and force limits; velocity servos become drives with kp = 0; motors
    become drives with kp = kd = 0 (pure effort) keeping force limits. Joints with
    no actuator get a drive with ``defaults``.
    """
    driven: set[str] = set()
    for act in list(spec.actuators):
        if act.trntype != _JOINT or not act.target:
            continue
        if act.target in driven:
            raise ValueError(
                f"joint {act.target!r} has several actuators; ambulo drives one actuator per "
                "joint. Remove the extra <actuator> entries or merge them."
            )
        _convert(act)
        driven.add(act.target)
    for joint in spec.joints:
        if int(joint.type) in DOF_JOINT_TYPES and joint.name and joint.name not in driven:
            add_drive(spec, joint.name, defaults.stiffness, defaults.damping)


def add_drive(spec: mujoco.MjSpec, joint: str, kp: float, kd: float,
              max_force: float | None = None):
    """Add the ambulo drive of ``joint`` (gains kp N*m/rad, kd N*m*s/rad; optional force limit N*m)."""
    act = spec.add_actuator(name=joint, target=joint, trntype=_JOINT)
    _set_gains(act, kp, kd)
    if max_force is not None:
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-max_force, max_force]
    return act


def _set_gains(act, kp: float, kd: float) -> None:
    act.gaintype, act.biastype = _FIXED, _AFFINE
    act.gainprm[:3] = [1.0, 0.0, 0.0]
    act.biasprm[:3] = [0.0, -kp, -kd]
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


def _convert(act) -> None:
    if is_drive(act):
        return
    gain, bias = act.gainprm[0], act.biasprm
    if act.biastype == _AFFINE and act.gaintype == _FIXED and bias[1] == -gain:
        kp, kd = gain, -bias[2]  # position servo: gain kp, bias (0, -kp, -kv)
    elif act.biastype == _AFFINE and act.gaintype == _FIXED and bias[1] == 0 and bias[2] == -gain:
        kp, kd = 0.0, gain  # velocity servo: gain kv, bias (0, 0, -kv)
    elif act.biastype == _NO_BIAS:
        kp, kd = 0.0, 0.0  # motor: effort only
    else:
        raise ValueError(
            f"actuator {act.name!r} on joint {act.target!r} is neither a position/velocity "
            "servo nor a motor; ambulo cannot turn it into a joint drive."
        )
    # the drive's force is the joint torque, so fold the gear into the limits
    gear = act.gear[0]
    if gear != 1.0:
        act.forcerange = [r * gear for r in act.forcerange]
        act.gear[0] = 1.0
    _set_gains(act, kp, kd)
