"""Navigation for legged robots: grid maps, the footstep planner, balance (ZMP, capture point,
centre of pressure), the preview-control walking pattern generator, and the whole-body
controller that walks the bundled humanoid along a pattern in MuJoCo (``walk_controller``,
``walk_sim``; pictures in ``walk_plot``)."""

from .balance import (
    CaptureRegion, CenterOfPressure, FootShape, PressureCenter, capture_point, capture_region, cart_table_zmp,
    foot_polygon, lipm_omega, polygon_signed_distance, support_polygon, zmp_in_support,
)
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
from .walk_controller import (HUMANOID_FOOT, StabilizerCfg, WalkController, WalkIK, build_reference, walk_model,
                              walk_robot)
from .walk_sim import WalkResult, WalkSimCfg, WalkSimulation, acceptance_walk, plan_walk, walk_pattern
from .preview import (
    PreviewControlCfg, PreviewController, WalkPattern, WalkPatternCfg, WalkPatternGenerator, kajita2003_preview_cfg,
    preview_gains, walk_pattern_cfg,
)

__all__ = [
    "CaptureRegion", "CenterOfPressure", "FootShape", "PressureCenter", "capture_point", "capture_region",
    "cart_table_zmp", "foot_polygon", "lipm_omega", "polygon_signed_distance", "support_polygon", "zmp_in_support",
    "PreviewControlCfg", "PreviewController", "WalkPattern", "WalkPatternCfg", "WalkPatternGenerator",
    "kajita2003_preview_cfg", "preview_gains", "walk_pattern_cfg",
    "FootstepPlan",
    "FootstepPlanner",
    "FootstepPlannerCfg",
    "GridMap",
    "PlanStatus",
    "humanoid_footstep_cfg",
    "plan_footsteps",
    "plot_plan",
    "HUMANOID_FOOT", "StabilizerCfg", "WalkController", "WalkIK", "build_reference", "walk_model", "walk_robot",
    "WalkResult", "WalkSimCfg", "WalkSimulation", "acceptance_walk", "plan_walk", "walk_pattern",
]
