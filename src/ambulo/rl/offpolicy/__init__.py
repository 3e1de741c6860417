"""Massively parallel off-policy actor-critics: ``ambulo train TASK --algo fast-sac | fast-td3``.

FastTD3's and FastSAC's recipe written for ambulo's vectorized envs: a replay ring of every
world's steps on the device (``replay``), a twin categorical critic (``categorical``,
``networks``), n-step returns, observation normalization, several large-batch updates per env
step (``learner``), run by ``runner.OffPolicyRunner`` behind the same run folders, checkpoints,
evaluation and export as PPO (``ambulo.rl.train_offpolicy`` sets a run up).
"""

from .config import ALGOS, OffPolicyCfg, offpolicy_cfg
from .runner import OffPolicyRunner, load_runner

__all__ = ["ALGOS", "OffPolicyCfg", "OffPolicyRunner", "load_runner", "offpolicy_cfg"]
