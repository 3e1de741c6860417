"""PpoCfg: a task's PPO settings (part of its ``TaskSpec``) and their rsl-rl-lib translation.

Pure data: importing it needs neither rsl-rl nor the ``rl`` extra, so task modules declare
their PPO settings next to their env config."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from ..utils.validate import Checked, rule


@dataclass(kw_only=True)
class PpoCfg(Checked):
    """PPO with an MLP actor-critic (rsl-rl-lib's ``OnPolicyRunner``)."""

    num_envs: int = field(default=4096, metadata=rule(minimum=1))
    """Default number of parallel envs for training this task."""
    max_iterations: int = field(default=1500, metadata=rule(minimum=1))
    num_steps_per_env: int = field(default=24, metadata=rule(minimum=1))
    """Rollout length per env per iteration: batch = num_envs * num_steps_per_env."""
    save_interval: int = field(default=50, metadata=rule(minimum=1))
    """Checkpoint every this many iterations (and at the end)."""
    actor_hidden_dims: tuple[int, ...] = (256, 128, 128)
    critic_hidden_dims: tuple[int, ...] = (256, 128, 128)
    activation: Literal["elu", "selu", "relu", "crelu", "lrelu", "tanh", "sigmoid", "softplus", "gelu", "swish",
                        "mish", "identity"] = "elu"
    """Hidden-layer activation (the names rsl-rl-lib resolves)."""
    init_noise_std: float = field(default=1.0, metadata=rule(minimum=0.0, strict=True))
    obs_normalization: bool = True
    """Running mean/std normalization of observations (exported with the policy)."""
    learning_rate: float = field(default=1.0e-3, metadata=rule(minimum=0.0, strict=True))
    schedule: Literal["adaptive", "fixed"] = "adaptive"
    """``adaptive`` scales the learning rate to keep the KL near ``desired_kl``."""
    desired_kl: float = field(default=0.01, metadata=rule(minimum=0.0, strict=True))
    num_learning_epochs: int = field(default=5, metadata=rule(minimum=1))
    num_mini_batches: int = field(default=4, metadata=rule(minimum=1))
    clip_param: float = field(default=0.2, metadata=rule(minimum=0.0, strict=True))
    gamma: float = field(default=0.99, metadata=rule(minimum=0.0, maximum=1.0))
    lam: float = field(default=0.95, metadata=rule(minimum=0.0, maximum=1.0))
    """GAE lambda."""
    value_loss_coef: float = field(default=1.0, metadata=rule(minimum=0.0))
    entropy_coef: float = field(default=0.01, metadata=rule(minimum=0.0))
    max_grad_norm: float = field(default=1.0, metadata=rule(minimum=0.0, strict=True))
    init_at_random_ep_len: bool = True
    """Start envs at random points of their first episode so resets spread out in time."""
    symmetry: bool = False
    """Train on every mini-batch and its left-right mirror image too (rsl-rl's ``Symmetry`` data
    augmentation, ``envs.symmetry``): the batch doubles, and the policy learns each gait for both
    legs. Walking tasks only (a task whose observations have no mirror rule is refused)."""

    def to_rsl_rl(self, has_critic_obs: bool) -> dict[str, Any]:
        """The ``train_cfg`` dict of ``rsl_rl.runners.OnPolicyRunner`` (rsl-rl-lib 5.x)."""

        def model(hidden: tuple[int, ...], stochastic: bool) -> dict[str, Any]:
            cfg: dict[str, Any] = {
                "class_name": "MLPModel",
                "hidden_dims": list(hidden),
                "activation": self.activation,
                "obs_normalization": self.obs_normalization,
            }
            if stochastic:
                cfg["distribution_cfg"] = {"class_name": "GaussianDistribution",
                                           "init_std": self.init_noise_std}
            return cfg

        return {
            "num_steps_per_env": self.num_steps_per_env,
            "save_interval": self.save_interval,
            "obs_groups": {
                "actor": ["policy"],
                # the critic group holds the clean policy terms plus privileged ones: observation
                # noise is for the actor only
                "critic": ["critic"] if has_critic_obs else ["policy"],
            },
            "actor": model(self.actor_hidden_dims, stochastic=True),
            "critic": model(self.critic_hidden_dims, stochastic=False),
            "algorithm": {
                "class_name": "PPO",
                "learning_rate": self.learning_rate,
                "schedule": self.schedule,
                "desired_kl": self.desired_kl,
                "num_learning_epochs": self.num_learning_epochs,
                "num_mini_batches": self.num_mini_batches,
                "clip_param": self.clip_param,
                "gamma": self.gamma,
                "lam": self.lam,
                "value_loss_coef": self.value_loss_coef,
                "entropy_coef": self.entropy_coef,
                "max_grad_norm": self.max_grad_norm,
                "use_clipped_value_loss": True,
            },
            "logger": "tensorboard",
            "check_for_nan": True,
        }


__all__ = ["PpoCfg"]
