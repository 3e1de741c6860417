"""humanoid-walk's step replayed as one CUDA graph (EnvCfg.cuda_graph) gives the eager step's results.

Three envs of 64 worlds, one seed, the same actions: two eager (the control: how far two eager
runs of MuJoCo Warp drift apart, if at all) and one in graph mode (3 eager warm-up steps, then
capture and 47 replays). 0.5 s episodes, so every world times out and is reset inside replays:
the reset draws (yaw, joint noise, commands, pushes) come from the env's generator, whose state
the graph must advance on every replay (``register_generator_state``); a graph that replayed
the draws of the capture, read a stale tensor or skipped the physics would part from the eager
env at once. The replays run under ``torch.cuda.set_sync_debug_mode("error")``: a host sync
inside the graph mode's step (copy in, replay, copies out, statistics window) raises.
CUDA only (skipped elsewhere); the CPU side of the split step: tests/envs/test_graph_step.py.
"""

from __future__ import annotations

import pytest
import torch

import ambulo.envs
from cuda_sync import graph_step

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

NUM_ENVS, STEPS, WARMUP = 64, 50, 3


def make(graph: bool):
    return ambulo.envs.make("humanoid-walk", num_envs=NUM_ENVS, device="cuda", seed=0, episode_length_s=0.5,
                            stats_interval_steps=8, cuda_graph=graph, cuda_graph_warmup_steps=WARMUP)


def outputs(step) -> dict[str, torch.Tensor]:
    obs, rewards, dones, extras = step
    out = {"obs": obs, "rewards": rewards, "dones": dones.float(), "time_outs": extras["time_outs"].float(),
           "critic": extras["observations"]["critic"]}
    out.update({f"episode/{k}": v.reshape(1) for k, v in extras.get("episode", {}).items()})
    return out


def max_diff(a: dict, b: dict) -> float:
    assert a.keys() == b.keys()  # the same statistics windows published
    return max(float((a[k] - b[k]).abs().max()) for k in a)


def test_graph_replay_equals_eager_steps():
    eager, control, graphed = make(False), make(False), make(True)
    gen = torch.Generator(device="cuda").manual_seed(1)
    actions = [0.5 * torch.randn(NUM_ENVS, eager.num_actions, generator=gen, device="cuda") for _ in range(STEPS)]
    drift, diff, resets = [], [], 0.0
    for i, a in enumerate(actions):
        e, c = outputs(eager.step(a)), outputs(control.step(a))
        g = outputs(graph_step(graphed, a, i, WARMUP))
        torch.cuda.synchronize()
        drift.append(max_diff(e, c))
        diff.append(max_diff(e, g))
        resets += float(e["dones"].sum()) if i > WARMUP else 0.0
    print(f"graph vs eager max |diff| per step: {max(diff):.3g} (eager vs eager: {max(drift):.3g}); "
          f"{resets:.0f} resets inside replays")
    assert graphed._graph.replays == STEPS - WARMUP
    assert resets >= NUM_ENVS  # every world reset at least once inside the replays
    if max(drift) == 0.0:  # MuJoCo Warp deterministic here: the graph must be bit-identical too
        assert max(diff) == 0.0, [f"{d:.3g}" for d in diff]
    else:  # nondeterministic kernels: the graph may drift no more than two eager runs do
        assert max(diff) <= 10 * max(drift) + 1e-5, ([f"{d:.3g}" for d in diff], [f"{d:.3g}" for d in drift])
    # the returned tensors are the caller's: the next replay does not overwrite them
    kept = outputs(graphed.step(actions[-1]))["obs"]
    before = kept.clone()
    graphed.step(actions[-1])
    assert torch.equal(kept, before)


def test_an_evaluation_replayed_as_a_graph_measures_what_the_eager_one_does():
    # ``ambulo eval`` and ``--eval-every`` run their env through ``use_cuda_graph``: the shipped
    # policy's metrics must not move beyond two eager runs' spread, and a second evaluation of the
    # same env (the generator restarted, as the periodic evaluation does) must repeat the first
    from ambulo.policies.shipped import load_policy
    from ambulo.rl.evaluate import run_episodes
    from ambulo.rl.vecenv import RslRlVecEnv

    shipped = load_policy("humanoid-walk")
    spec = ambulo.envs.spec("humanoid-walk")

    def policy(obs):
        return shipped(obs["policy"])

    def evaluation(env):
        return run_episodes(env, RslRlVecEnv(env), policy, spec)

    def make_eval():
        return ambulo.envs.make("humanoid-walk", num_envs=NUM_ENVS, device="cuda", seed=5, play=True,
                                episode_length_s=3.0)

    eager, graphed = make_eval(), make_eval()
    assert graphed.use_cuda_graph() and graphed._graph is not None
    fresh = graphed.generator.get_state()
    a, b = evaluation(eager), evaluation(graphed)
    graphed.generator.set_state(fresh)
    c = evaluation(graphed)
    assert graphed._graph.captures == 1 and graphed._graph.replays == 2 * graphed.max_episode_length - WARMUP
    keys = ("fall_rate", "mean_abs_vel_error_m_s", "mean_abs_yaw_rate_error_rad_s", "mean_return")
    print({k: (a[k], b[k], c[k]) for k in keys})
    for k in keys:
        assert abs(a[k] - b[k]) <= 1e-3 * max(1.0, abs(a[k])), (k, a[k], b[k])
        assert abs(b[k] - c[k]) <= 1e-3 * max(1.0, abs(b[k])), (k, b[k], c[k])
