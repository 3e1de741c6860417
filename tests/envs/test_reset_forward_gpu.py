"""EnvCfg.reset_forward="kinematics" on a GPU: the step replayed as a CUDA graph equals the eager
step, sync-free, and both give the observations and rewards of reset_forward="full".

On a GPU the masked reset (and its forward) runs every step, inside the graph: the kinematics
pass and its ``acc_stale`` bookkeeping must be in-place kernels that a replay reruns. Four envs
of 64 worlds, one seed, the same actions: "full" eager, "kinematics" eager twice (the control:
how far two eager runs drift apart, if at all) and "kinematics" as a graph (3 eager warm-up
steps, then capture and replays under sync debug mode "error"). 0.5 s episodes, so every world
is reset inside replays. CUDA only; the CPU checks: tests/envs/test_reset_forward.py.
"""

from __future__ import annotations

import pytest
import torch

import ambulo.envs
from cuda_sync import graph_step

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

NUM_ENVS, STEPS, WARMUP, NUM_FEET = 64, 40, 3, 2


def make(mode: str, graph: bool):
    return ambulo.envs.make("humanoid-walk", num_envs=NUM_ENVS, device="cuda", seed=0, episode_length_s=0.5,
                            stats_interval_steps=8, cuda_graph=graph, cuda_graph_warmup_steps=WARMUP,
                            reset_forward=mode)


def outputs(step) -> dict[str, torch.Tensor]:
    obs, rewards, dones, extras = step
    return {"obs": obs.clone(), "rewards": rewards.clone(), "dones": dones.float(),
            "critic": extras["observations"]["critic"].clone()}


def max_diff(a: dict, b: dict, keys=None) -> float:
    return max(float((a[k] - b[k]).abs().max()) for k in (keys or a))


def test_kinematics_reset_forward_replays_as_a_graph_and_matches_full():
    full, eager, control, graphed = make("full", False), make("kinematics", False), make("kinematics", False), \
        make("kinematics", True)
    gen = torch.Generator(device="cuda").manual_seed(1)
    actions = [0.5 * torch.randn(NUM_ENVS, eager.num_actions, generator=gen, device="cuda") for _ in range(STEPS)]
    drift, graph_diff, mode_diff, resets = [], [], [], 0.0
    for i, a in enumerate(actions):
        f, e, c = outputs(full.step(a)), outputs(eager.step(a)), outputs(control.step(a))
        g = outputs(graph_step(graphed, a, i, WARMUP))
        torch.cuda.synchronize()
        drift.append(max_diff(e, c))
        graph_diff.append(max_diff(e, g))
        # the documented difference: feet_contact reads 0 on the worlds reset in this step
        reset = e["dones"].bool()
        assert not e["critic"][reset, -NUM_FEET:].any() and not g["critic"][reset, -NUM_FEET:].any(), i
        e["critic"], f["critic"] = e["critic"][:, :-NUM_FEET], f["critic"][:, :-NUM_FEET]
        mode_diff.append(max_diff(e, f))
        resets += float(e["dones"].sum()) if i > WARMUP else 0.0
    print(f"kinematics graph vs eager max |diff| per step: {max(graph_diff):.3g}; kinematics vs full: "
          f"{max(mode_diff):.3g} (eager vs eager: {max(drift):.3g}); {resets:.0f} resets inside replays")
    assert graphed._graph.replays == STEPS - WARMUP
    assert resets >= NUM_ENVS
    tol = 10 * max(drift) + 1e-5
    assert max(graph_diff) <= tol, [f"{d:.3g}" for d in graph_diff]
    assert max(mode_diff) <= tol, [f"{d:.3g}" for d in mode_diff]

