"""``CommandIntake``: how a ``Ros2Bridge`` takes commands (part of ``Ros2Bridge``, a mixin).

A listener thread receives what the publisher process forwards (Twists, joint commands, subscription
counts, its final counts), checks each command (``commands.py``: a bad one is refused with a warning
naming the problem) and leaves the latest good one pending; the physics thread applies it at the next
step (``_apply_commands``), so the physics loop never waits on the network.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .commands import names_problem, targets_problem, twist_problem

log = logging.getLogger("ambulo.ros2")


class CommandIntake:
    """``Ros2Bridge``'s commands: the listener thread (``_listen``, ``_on_*``), ``warn`` and
    ``_apply_commands`` (physics thread)."""

    def _listen(self) -> None:
        """Commands from the publisher process (this thread checks them, as rclpy's executor did)."""
        while True:
            try:
                msg = self._conn.recv()
            except (EOFError, OSError):
                return
            try:
                if msg[0] == "twist":
                    self._on_twist(msg[1], msg[2])
                elif msg[0] == "joint_array":
                    self._on_joint_array(msg[1])
                elif msg[0] == "joint_state":
                    self._on_joint_state(msg[1], msg[2])
                elif msg[0] == "matched":  # (matched, topic, subscriptions now, wall time s)
                    self.subscribers[msg[1]] = (msg[2], msg[3])
                elif msg[0] == "closed":
                    self._closed_counts = msg[1]
                    self.failed.update(msg[2])
                    return
            except Exception as err:  # noqa: BLE001 - a command must never end the bridge
                log.error("ROS 2 command %s failed: %s", msg[0], err)

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
        handler = self._handler
        if handler is None:
            return self.warn(self.cfg.cmd_vel_topic, f"robot {self.robot.name!r} has no velocity controller")
        check = getattr(handler, "check", None)
        problem = getattr(handler, "problem", None) or (check(lin, ang) if check is not None else twist_problem(
            lin, ang, self.cfg.max_linear_speed_m_s, self.cfg.max_angular_speed_rad_s,
            getattr(handler, "holonomic", False)))
        if problem:
            return self.warn(self.cfg.cmd_vel_topic, problem)
        with self._lock:
            self._pending["cmd_vel"] = (float(lin[0]), float(lin[1]), float(ang[2]))
            self._pending["walking"] = True  # the latest of a Twist and a joint command decides

    def _on_joint_array(self, data) -> None:
        values = np.asarray(data, float)
        limits = self.robot.entity.joint_pos_limits.cpu().numpy()[self.robot.entity.find_joints(self.command_joints)]
        problem = targets_problem(values, self.command_joints, limits)
        if problem:
            return self.warn(self.cfg.joint_command_topic, problem)
        with self._lock:
            self._pending["joints"] = (list(self.command_joints), values)
            self._pending["walking"] = False

    def _on_joint_state(self, names, positions) -> None:
        names, values = list(names), np.asarray(positions, float)
        problem = names_problem(names, list(self.robot.entity.joint_names))
        if problem is None:
            limits = self.robot.entity.joint_pos_limits.cpu().numpy()[self.robot.entity.find_joints(names)]
            problem = targets_problem(values, names, limits)
        if problem:
            return self.warn(self.cfg.joint_state_command_topic, problem)
        with self._lock:
            self._pending["joints"] = (names, values)
            self._pending["walking"] = False

    # -- applying them (physics thread, before each step) ------------------------------------------
    def _apply_commands(self) -> None:
        from ..sim import ArticulationAction  # noqa: PLC0415

        if not self._pending and self.cmd_vel is None and not self.walking:  # nothing new, nothing to follow
            return
        with self._lock:
            pending, self._pending = self._pending, {}
            self.cmd_vel = pending.get("cmd_vel", self.cmd_vel)
        if self._every_step and "walking" in pending:
            if not pending["walking"]:  # a joint command pauses the walking policy until the next Twist
                hand_over = getattr(self._handler, "hand_over", None)
                if self.walking and hand_over is not None:
                    hand_over()
                self.cmd_vel = None
            self.walking = pending["walking"]
        if "joints" in pending:
            names, values = pending["joints"]
            idx = self.robot.entity.find_joints(names)
            self.robot.apply_action(ArticulationAction(joint_positions=values, joint_indices=idx))
        if self._handler is None or not (self.walking if self._every_step else self.cmd_vel is not None):
            return
        try:
            self._handler(self.cmd_vel or (0.0, 0.0, 0.0))  # a walking policy walks in place before a Twist
        except ValueError as err:
            self.cmd_vel, self.walking = None, False
            self.warn(self.cfg.cmd_vel_topic, str(err))
