"""Footstep planning for legged robots on 2-D grid maps: the map (``grid_map``), the footstep
lattice, its checks and heuristic, the A* planner (``footsteps``) and a picture of a plan
(``footstep_plot``). Walking a plan (balance, preview control, the whole-body controller) is
``ambulo.locomotion``'s."""

from .footstep_plot import plot_plan
from .footsteps import (
    FootstepPlan,
    FootstepPlanner,
    FootstepPlannerCfg,
    PlanStatus,
    humanoid_footstep_cfg,
    plan_footsteps,
)
from .grid_map import GridMap

__all__ = [
    "FootstepPlan",
    "FootstepPlanner",
    "FootstepPlannerCfg",
    "GridMap",
    "PlanStatus",
    "humanoid_footstep_cfg",
    "plan_footsteps",
    "plot_plan",
]
