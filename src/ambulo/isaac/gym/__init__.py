"""Isaac Gym scripts unchanged under ``ambulo run``: ``isaacgym.gymapi``, ``gymtorch``, ``gymutil``.

The import hook (``ambulo.isaac.hook``) answers ``isaacgym.*`` from ``names.MODULES`` while a
script runs, so nothing is installed under Isaac's names. The parts:

- ``types``: ``Vec3``, ``Quat`` (x, y, z, w), ``Transform``, ``SimParams``/``PhysXParams``,
  ``AssetOptions``, ``PlaneParams``, ``CameraProperties``, the enums;
- ``assets``: ``load_asset`` through ambulo's importers, with Isaac's names and DOF properties;
- ``sim``: ``create_env``/``create_actor`` calls become ONE model stepped in N worlds;
- ``tensors``: the tensor API in Isaac Gym's layouts; ``gym``: the ``Gym`` interface object;
- ``gymapi``/``gymtorch``/``gymutil``/``torch_utils``: the modules scripts import;
- ``session``: what ``ambulo run`` sets up around a script (time budget, CUDA on a CPU host via
  ``device``, rl_games' ``RLGPU``/``ISAACGYM`` vecenvs via ``rl_games_env``).
"""

from .session import GymBudgetSpent, gym_session, simulated

__all__ = ["GymBudgetSpent", "gym_session", "simulated"]
