"""``CommandIntake``: how a ``Ros2Bridge`` takes commands.

A listener thread receives what the publisher process forwards (Twists, joint commands, subscription
counts, its final counts), checks each command (``commands.py``: a bad one is refused with a warning
naming the problem) and leaves the latest good one pending; the physics thread applies it at the next
step (``apply``), so the physics loop never waits on the network.
"""

from __future__ import annotations

import logging
import threading
import time

import numpy as np

from .commands import names_problem, targets_problem, twist_problem

log = logging.getLogger("ambulo.ros2")


class CommandIntake:
    """A bridge's commands: ``receive`` (listener thread), ``warn`` and ``apply`` (physics thread).

    Args:
      cfg: the bridge's ``BridgeCfg`` (topics, speed limits).
      robot: the robot that takes commands (None: every command is ignored).
      command_joints: the joints a ``Float64MultiArray`` command names, in order.
      handler: what turns /cmd_vel into actions (``commands.CmdVelHandler``), or None.
      send: sends a message to the publisher process (a warning for its node to log).

    Attributes: ``cmd_vel`` (the velocity command being followed, or None), ``walking`` (a walking
    policy, a handler with ``every_step``, drives the joints: from attaching until a joint command,
    and again from the next accepted Twist), ``rejected`` (why each refused command was refused).
    """

    def __init__(self, cfg, robot, command_joints: list[str], handler, send):
        self.cfg, self.robot, self.command_joints, self.handler = cfg, robot, command_joints, handler
        self._send = send
        self._lock = threading.Lock()
        self.pending: dict[str, object] = {}
        """What the listener thread accepted since the last physics step (the latest of each kind)."""
        self.cmd_vel: tuple[float, float, float] | None = None
        self.every_step = bool(getattr(handler, "every_step", False))
        self.walking = self.every_step
        self.rejected: list[str] = []
        self._warned_at: dict[str, float] = {}

    def receive(self, msg: tuple) -> None:
        """A command the publisher process forwarded: checked here, kept pending when good."""
        if self.robot is None:
            return
        if msg[0] == "twist":
            self._on_twist(msg[1], msg[2])
        elif msg[0] == "joint_array":
            self._on_joint_array(msg[1])
        elif msg[0] == "joint_state":
            self._on_joint_state(msg[1], msg[2])

    def warn(self, topic: str, problem: str) -> None:
        """Refuse a command: remember why, and log it (at most once a second per problem)."""
        text = f"{topic}: command rejected: {problem}"
        self.rejected.append(text)
        now = time.monotonic()
        if now - self._warned_at.get(text, -1e9) >= 1.0:
            self._warned_at[text] = now
            try:
                self._send(("warn", text))  # the node logs it: to the console and /rosout
            except OSError:
                log.warning(text)

    # -- commands (listener thread) --------------------------------------------------------------
    def _on_twist(self, lin, ang) -> None:
        handler = self.handler
        if handler is None:
            return self.warn(self.cfg.cmd_vel_topic, f"robot {self.robot.name!r} has no velocity controller")
        check = getattr(handler, "check", None)
        problem = getattr(handler, "problem", None) or (check(lin, ang) if check is not None else twist_problem(
            lin, ang, self.cfg.max_linear_speed_m_s, self.cfg.max_angular_speed_rad_s,
            getattr(handler, "holonomic", False)))
        if problem:
            return self.warn(self.cfg.cmd_vel_topic, problem)
        with self._lock:
            self.pending["cmd_vel"] = (float(lin[0]), float(lin[1]), float(ang[2]))
            self.pending["walking"] = True  # the latest of a Twist and a joint command decides

    def _on_joint_array(self, data) -> None:
        values = np.asarray(data, float)
        limits = self.robot.entity.joint_pos_limits.cpu().numpy()[self.robot.entity.find_joints(self.command_joints)]
        problem = targets_problem(values, self.command_joints, limits)
        if problem:
            return self.warn(self.cfg.joint_command_topic, problem)
        with self._lock:
            self.pending["joints"] = (list(self.command_joints), values)
            self.pending["walking"] = False

    def _on_joint_state(self, names, positions) -> None:
        names, values = list(names), np.asarray(positions, float)
        problem = names_problem(names, list(self.robot.entity.joint_names))
        if problem is None:
            limits = self.robot.entity.joint_pos_limits.cpu().numpy()[self.robot.entity.find_joints(names)]
            problem = targets_problem(values, names, limits)
        if problem:
            return self.warn(self.cfg.joint_state_command_topic, problem)
        with self._lock:
            self.pending["joints"] = (names, values)
            self.pending["walking"] = False

    # -- applying them (physics thread, before each step) ------------------------------------------
    def apply(self) -> None:
        from ..sim import ArticulationAction

        if not self.pending and self.cmd_vel is None and not self.walking:  # nothing new, nothing to follow
            return
        with self._lock:
            pending, self.pending = self.pending, {}
            self.cmd_vel = pending.get("cmd_vel", self.cmd_vel)
        if self.every_step and "walking" in pending:
            if not pending["walking"]:  # a joint command pauses the walking policy until the next Twist
                hand_over = getattr(self.handler, "hand_over", None)
                if self.walking and hand_over is not None:
                    hand_over()
                self.cmd_vel = None
            self.walking = pending["walking"]
        if "joints" in pending:
            names, values = pending["joints"]
            idx = self.robot.entity.find_joints(names)
            self.robot.apply_action(ArticulationAction(joint_positions=values, joint_indices=idx))
        if self.handler is None or not (self.walking if self.every_step else self.cmd_vel is not None):
            return
        try:
            self.handler(self.cmd_vel or (0.0, 0.0, 0.0))  # a walking policy walks in place before a Twist
        except ValueError as err:
            self.cmd_vel, self.walking = None, False
            self.warn(self.cfg.cmd_vel_topic, str(err))


__all__ = ["CommandIntake"]
