"""The step split for CUDA graphs (envs.graph_step), checked on the CPU engine.

A CUDA graph replays the kernels of one captured step: Python state is not rerun and a tensor
that the step rebinds instead of writing in place is read stale on replay. These tests hold
the CPU outcomes of the split step to the eager step's from before the split (bit-identical),
and the step's persistent tensors to in-place writes. The replay itself needs CUDA:
tests/envs/test_graph_step_gpu.py.
"""

from __future__ import annotations

import contextlib
import hashlib

import torch

import ambulo.envs

# sha256 over 50 steps of humanoid-walk (8 envs, seed 3, 0.3 s episodes, statistics every 5 steps,
# actions 2 * randn from a CPU generator seeded 0) of obs, rewards, dones, critic obs, time-outs and
# the published episode statistics, from the step before the split (main at 8f3a5de, MuJoCo 3.x CPU
# engine on this machine). A MuJoCo or torch upgrade that changes float results changes it: re-derive
# it from the eager step of that version, never from the code under test alone. The CPU under it matters too:
# the same code (bb6b2a0) and pinned MuJoCo 4.0.0 / torch 2.13.0 gave the first digest on the VMs of sessions 9-16
# and the second on session 17's AMD EPYC (AVX-512) VM, where every other test passed. A code change gives a
# third digest on both.
EAGER_50_STEPS_SHA256 = {"c6486737975da6999eede73074503f15c46b2678b5196f743c2cff5baa30b843",
                         "5a65aa575554e636948dd598dd49149446b7bdec3c4e007e115ea3a1b7d0a9b4"}

# Tensors the step rebinds each step: each is written before anything in the step reads it (the
# outputs and the terms computed once per step), so a replay that writes the captured tensors
# is right. Any other rebinding of persistent state freezes it under a CUDA graph.
WRITTEN_BEFORE_READ = {("env", "obs_buf"), ("env", "_critic_buf"), ("env", "_fell"), ("env", "_gravity_b"),
                       ("env", "_targets")}


def make_env(**overrides):
    # the hash holds the "full" reset pass (humanoid-walk's default is "kinematics" since session 12;
    # tests/envs/test_reset_forward.py holds that one equal to "full" where the policy looks)
    overrides.setdefault("reset_forward", "full")
    return ambulo.envs.make("humanoid-walk", num_envs=8, device="cpu", seed=3, episode_length_s=0.3,
                            stats_interval_steps=5, **overrides)


def trace(env) -> tuple[str, int]:
    gen = torch.Generator().manual_seed(0)
    digest, windows = hashlib.sha256(), 0
    for _ in range(50):
        actions = torch.randn(env.num_envs, env.num_actions, generator=gen) * 2.0
        obs, rewards, dones, extras = env.step(actions)
        for t in (obs, rewards, dones, extras["observations"]["critic"], extras["time_outs"]):
            digest.update(t.contiguous().numpy().tobytes())
        windows += "episode" in extras
        for key, value in sorted(extras.get("episode", {}).items()):
            digest.update(key.encode())
            digest.update(value.numpy().tobytes())
    return digest.hexdigest(), windows


def test_split_step_is_bit_identical_to_the_eager_step_on_the_cpu():
    # cuda_graph is ignored on the CPU: the flag must not change the CPU path either
    env = make_env(cuda_graph=True)
    assert env._graph is None
    digest, windows = trace(env)
    assert windows == 3  # resets and statistics windows were exercised, not only plain steps
    assert digest in EAGER_50_STEPS_SHA256


def _tensors(env) -> dict[tuple[str, str], torch.Tensor]:
    owners = {"env": env, "feet": env.feet, "commands": env.commands, "stats": env._stats,
              "transfer": env.transfer, "robot": env.robot}
    return {(name, key): value for name, obj in owners.items() for key, value in vars(obj).items()
            if isinstance(value, torch.Tensor)}


def test_step_keeps_its_state_in_place():
    env = make_env()
    zeros = torch.zeros(env.num_envs, env.num_actions)
    for _ in range(16):  # past the lazily made buffers (statistics sums at the first time-out, noise scale)
        env.step(zeros)
    before = _tensors(env)
    sums = env._stats.sums
    for _ in range(15):  # every env timed out (0.3 s = 15 steps): resets, sums added, windows published
        env.step(zeros)
    after = _tensors(env)
    rebound = {key for key, value in after.items() if before.get(key) is not value}
    assert rebound == WRITTEN_BEFORE_READ
    assert env._stats.sums is sums


def test_contact_timers_advance_in_place():
    env = make_env()
    timers = [env.feet._air, env.feet._last_air, env.feet._contact_time, env.feet._first]
    zeros = torch.zeros(env.num_envs, env.num_actions)
    air = []
    for _ in range(10):
        env.step(zeros)
        air.append(env.feet.data.current_air_time_s.clone())
    assert all(a is b for a, b in zip(timers, [env.feet._air, env.feet._last_air, env.feet._contact_time,
                                              env.feet._first]))
    # the timers still count: a foot in the air gains one policy step per step
    grew = (air[-1] - air[-2])[air[-1] > 0]
    assert torch.allclose(grew, torch.full_like(grew, env.step_dt_s)) or grew.numel() == 0


