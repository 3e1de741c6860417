"""Training, playing, exporting and evaluating policies for ``ambulo.envs`` tasks.

PPO comes from rsl-rl-lib (the ``rl`` extra). ``train`` writes a run folder
(``runs/<task>/<time>/``) that ``play``, ``export`` and ``evaluate`` take back.
"""

from .checkpoints import CheckpointError, RunError
from .config import PpoCfg, ppo_cfg
from .evaluate import evaluate
from .export import export
from .interrupt import TrainingInterrupted
from .play import play
from .train import train

__all__ = ["CheckpointError", "PpoCfg", "RunError", "TrainingInterrupted", "evaluate", "export",
           "play", "ppo_cfg", "train"]
