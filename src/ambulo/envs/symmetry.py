"""Left-right mirror symmetry of the walking tasks: observations and actions reflected through the
robot's sagittal plane (the base frame's x-z plane, y -> -y).

A biped that walks well with its left leg walks as well with its right: the mirror image of every
transition is a transition of the same task. Training on both (data augmentation: Mittal et al.,
ICRA 2024, rsl-rl's ``Symmetry`` extension; FastSAC's ``use_symmetry``) doubles what each world's
experience teaches and keeps gaits from limping to one side.

Everything is derived from the robot model and the task's observation terms, never restated:

- joints: each ``left_*`` joint pairs with its ``right_*`` namesake (a joint with neither in its
  name, a waist joint, pairs with itself). The sign comes from the joints' world axes at the model's
  rest pose: a hinge's angle is a rotation about its axis, and reflection maps a rotation axis ``a``
  to ``(-a_x, a_y, -a_z)`` (an axial vector), so a roll or yaw joint flips sign and a pitch joint
  keeps it, whatever sign the file wrote the axis with (a slide's axis is a polar vector). The pairing is checked: mirrored anchors and
  axes must coincide, and the default pose must be its own mirror image.
- observation terms, by name (``TERM_RULES``): vectors, axial vectors, commands, joint-space terms,
  per-foot terms (the feet swapped), the height scan (each point swapped with its image across
  the heading axis), footstep commands (lateral offset, yaw and side negated, the order kept) and
  sole poses (the soles swapped). A term without a rule is refused: a wrong mirror teaches a wrong policy, so
  a new term must say how it reflects.

``task_mirror(env)`` returns a ``TaskMirror`` of index-and-sign maps; applying one is a gather and a
multiply, on the device, for any batch shape.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco
import numpy as np
import torch

from ..utils.checks import InvalidValueError

POLAR = (1.0, -1.0, 1.0)
"""Sign of each component of a vector (position, velocity, gravity) under y -> -y."""
AXIAL = (-1.0, 1.0, -1.0)
"""Sign of each component of an axial vector (angular velocity, rotation axis) under y -> -y: the
reflection's determinant -1 times the polar signs."""
COMMAND = (1.0, -1.0, -1.0)
"""(vx, vy, yaw rate): forward speed kept, lateral speed and turning reversed."""

class SymmetryError(InvalidValueError):
    """A robot or task that cannot be mirrored: one line naming what and how to go on (the CLI shows
    it as bad input, not as a bug)."""

    def __init__(self, message: str):
        ValueError.__init__(self, message)


_SIDES = (("left", "right"), ("Left", "Right"), ("LEFT", "RIGHT"))


def mirror_name(name: str) -> str:
    """``name`` with left and right swapped (``left_knee`` <-> ``right_knee``); unchanged if it has
    neither (a joint on the mid-plane)."""
    for left, right in _SIDES:
        if left in name or right in name:
            swap = {left: right, right: left}
            return re.sub(f"{left}|{right}", lambda m, swap=swap: swap[m.group(0)], name)
    return name


@dataclass(frozen=True)
class Reflection:
    """A mirror map of a vector's last axis: ``out[..., i] = sign[i] * x[..., index[i]]``."""

    index: torch.Tensor
    """(D,) long: the component each output component reads."""
    sign: torch.Tensor
    """(D,) float32: +1 or -1."""

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        """The mirror image of ``x`` (..., D)."""
        return x.index_select(-1, self.index) * self.sign.to(x.dtype)

    @property
    def size(self) -> int:
        return int(self.index.numel())


def _reflection(index, sign, device) -> Reflection:
    return Reflection(torch.as_tensor(np.asarray(index), dtype=torch.long, device=device),
                      torch.as_tensor(np.asarray(sign), dtype=torch.float32, device=device))


