"""Commands from ROS 2 into the simulator: checks that name the problem, and what applies them.

A command that fails a check is dropped with a warning (``ros2.warn``) and the robot keeps the
last good command: NaN/inf, wrong array length, unknown joint names, a Twist a differential drive
cannot follow (sideways or out-of-plane motion) or beyond the configured speed limits, a Twist
outside the walking policy's trained ranges, position targets outside a joint's range.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from ..robots.humanoid import POLICY_TASK

CmdVel = tuple[float, float, float]
"""(forward m/s, left m/s, yaw rate rad/s) in the robot's base frame."""


class CmdVelHandler(Protocol):
    """Turns a checked velocity command into robot actions; called before every physics step while
    a command is followed.

    Optional attributes the bridge reads: ``holonomic`` (linear.y allowed), ``problem`` (a reason to
    refuse every Twist), ``check(linear, angular) -> str | None`` (replaces the ``BridgeCfg`` speed
    limits with the handler's own), ``every_step`` (True: called every physics step from the start,
    with (0, 0, 0) until the first Twist, and paused by joint commands; see ``WalkingPolicyDrive``).
    """

    def __call__(self, command: CmdVel) -> None: ...


def _twist_values(linear, angular, holonomic: bool) -> tuple[dict[str, float], str | None]:
    """The six Twist values by name, and why they are not a finite planar command (or None)."""
    values = {f"linear.{a}": v for a, v in zip("xyz", linear)} | {f"angular.{a}": v for a, v in zip("xyz", angular)}
    for name, value in values.items():
        if not math.isfinite(value):
            return values, f"{name} is {value}: not a finite number"
    planar_only = ("linear.z", "angular.x", "angular.y") + (() if holonomic else ("linear.y",))
    for name in planar_only:
        if values[name] != 0.0:
            return values, (f"{name}={values[name]:g} but this robot {'moves' if holonomic else 'drives'} in the "
                            f"plane{'' if holonomic else ' and cannot move sideways'}; send only linear.x"
                            f"{', linear.y' if holonomic else ''} and angular.z")
    return values, None


def twist_problem(linear, angular, max_linear: float, max_angular: float, holonomic: bool) -> str | None:
    """Why a ``geometry_msgs/Twist`` (``linear``/``angular`` xyz) cannot be executed, or None."""
    values, problem = _twist_values(linear, angular, holonomic)
    if problem:
        return problem
    speed = math.hypot(values["linear.x"], values["linear.y"])
    if speed > max_linear:
        return f"linear speed {speed:g} m/s exceeds the robot's limit of {max_linear:g} m/s"
    if abs(values["angular.z"]) > max_angular:
        return f"angular.z {values['angular.z']:g} rad/s exceeds the robot's limit of {max_angular:g} rad/s"
    return None


def targets_problem(values, joint_names: list[str], limits: np.ndarray) -> str | None:
    """Why position targets ``values`` for ``joint_names`` (``limits`` (J, 2) rad or m) are refused, or None."""
    values = np.asarray(values, float)
    if len(values) != len(joint_names):
        return (f"got {len(values)} values for {len(joint_names)} joints; send one per joint in this order: "
                f"{', '.join(joint_names)}")
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        return f"value {values[bad[0]]} for joint {joint_names[bad[0]]!r} is not a finite number"
    outside = np.flatnonzero((values < limits[:, 0] - 1e-9) | (values > limits[:, 1] + 1e-9))
    if outside.size:
        i = outside[0]
        return (f"target {values[i]:g} for joint {joint_names[i]!r} is outside its range "
                f"[{limits[i, 0]:g}, {limits[i, 1]:g}]")
    return None


def names_problem(names: list[str], known: list[str]) -> str | None:
    """Why joint names of a ``sensor_msgs/JointState`` command are refused, or None."""
    unknown = [n for n in names if n not in known]
    if unknown:
        return f"unknown joint name {unknown[0]!r}; joints are {', '.join(known)}"
    if len(set(names)) != len(names):
        return "a joint name appears more than once"
    return None


class DifferentialDrive:
    """/cmd_vel for a ``WheeledRobot`` through Isaac's ``DifferentialController``."""

    holonomic = False

    def __init__(self, robot, controller=None):
        from ..sim import DifferentialController

        self.robot = robot
        self.controller = controller or DifferentialController()
        self._applied: CmdVel | None = None

    def __call__(self, command: CmdVel) -> None:
        if command == self._applied:  # the wheel drives keep their velocity targets
            return
        self.robot.apply_wheel_actions(self.controller.forward([command[0], command[2]]))
        self._applied = command


