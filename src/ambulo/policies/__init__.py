"""Shipped policies and the observation recipes that feed them (content: below envs, sim and the apps).

- ``shipped``: ``load_policy(task)``, the trained networks in ``assets/data/policies`` with their
  ``contract.json``.
- ``velocity_obs``: ``velocity_policy_terms``, the velocity-tracking observation the humanoid-walk
  task trains on and the runner rebuilds.
- ``walking``: ``WalkingPolicy``, the shipped walking policy driving an ``Entity``
  (``sim.HumanoidWalkingPolicy`` is it on an Isaac-style ``Robot``).
- ``footstep_obs``, ``footstep_policy``: the humanoid-footsteps observation and ``FootstepPolicy``,
  its shipped policy driving an ``Entity`` (``navigation.footstep_walker`` gives it the footsteps).
"""

from .footstep_obs import FOOTSTEP_POLICY_TERMS, footstep_policy_terms
from .footstep_policy import FootstepPolicy
from .shipped import POLICY_DIR, ShippedPolicy, load_policy, policy_dir, read_contract, shipped_tasks
from .velocity_obs import VELOCITY_POLICY_TERMS, velocity_policy_terms
from .walking import WalkingPolicy

__all__ = ["FOOTSTEP_POLICY_TERMS", "POLICY_DIR", "VELOCITY_POLICY_TERMS", "FootstepPolicy", "ShippedPolicy",
           "WalkingPolicy", "footstep_policy_terms", "load_policy", "policy_dir", "read_contract", "shipped_tasks",
           "velocity_policy_terms"]