def joint_mirror(model: mujoco.MjModel, prim_path: str, joint_names: list[str], default_pos: np.ndarray,
                 *, tol: float = 1.0e-4) -> tuple[np.ndarray, np.ndarray]:
    """(index, sign), each (J,): mirrored joint ``i`` reads ``sign[i] * q[index[i]]``.

    ``joint_names`` are relative to ``prim_path`` (``Entity.joint_names``); ``default_pos`` (J,) the
    default joint positions, rad. Raises SymmetryError naming the joint when the model is not
    mirror-symmetric (a missing partner, anchors or axes that are not mirror images, an asymmetric
    default pose)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # the rest pose qpos0: every hinge at 0
    prefix = prim_path.rstrip("/") + "/"
    ids = [model.joint(prefix + n).id for n in joint_names]
    root = int(model.body_rootid[model.jnt_bodyid[ids[0]]]) if ids else 0
    root_rot = data.xmat[root].reshape(3, 3)
    # anchors and axes in the root body's frame: the robot may stand anywhere in the world
    anchors = (data.xanchor[ids] - data.xpos[root]) @ root_rot
    axes = data.xaxis[ids] @ root_rot
    position = {n: i for i, n in enumerate(joint_names)}
    index, sign = np.zeros(len(ids), np.int64), np.zeros(len(ids))
    polar, axial = np.asarray(POLAR), np.asarray(AXIAL)
    for i, name in enumerate(joint_names):
        partner = mirror_name(name)
        if partner not in position:
            raise SymmetryError(f"{prim_path}: joint {name!r} has no mirror partner {partner!r}; "
                                "symmetry needs left_/right_ joint pairs; train it without symmetry")
        j = position[partner]
        if np.abs(anchors[i] * polar - anchors[j]).max() > 1.0e-3:
            raise SymmetryError(f"{prim_path}: joints {name!r} and {partner!r} are not at mirror-image places "
                                f"({anchors[i].round(4).tolist()} vs {anchors[j].round(4).tolist()} m in the base frame)")
        kind = model.jnt_type[ids[i]]
        if kind not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            raise SymmetryError(f"{prim_path}: joint {name!r} is neither a hinge nor a slide; symmetry mirrors "
                                "those only; train it without symmetry")
        # a hinge turns about its axis (an axial vector), a slide moves along it (a polar one)
        reflect = axial if kind == int(mujoco.mjtJoint.mjJNT_HINGE) else polar
        dot = float(np.dot(axes[i] * reflect, axes[j]))
        if abs(abs(dot) - 1.0) > tol:
            raise SymmetryError(f"{prim_path}: joint axes of {name!r} and {partner!r} are not mirror images "
                                f"({axes[i].round(4).tolist()} vs {axes[j].round(4).tolist()})")
        index[i], sign[i] = j, np.sign(dot)
    mirrored = sign * np.asarray(default_pos, dtype=np.float64)[index]
    bad = np.flatnonzero(np.abs(mirrored - default_pos) > 1.0e-6)
    if bad.size:
        names = [joint_names[b] for b in bad[:4]]
        raise SymmetryError(f"{prim_path}: the default pose is not its own mirror image at joints {names}; "
                            "symmetry needs a left-right symmetric default pose; train it without symmetry")
    return index, sign


def pair_mirror(names: list[str]) -> np.ndarray:
    """(K,) index of each name's mirror partner in ``names`` (per-foot terms: the feet swap)."""
    position = {n: i for i, n in enumerate(names)}
    missing = [n for n in names if mirror_name(n) not in position]
    if missing:
        raise SymmetryError(f"{missing} have no mirror partner among {names}")
    return np.asarray([position[mirror_name(n)] for n in names], np.int64)


def points_mirror(points_xy: np.ndarray, *, tol: float = 1.0e-5) -> np.ndarray:
    """(P,) index of the point at (x, -y) for each of ``points_xy`` (P, 2) (the height scan's grid
    in the heading frame); raises ValueError if the grid is not symmetric about the x axis."""
    pts = np.asarray(points_xy, np.float64)
    image = pts * np.asarray([1.0, -1.0])
    dist = np.abs(image[:, None, :] - pts[None, :, :]).max(axis=-1)  # (P, P)
    index = dist.argmin(axis=1)
    if (dist[np.arange(len(pts)), index] > tol).any():
        raise SymmetryError("the height scan's points are not symmetric about the heading axis "
                            "(HeightScanCfg: give an odd number of points across, centred)")
    return index


@dataclass(frozen=True)
class TaskMirror:
    """A task's mirror maps: the actor's observations, the critic's (None without privileged
    observations) and the actions."""

    policy: Reflection
    critic: Reflection | None
    actions: Reflection