def test_tasks_with_python_cursors_refuse_graph_mode():
    env = ambulo.envs.make("humanoid-walk-robust", num_envs=4, device="cpu", seed=0)
    assert "DelayBuffer" in env._graph_unsafe_reason()
    assert make_env()._graph_unsafe_reason() is None


class _RunOnReplay:
    """Stands in for a CUDA graph on the CPU: the capture runs the step once (as capture plus
    first replay would), each later replay runs it again and writes the results into the
    capture's output tensors, as a real replay writes the graph's static outputs."""

    def __init__(self, fn):
        self.fn, self.out, self.first = fn, fn(), True

    def replay(self):
        if self.first:
            self.first = False
            return
        new = self.fn()
        for name in ("obs", "rewards", "dones", "time_outs", "terminated", "final_obs", "critic_obs"):
            if getattr(self.out, name) is not None:
                getattr(self.out, name).copy_(getattr(new, name))
        for key, value in self.out.terminations.items():
            value.copy_(new.terminations[key])


def test_graph_step_plumbing_matches_the_eager_step(monkeypatch):
    # GraphStep's own work (warm-up count, the static input, copies of the outputs, the env's
    # observation buffers, recapture) on MuJoCo Warp's CPU device with the graph faked
    import pytest

    pytest.importorskip("mujoco_warp")
    from ambulo.envs.graph_step import GraphStep

    def capture(self, fn):
        graph = _RunOnReplay(fn)
        return graph, None, graph.out

    monkeypatch.setattr(GraphStep, "_side_stream", lambda self: contextlib.nullcontext())
    monkeypatch.setattr(GraphStep, "_capture_graph", capture)
    kwargs = dict(num_envs=4, device="cpu", engine="warp", seed=1, episode_length_s=0.1, stats_interval_steps=3)
    eager, graphed = ambulo.envs.make("humanoid-walk", **kwargs), ambulo.envs.make("humanoid-walk", **kwargs)
    graphed._graph = GraphStep(graphed)
    gen = torch.Generator().manual_seed(0)
    kept = []
    for i in range(12):  # 5-step episodes: resets after the capture at step 3
        if i == 8:  # what the step computes changes: the graph is captured again
            eager.return_final_obs = graphed.return_final_obs = True
        actions = torch.randn(4, eager.num_actions, generator=gen)
        a, b = eager.step(actions), graphed.step(actions)
        for x, y in zip(a[:3], b[:3]):
            assert torch.equal(x, y)
        assert a[3].keys() == b[3].keys()
        assert torch.equal(a[3]["observations"]["critic"], b[3]["observations"]["critic"])
        for key, value in a[3].get("episode", {}).items():
            assert torch.equal(value, b[3]["episode"][key]), key
        assert graphed.get_observations() is b[0]
        kept.append((b[0], b[0].clone()))
    assert all(torch.equal(obs, copy) for obs, copy in kept)  # no step's outputs overwritten later
    assert graphed._graph.captures == 2 and graphed._graph.replays == 12 - 3
    # an evaluation's full reset between replays (the graph is kept): the replays still match
    gen_e, gen_g = eager.generator.get_state(), graphed.generator.get_state()
    assert torch.equal(gen_e, gen_g)
    assert torch.equal(eager.reset(), graphed.reset())
    for _ in range(6):
        actions = torch.randn(4, eager.num_actions, generator=gen)
        a, b = eager.step(actions), graphed.step(actions)
        for x, y in zip(a[:3], b[:3]):
            assert torch.equal(x, y)
    assert graphed._graph.captures == 2 and graphed._graph.replays == 12 - 3 + 6


def test_a_full_reset_keeps_the_state_a_graph_reads_in_place():
    # evaluations (``run_episodes``) reset every env before each evaluation, between replays of a
    # graph captured at the first one: a reset that rebinds a tensor the graph reads freezes it
    env = make_env()
    zeros = torch.zeros(env.num_envs, env.num_actions)
    for _ in range(16):
        env.step(zeros)
    before = _tensors(env)
    env.reset()
    env.step(zeros)
    rebound = {key for key, value in _tensors(env).items() if before.get(key) is not value}
    assert rebound <= WRITTEN_BEFORE_READ


def test_use_cuda_graph_is_a_no_op_off_cuda_and_refused_tasks_stay_eager():
    env = make_env()
    assert env.use_cuda_graph() is False and env._graph is None
    robust = ambulo.envs.make("humanoid-walk-robust", num_envs=4, device="cpu", seed=0)
    assert robust.use_cuda_graph() is False


def test_graph_mode_is_only_for_audited_task_classes():
    # a subclass's step is other code: humanoid-footsteps (a HumanoidWalkEnv) rebinds its touchdown
    # timers each step, which a replay would freeze, so it stays eager until audited itself
    footsteps = ambulo.envs.make("humanoid-footsteps", num_envs=4, device="cpu", seed=0)
    assert "not audited" in footsteps._graph_unsafe_reason()
    assert "not audited" in ambulo.envs.make("jetbot-goal", num_envs=4, device="cpu", seed=0)._graph_unsafe_reason()
    assert make_env()._graph_unsafe_reason() is None