def range_problem(linear, angular, ranges: dict[str, tuple[float, float]], what: str) -> str | None:
    """Why a Twist is refused by a controller that takes (linear.x, linear.y, angular.z) each within
    ``ranges`` (``{"linear.x": (low, high), ...}``), or None."""
    values, problem = _twist_values(linear, angular, holonomic=True)
    if problem:
        return problem
    for name, (low, high) in ranges.items():
        if not low <= values[name] <= high:
            unit = "rad/s" if name.startswith("angular") else "m/s"
            return f"{name} {values[name]:g} {unit} exceeds {what} of [{low:g}, {high:g}] {unit}"
    return None


class NoWalkingPolicy:
    """/cmd_vel for a legged robot no shipped walking policy drives: every command is refused, saying why."""

    holonomic = True

    def __init__(self, problem: str | None = None):
        self.problem = problem or (
            "no walking policy for this robot (the shipped humanoid-walk policy drives the bundled humanoid "
            "only), so it cannot follow /cmd_vel; pass cmd_vel_handler= to Ros2Bridge, or command its joints "
            "on the joint command topics")

    def __call__(self, command: CmdVel) -> None:
        raise ValueError(self.problem)


class WalkingPolicyDrive:
    """/cmd_vel for the bundled humanoid through ``ambulo.sim.HumanoidWalkingPolicy``.

    Built when the bridge attaches: the walker stands the humanoid in the policy's default pose, and
    from then on ``forward`` runs every physics step with the command being followed, (0, 0, 0)
    (walking in place) until the first Twist. A Twist outside the policy's trained ranges
    (``contract.json``'s ``command_ranges`` for linear.x, linear.y and angular.z) is refused, not
    clipped. A joint command (``/joint_group_position_controller/command`` or
    ``/joint_command``) pauses the walker, so the joints hold what was commanded (joints it does not
    name keep the walker's last targets); the next accepted Twist hands the joints back to it.
    """

    holonomic = True
    every_step = True

    def __init__(self, robot, walker, physics_dt: float):
        self.robot, self.walker, self.physics_dt = robot, walker, physics_dt
        ranges = walker.contract["command_ranges"]
        self.ranges = {"linear.x": tuple(ranges["lin_vel_x_m_s"]), "linear.y": tuple(ranges["lin_vel_y_m_s"]),
                       "angular.z": tuple(ranges["yaw_rate_rad_s"])}
        walker.initialize()

    def check(self, linear, angular) -> str | None:
        return range_problem(linear, angular, self.ranges, "the walking policy's trained range")

    def __call__(self, command: CmdVel) -> None:
        self.walker.forward(self.physics_dt, command)

    def hand_over(self) -> None:
        """Before a joint command: the articulation's targets become the walker's last ones, so joints
        the command does not name hold them (the walker writes the drives directly)."""
        from ..sim import ArticulationAction

        last = self.walker.joint_targets()[0].cpu().numpy()
        self.robot.apply_action(ArticulationAction(joint_positions=last))


def walking_policy_handler(robot, physics_dt: float | None = None) -> CmdVelHandler:
    """``WalkingPolicyDrive`` when ``robot`` is the humanoid the shipped walking policy drives and
    the World steps at the policy's physics_dt; otherwise ``NoWalkingPolicy`` saying why."""
    from ..policies.shipped import load_policy, read_contract, shipped_tasks

    if POLICY_TASK not in shipped_tasks():
        return NoWalkingPolicy()
    contract = read_contract(POLICY_TASK)
    if list(robot.entity.joint_names) != contract["joint_names"]:
        return NoWalkingPolicy()
    wanted = float(contract["physics_dt_s"])
    if physics_dt is None or abs(physics_dt - wanted) > 1e-9:
        stepping = "an unknown time" if physics_dt is None else f"{physics_dt:g} s"
        return NoWalkingPolicy(
            f"the humanoid's walking policy was trained at physics_dt {wanted:g} s and this World steps "
            f"{stepping}, so it cannot follow /cmd_vel; create the World with physics_dt={wanted:g} "
            f"(`ambulo bridge humanoid` does, at its default --rate {1 / wanted:g})")
    from ..sim import HumanoidWalkingPolicy

    return WalkingPolicyDrive(robot, HumanoidWalkingPolicy(robot, policy=load_policy(POLICY_TASK)), physics_dt)


def default_cmd_vel_handler(robot, physics_dt: float | None = None) -> CmdVelHandler | None:
    """Differential drive for a ``WheeledRobot``; the shipped walking policy for the bundled humanoid
    (``walking_policy_handler``; it stands the humanoid in the policy's default pose); a refusal
    saying why for another free-floating robot; None (no /cmd_vel) for anything else."""
    from ..sim import WheeledRobot

    if isinstance(robot, WheeledRobot):
        return DifferentialDrive(robot)
    if robot.entity.is_floating:
        return walking_policy_handler(robot, physics_dt)
    return None


__all__ = ["CmdVel", "CmdVelHandler", "DifferentialDrive", "NoWalkingPolicy", "WalkingPolicyDrive",
           "default_cmd_vel_handler", "names_problem", "range_problem", "targets_problem", "twist_problem",
           "walking_policy_handler"]