def _vector_rule(signs):
    def rule(size, ctx):
        if size % 3:
            raise SymmetryError(f"a 3-vector term of size {size}")
        return np.arange(size), np.tile(signs, size // 3)
    return rule


def _joint_rule(size, ctx):
    index, sign = ctx["joints"]
    if size != len(index):
        raise SymmetryError(f"a joint-space term of size {size} for {len(index)} joints")
    return index, sign


def _feet_rule(size, ctx):
    index = ctx["feet"]
    if size != len(index):
        raise SymmetryError(f"a per-foot term of size {size} for {len(index)} feet")
    return index, np.ones(size)


def _scan_rule(size, ctx):
    index = ctx.get("scan")
    if index is None or size != len(index):
        raise SymmetryError(f"a height scan of size {size} without the task's scan points")
    return index, np.ones(size)


def _footsteps_rule(size, ctx):
    # per target (the next two, in order): x, y, [z,] cos yaw, sin yaw, side (+1 left), heading frame
    per = {10: (1.0, -1.0, 1.0, -1.0, -1.0), 12: (1.0, -1.0, 1.0, 1.0, -1.0, -1.0)}.get(size)
    if per is None:
        raise SymmetryError(f"a footstep command of size {size} (10 or 12: two targets of x, y, [z,] cos, sin, side)")
    return np.arange(size), np.tile(per, 2)


def _soles_rule(size, ctx):
    index = ctx.get("soles")
    if index is None or size != 3 * len(index):
        raise SymmetryError(f"a per-sole (x, y, yaw) term of size {size} without the task's sole sites")
    return (np.concatenate([np.arange(3) + 3 * j for j in index]), np.tile((1.0, -1.0, -1.0), len(index)))


def _scalar_rule(size, ctx):
    return np.arange(size), np.ones(size)


TERM_RULES = {
    "projected_gravity": _vector_rule(POLAR),
    "base_lin_vel": _vector_rule(POLAR),
    "base_ang_vel": _vector_rule(AXIAL),
    "velocity_commands": _vector_rule(COMMAND),
    "joint_pos_rel": _joint_rule,
    "joint_vel": _joint_rule,
    "actions": _joint_rule,
    "base_height": _scalar_rule,
    "feet_contact": _feet_rule,
    "feet_height_over_ground": _feet_rule,
    "height_scan": _scan_rule,
    "footsteps": _footsteps_rule,
    "soles_b": _soles_rule,
}
"""How each observation term reflects, by the name the task gives it (``_policy_terms`` and
``_privileged_terms``): ``rule(size, context) -> (index, sign)`` over the term's own columns."""


def _terms_mirror(terms: list[tuple[str, torch.Tensor]], ctx: dict, task: str, device) -> Reflection:
    index, sign, start = [], [], 0
    for name, value in terms:
        rule = TERM_RULES.get(name)
        if rule is None:
            raise SymmetryError(f"{task}: observation term {name!r} has no mirror rule; add one to "
                                "ambulo.envs.symmetry.TERM_RULES or train without symmetry")
        size = int(value.shape[1])
        try:
            i, s = rule(size, ctx)
        except SymmetryError as err:
            raise SymmetryError(f"{task}: term {name!r}: {err}") from None
        index.append(np.asarray(i) + start)
        sign.append(np.asarray(s, np.float64))
        start += size
    return _reflection(np.concatenate(index), np.concatenate(sign), device)


def task_mirror(env) -> TaskMirror:
    """The mirror maps of a walking task's env (an ``RLEnv`` with ``robot``, ``_policy_terms`` and,
    with privileged observations, ``_privileged_terms``; ``feet_body_ids`` and ``scanner`` when it has
    per-foot terms or a height scan). Actions are joint targets about the default pose, one a joint."""
    task = type(env).__name__
    robot = env.robot
    default = robot.default_joint_pos.detach().cpu().double().numpy().reshape(-1)  # (J,)
    joints = joint_mirror(robot.engine.model, robot.prim_path, list(robot.joint_names), default)
    ctx = {"joints": joints}
    if getattr(env, "feet_body_ids", None) is not None:
        ctx["feet"] = pair_mirror([robot.body_names[i] for i in env.feet_body_ids.tolist()])
    if getattr(env.cfg, "sole_sites", None):
        ctx["soles"] = pair_mirror(list(env.cfg.sole_sites))
    if getattr(env, "scanner", None) is not None:
        ctx["scan"] = points_mirror(env.scanner.points_h.cpu().numpy())
    if env.num_actions != len(joints[0]):
        raise SymmetryError(f"{task}: {env.num_actions} actions for {len(joints[0])} joints; symmetry needs one "
                            "action a joint; train it without symmetry")
    # the critic's columns are the policy terms (noise-free) and then the privileged ones (RLEnv)
    policy = list(env._policy_terms().items())
    privileged = env._privileged_terms()
    critic = None if privileged is None else _terms_mirror(policy + list(privileged.items()), ctx, task, env.device)
    return TaskMirror(policy=_terms_mirror(policy, ctx, task, env.device), critic=critic,
                      actions=_reflection(*joints, env.device))


__all__ = ["AXIAL", "COMMAND", "POLAR", "TERM_RULES", "Reflection", "TaskMirror", "joint_mirror", "mirror_name",
           "pair_mirror", "points_mirror", "task_mirror", "SymmetryError"]
