"""humanoid-walk-robust: humanoid-walk trained under the transfer randomization, judged at its corners.

Issue 30's bar for transfer: "the flat-ground policy still meets ``walks`` with gains +-20 %,
0-20 ms latency and CoM +-3 cm". The task trains under ``transfer_cfg_wide`` (those three and
motor strength, joint friction, armature, observation delay, drawn per world) and its criterion
``walks_robust`` is ``walks`` (``WALKS``' bars) holding in each of 17 blocks of the evaluation:
nominal and the 16 corners of the three terms (``envs.transfer.transfer_corners``, the
robustness table's corner rows). Judged on the nominal env alone, session 13's first walking
checkpoint (3.4 min on an H200) stopped ``--stop-at-criterion`` and then missed 6 of the 16
corners (gains x0.8, by 0.004-0.046 m/s): the bar judged must be the one the issue states.

Episodes: 20 a block, 340 in all (``ambulo eval``'s and ``--eval-every``'s default; another
count must be a multiple of 17). 20, because ``fall_rate <= 0.05`` then allows one fall in a
block (with 10 a single fall fails it) and a block's mean velocity error over 20 episodes has
about 1/sqrt(2) the sampling error of 10's; and it is affordable where it costs: the CPU-engine
confirmation of a GPU success runs 340 worlds x 1,000 steps, 3.2x humanoid-walk's 100 (measured
on the 2-core development VM, shared, with the shipped walker: 53 ms a policy step against
16.7 ms, 53 s against 17 s an evaluation; a 16-core GPU host runs it in a fraction of that), and
it runs only when the GPU evaluation has met the criterion. On the GPU the width costs little
(1,000 launch-bound steps whatever the worlds), though the latency blocks step one physics step
at a time and keep the evaluation env off CUDA graphs.
"""

from __future__ import annotations

from .humanoid_walk import (
    WALKS,
    HumanoidWalkCfg,
    HumanoidWalkEnv,
    humanoid_walk_cfg,
    humanoid_walk_metrics,
    humanoid_walk_play_cfg,
    humanoid_walk_ppo,
)
from .registry import Criterion, EvalBlocks, TaskSpec, register
from .transfer import TransferCfg, transfer_cfg_wide, transfer_corners

WALKS_ROBUST = Criterion("walks_robust", max_values=dict(WALKS.max_values))
"""``walks`` in every block of the evaluation (nominal and the 16 corners): ``WALKS``' bars,
judged block by block (``rl.eval_blocks``)."""

EPISODES_PER_BLOCK = 20
"""The default evaluation's episodes per block (the module docstring says why 20)."""


def humanoid_walk_robust_cfg() -> HumanoidWalkCfg:
    """humanoid-walk trained under the issue's transfer ranges (``transfer_cfg_wide``: gains
    +-20 %, strength +-10 %, joint friction, armature, CoM +-3 cm, 0-20 ms latency, 0-1 step of
    observation delay). Its own task name, so its runs, its shipped policy and ``ambulo eval``
    never mix with humanoid-walk's; the play variant is humanoid-walk's (nominal), and the
    evaluation lays it out in blocks (``humanoid_walk_robust_eval_blocks``)."""
    cfg = humanoid_walk_cfg()
    cfg.transfer = transfer_cfg_wide()
    return cfg


def humanoid_walk_robust_eval_blocks() -> EvalBlocks:
    """Nominal and the 16 corners of gains, latency and CoM, as the play env's ``transfer_blocks``."""
    corners = transfer_corners()
    return EvalBlocks(names=("nominal", *corners),
                      env_overrides={"transfer_blocks": (TransferCfg(), *corners.values())},
                      episodes_per_block=EPISODES_PER_BLOCK)


register(TaskSpec(
    name="humanoid-walk-robust",
    env_cls=HumanoidWalkEnv,
    cfg_fn=humanoid_walk_robust_cfg,
    play_cfg_fn=humanoid_walk_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="humanoid-walk trained under the transfer randomization (gains, strength, friction, armature, "
                "CoM, latency, observation delay); judged nominal and at the 16 gains/latency/CoM corners",
    step_metrics=humanoid_walk_metrics,
    criteria=(WALKS_ROBUST,),
    eval_blocks_fn=humanoid_walk_robust_eval_blocks,
))
