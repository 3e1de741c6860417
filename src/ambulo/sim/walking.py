"""HumanoidWalkingPolicy: the shipped walking policy on an Isaac-style ``Robot``.

``policies.WalkingPolicy`` drives an ``Entity``; a ``Robot`` has one only after ``world.reset()``.
So, as in Isaac Sim's policy examples, build this on the robot, call ``initialize()`` after the
reset (it binds the robot's entity and stands it in the policy's default pose), then
``forward(step_size, command)`` from a physics callback.
"""

from __future__ import annotations

from ..policies.shipped import ShippedPolicy
from ..policies.walking import WalkingPolicy
from ..robots.humanoid import POLICY_TASK


class HumanoidWalkingPolicy(WalkingPolicy):
    """``WalkingPolicy`` on ``robot``'s entity, bound at ``initialize()`` (see the module doc)."""

    def __init__(self, robot, task: str = POLICY_TASK, policy: ShippedPolicy | None = None):
        super().__init__(None, task, policy)
        self.robot = robot

    def initialize(self) -> None:
        """Check the robot is the one the policy drives and stand it in the default pose."""
        if self.robot.entity is None:
            raise RuntimeError("HumanoidWalkingPolicy.initialize() needs the world reset first: call "
                               "world.reset() before initialize()")
        self.bind(self.robot.entity)
        self.reset()


__all__ = ["HumanoidWalkingPolicy"]
