"""Legged locomotion of the bundled humanoid on the core: balance, walking patterns, and the
whole-body controller that walks a footstep plan in simulation.

- ``balance``: cart-table ZMP, support polygons and margins, capture point and region, and the
  centre of pressure measured from contact forces.
- ``preview``: Kajita's ZMP preview control and the walking pattern generator (CoM, ZMP, feet).
- ``walk_controller``: whole-body IK, inverse-dynamics feed-forward and the capture-point
  stabilizer; its joint targets go through the humanoid's ``core.Entity`` drives.
- ``walk_world``: the walk arena started on ``core.Simulation``, the humanoid's ``core.Entity``
  in its ``home`` keyframe.
- ``walk_sim``: a footstep plan walked there (the engine steps the physics), with the balance
  measured as it goes; ``walk_plot`` draws it.
- ``step_walker``: the same pattern and controller online in any simulation (``ZmpStepWalker``):
  a receding preview window over the queued footsteps, new plans taken at the next touchdown.

The footstep planner it walks is ``ambulo.nav``'s; the arena it walks in is
``ambulo.scenes.walk_arena``; the robot's facts are ``ambulo.robots.humanoid``'s.
"""

from .balance import (
    CaptureRegion,
    CenterOfPressure,
    FootShape,
    PressureCenter,
    capture_point,
    capture_region,
    cart_table_zmp,
    foot_polygon,
    lipm_omega,
    polygon_signed_distance,
    support_polygon,
    zmp_in_support,
)
from .preview import (
    PreviewControlCfg,
    PreviewController,
    WalkPattern,
    WalkPatternCfg,
    WalkPatternGenerator,
    kajita2003_preview_cfg,
    preview_gains,
    walk_pattern_cfg,
)
from .step_walker import StepWalkerCfg, WalkerBalance, ZmpStepWalker, step_walker_cfg
from .walk_controller import HUMANOID_FOOT, StabilizerCfg, WalkController, WalkIK, build_reference, walk_robot
from .walk_sim import WalkResult, WalkSimCfg, WalkSimulation, acceptance_walk, plan_walk, walk_pattern
from .walk_world import WalkWorld, start_walk_world

__all__ = [
    "CaptureRegion", "CenterOfPressure", "FootShape", "PressureCenter", "capture_point", "capture_region",
    "cart_table_zmp", "foot_polygon", "lipm_omega", "polygon_signed_distance", "support_polygon", "zmp_in_support",
    "PreviewControlCfg", "PreviewController", "WalkPattern", "WalkPatternCfg", "WalkPatternGenerator",
    "kajita2003_preview_cfg", "preview_gains", "walk_pattern_cfg",
    "HUMANOID_FOOT", "StabilizerCfg", "WalkController", "WalkIK", "build_reference", "walk_robot",
    "WalkResult", "WalkSimCfg", "WalkSimulation", "acceptance_walk", "plan_walk", "walk_pattern",
    "WalkWorld", "start_walk_world",
    "StepWalkerCfg", "WalkerBalance", "ZmpStepWalker", "step_walker_cfg",
]
