"""A run's training overrides reach its play/eval env only where the play variant does not set the
setting itself: transfer randomization and the training ranges stay off in evaluation; the robust
variant (humanoid-walk-robust) trains under the wide transfer ranges and evaluates nominal, with the
transfer corners added as blocks of the evaluation."""

import ambulo.envs as envs
from ambulo.envs.transfer import transfer_cfg_wide
from ambulo.rl.runs import play_overrides


def test_training_only_overrides_stay_out_of_the_play_env():
    trained = {"transfer.com_offset_m": 0.05, "transfer.kp_scale_range": (0.8, 1.2), "friction_range": (0.2, 1.0),
               "curriculum_start_scale": 0.2, "observation_noise.joint_vel": 0.1,
               "action_scale": 0.3, "physics.solver_iterations": 20, "reward_weights.upright": 1.0}
    kept = play_overrides("humanoid-walk", trained)
    assert kept == {"action_scale": 0.3, "physics.solver_iterations": 20, "reward_weights.upright": 1.0}
    cfg = envs.make_cfg("humanoid-walk", play=True, **kept)
    assert cfg.transfer == envs.make_cfg("humanoid-walk", play=True).transfer and cfg.action_scale == 0.3


def test_a_leaf_the_play_variant_leaves_alone_carries_over():
    # humanoid-rough's play variant sets curriculum levels, not the terrain's spacing
    kept = play_overrides("humanoid-rough", {"terrain.spacing_m": 0.1, "curriculum.init_level": 0})
    assert kept == {"terrain.spacing_m": 0.1}


def test_training_kind_weights_do_not_change_what_the_evaluation_pools():
    # equal to the play variant's (None) and still dropped: the whole curriculum is training's own
    for task in ("humanoid-rough", "g1-rough"):
        kept = play_overrides(task, {"curriculum.kind_weights": (1.0,) * 6 + (2.0,), "action_scale": 0.3})
        assert kept == {"action_scale": 0.3}
        assert envs.make_cfg(task, play=True, **kept).curriculum.kind_weights is None
    # humanoid-footsteps-stairs' fixed levels likewise: its placement errors pool every column equally
    kept = play_overrides("humanoid-footsteps-stairs", {"levels.kind_weights": (1.0, 2.0, 1.0), "action_scale": 0.3})
    assert kept == {"action_scale": 0.3}
    assert envs.make_cfg("humanoid-footsteps-stairs", play=True, **kept).levels.kind_weights is None


def test_the_robust_variant_trains_under_the_wide_ranges_and_evaluates_nominal():
    walk, robust = envs.spec("humanoid-walk"), envs.spec("humanoid-walk-robust")
    assert robust.cfg_fn().transfer == transfer_cfg_wide()
    assert robust.play_cfg() == walk.play_cfg()  # `walks` means what it means for humanoid-walk
    # ... judged in every block of its evaluation (nominal + the transfer corners: tests/rl/test_eval_blocks.py)
    (walks,), (walks_robust,) = walk.criteria, robust.criteria
    assert walks_robust.max_values == walks.max_values and walks_robust.min_values == walks.min_values
    assert walk.eval_blocks() is None and robust.eval_blocks() is not None
    assert robust.ppo_cfg_fn() == walk.ppo_cfg_fn()
    trained, wide = robust.cfg_fn(), transfer_cfg_wide()
    walk_cfg = walk.cfg_fn()
    walk_cfg.transfer = wide
    assert trained == walk_cfg  # nothing else differs from humanoid-walk
