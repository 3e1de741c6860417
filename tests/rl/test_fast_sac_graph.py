"""FastSAC/FastTD3 updates as replayed CUDA graphs (``OffPolicyCfg.cuda_graph``).

On the CPU: the option is ignored (eager updates, ``update_from`` is ``update`` of a sample), a
checkpoint's ``capturable`` flag does not leak into the loading run, ``FinalCriticObs`` hands
out the captured buffer when the env step is a replayed graph, and ``UpdateGraphs``' warm-ups,
captures and replays follow their rules (torch.cuda's graph API faked). On CUDA (skipped here):

- graph updates give the parameters of eager updates from the same state and generators, to
  float rounding, not bitwise: both run the same kernels, but ``categorical.project`` adds with
  ``scatter_add_``, whose CUDA atomics add in no fixed order (two eager runs differ in the last
  bits too); the generators' states, which the graph must advance as eager draws do, are
  compared bitwise;
- a sample captured in a graph draws, after the ring has grown and wrapped, the batch an eager
  sample draws from the same generator state, bit for bit (no host ``size``/``ptr`` baked in);
- a training iteration (humanoid-walk, env step and updates both graphs) runs under torch's
  sync debug mode "error", and a resumed run captures again.
"""

from __future__ import annotations

import contextlib
import types

import pytest
import torch

from ambulo.rl.offpolicy import offpolicy_cfg
from ambulo.rl.offpolicy.config import OffPolicyCfg
from ambulo.rl.offpolicy.learner import FastOffPolicy
from ambulo.rl.offpolicy.replay import ReplayRing
from ambulo.rl.offpolicy.runner import FinalCriticObs

cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

OBS, ACTIONS, WORLDS = 12, 4, 64


def _cfg(**overrides) -> OffPolicyCfg:
    small = dict(actor_hidden_dims=(64, 64), critic_hidden_dims=(64, 64), num_atoms=51, batch_size=512,
                 n_step=3, learning_starts=3, buffer_steps_per_env=16, policy_delay=2, actor_lr=1.0e-3,
                 critic_lr=1.0e-3, init_alpha=0.05)
    return OffPolicyCfg(**{**small, **overrides})


def _ring(device: str, steps: int = 10, seed: int = 0) -> ReplayRing:
    """A ring of random steps (rewards ~N(0, 1), 5 % of steps end, half of those terminate)."""
    g = torch.Generator().manual_seed(seed)
    ring = ReplayRing(WORLDS, 16, OBS, 0, ACTIONS, device)
    for _ in range(steps):
        obs, next_obs = torch.randn(WORLDS, OBS, generator=g), torch.randn(WORLDS, OBS, generator=g)
        actions = torch.rand(WORLDS, ACTIONS, generator=g) * 2 - 1
        ended = torch.rand(WORLDS, generator=g) < 0.05
        terminated = ended & (torch.rand(WORLDS, generator=g) < 0.5)
        ring.add(*(t.to(device) if t is not None else None for t in (
            obs, None, actions, torch.randn(WORLDS, generator=g), next_obs, None, terminated, ended)))
    return ring


def _learner(cfg: OffPolicyCfg, device: str, ring: ReplayRing) -> FastOffPolicy:
    torch.manual_seed(0)  # the same initial weights for every learner
    learner = FastOffPolicy(cfg, OBS, OBS, ACTIONS, device)
    for norm in (learner.actor.normalizer, learner.critic.normalizer):
        norm.update(ring.obs.reshape(-1, OBS) * 2.0 + 1.0)  # a normalizer that is not the identity
    return learner


def _weights(learner: FastOffPolicy) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in learner.state_dict().items()}


# -- CPU ------------------------------------------------------------------------------------------
def test_cuda_graph_is_ignored_on_the_cpu_and_update_from_is_update_of_a_sample():
    ring = _ring("cpu")
    graphed, plain = _learner(_cfg(cuda_graph=True), "cpu", ring), _learner(_cfg(), "cpu", ring)
    assert not graphed.graphed and graphed.graphs is None
    assert not any(g["capturable"] for opt in (graphed.actor_opt, graphed.critic_opt, graphed.alpha_opt)
                   for g in opt.param_groups)
    gen_a, gen_b = torch.Generator().manual_seed(3), torch.Generator().manual_seed(3)
    cfg = plain.cfg
    for _ in range(3):
        torch.manual_seed(1)  # the actor's sampling noise
        graphed.update_from(ring, gen_a)
        torch.manual_seed(1)
        plain.update(ring.sample(cfg.batch_size, cfg.n_step, cfg.gamma, gen_b))
    a, b = _weights(graphed), _weights(plain)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert graphed.num_updates == plain.num_updates == 3 and graphed.graphs is None


def test_loading_a_checkpoint_keeps_this_runs_capturable_flag():
    """A graph run's checkpoint has ``capturable=True`` groups; loaded by an eager CPU run they
    must not stay so (CPU optimizers refuse capturable steps), and the reverse on CUDA."""
    ring = _ring("cpu")
    saver, loader = _learner(_cfg(), "cpu", ring), _learner(_cfg(), "cpu", ring)
    saver.update_from(ring, torch.Generator().manual_seed(0))
    saved = saver.state()
    for name in ("actor_opt", "critic_opt", "alpha_opt"):
        for group in saved[name]["param_groups"]:
            group["capturable"] = True  # as a cuda_graph run saves them
    loader.load_state(saved)
    assert not any(g["capturable"] for opt in (loader.actor_opt, loader.critic_opt, loader.alpha_opt)
                   for g in opt.param_groups)
    loader.update_from(ring, torch.Generator().manual_seed(0))  # a capturable CPU step would raise


def test_final_critic_obs_of_a_replayed_env_graph_is_the_captured_buffer():
    """A graph step runs no Python: ``FinalCriticObs`` must return the buffer the capture's first
    observation call made (which each replay rewrites), not None or an eager step's buffer."""
    env = types.SimpleNamespace(_critic_buf=None)
    made = []

    def compute():
        env._critic_buf = torch.full((2, 3), float(len(made)))
        made.append(env._critic_buf)
        return env._critic_buf

    env._compute_observations = compute
    final = FinalCriticObs(env)

    def eager_step():  # the env's Python step: final observations, then those after resets
        env._compute_observations()
        env._compute_observations()
        return "stepped"

    assert final.step(eager_step) == ("stepped", made[0])
    assert final.step(eager_step)[1] is made[2]  # the capture: the first call's buffer is kept

    def replay():  # the graph rewrites the captured buffer in place, calls nothing
        made[2].fill_(7.0)
        return "replayed"

    result, before_reset = final.step(replay)
    assert result == "replayed" and before_reset is made[2] and float(before_reset[0, 0]) == 7.0


class _FakeCuda:
    """Stand-ins for torch.cuda's stream and graph API on the CPU: a capture records the function
    (running nothing, as a real capture runs nothing) and a replay runs it."""

    class CUDAGraph:
        def __init__(self):
            self.fn, self.generators = None, []

        def register_generator_state(self, generator):
            self.generators.append(generator)

        def replay(self):
            self.fn()

    def __init__(self, fail: bool = False):
        self.fail, self.capturing, self.graphs = fail, None, []

    def graph(self, graph, stream=None, capture_error_mode="global"):
        fake = self

        class Capture:
            def __enter__(self):
                fake.capturing = graph
                fake.graphs.append(graph)

            def __exit__(self, *exc):
                fake.capturing = None

        return Capture()

    def stream(self, stream):
        return contextlib.nullcontext()


def test_update_graphs_warm_up_each_kind_then_capture_once_and_replay(monkeypatch):
    from ambulo.rl.offpolicy import graphs as graphs_module

    fake = _FakeCuda()
    for name in ("CUDAGraph", "graph", "stream"):
        monkeypatch.setattr(graphs_module.torch.cuda, name, getattr(fake, name))
    monkeypatch.setattr(graphs_module.torch.cuda, "Stream", lambda device: types.SimpleNamespace(
        wait_stream=lambda other: None))
    monkeypatch.setattr(graphs_module.torch.cuda, "current_stream", lambda device: types.SimpleNamespace(
        wait_stream=lambda other: None))
    generator = torch.Generator()
    graphs = graphs_module.UpdateGraphs(torch.device("cuda"), warmup=3, generators=(generator,))
    ran = []

    def update(kind):
        def fn():
            if fake.capturing is not None:
                fake.capturing.fn = fn  # captured, not run
            else:
                ran.append(kind)
        return fn

    kinds = ["actor", "critic"] * 6
    for kind in kinds:
        graphs(kind, update(kind))
    assert ran == kinds  # every call is one update: 3 eager ones per kind, the capturing call replays once
    assert graphs.captures == 2 and graphs.replays == 6
    assert [g.generators for g in fake.graphs] == [[generator], [generator]]
    graphs.reset()  # a load: warm up and capture again
    for kind in kinds[:8]:
        graphs(kind, update(kind))
    assert graphs.captures == 4 and graphs.replays == 8

    def broken():
        raise ValueError("operation not permitted when stream is capturing")

    graphs.reset()
    for _ in range(3):
        graphs("critic", lambda: None)
    with pytest.raises(RuntimeError, match="cuda_graph: capturing the update failed .*cuda_graph=false"):
        graphs("critic", broken)


# -- CUDA -----------------------------------------------------------------------------------------
@cuda
def test_a_captured_sample_draws_the_eager_batch_as_the_ring_grows_and_wraps():
    ring = _ring("cuda", steps=2)
    gen = torch.Generator("cuda").manual_seed(4)
    stream = torch.cuda.Stream()
    stream.wait_stream(torch.cuda.current_stream())
    with torch.cuda.stream(stream):
        ring.sample(256, 3, 0.9, gen)  # warm-up on the capture stream
    torch.cuda.current_stream().wait_stream(stream)
    graph = torch.cuda.CUDAGraph()
    graph.register_generator_state(gen)
    with torch.cuda.graph(graph, stream=stream):
        captured = ring.sample(256, 3, 0.9, gen)
    more = _ring("cuda", steps=20, seed=1)  # 20 steps into 16 slots: full and wrapped
    for i in range(20):
        ring.add(more.obs[i % 16], None, more.actions[i % 16], more.rewards[i % 16], more.next_obs[i % 16],
                 None, more.terminated[i % 16], more.ended[i % 16])
        if i in (3, 19):  # partly filled (6 slots), then wrapped (ptr 6 of 16)
            state = gen.get_state()
            graph.replay()
            after_replay = gen.get_state()
            gen.set_state(state)
            eager = ring.sample(256, 3, 0.9, gen)
            assert torch.equal(gen.get_state(), after_replay), "the replay did not advance the generator"
            for name in ("obs", "actions", "returns", "discount", "next_obs"):
                assert torch.equal(getattr(captured, name), getattr(eager, name)), (i, name)
    assert ring.size == 16 and ring.ptr == 6


def _run_updates(learner: FastOffPolicy, ring: ReplayRing, n: int, seed: int,
                 gen: torch.Generator | None = None) -> torch.Generator:
    """``n`` updates drawing from ``gen`` (a new CUDA generator if None) seeded with ``seed``.
    Passing the generator of an earlier call keeps a graphed learner's ``UpdateGraphs``: a new
    generator object makes the learner build new graphs for it."""
    gen = (torch.Generator("cuda") if gen is None else gen).manual_seed(seed)
    torch.cuda.manual_seed(seed + 1)  # the default generator: the actor's and the target's noise
    for _ in range(n):
        learner.update_from(ring, gen)
    torch.cuda.synchronize()
    return gen


TOLERANCE = {False: 1.0e-5, True: 1.0e-4}
"""Largest |graph - eager| weight difference allowed, by ``amp``: rounding-order differences
(scatter_add_ atomics; under bfloat16 also a rare flipped rounding of a cast weight) move a
weight by far less; a wrong batch, a skipped actor update or a generator that did not advance
moves it by about a learning rate's step (1e-3)."""


@cuda
@pytest.mark.parametrize(("algo", "amp"), [("fast-sac", False), ("fast-sac", True), ("fast-td3", False)])
def test_graph_updates_give_the_eager_updates_weights(algo, amp):
    ring = _ring("cuda")
    eager = _learner(_cfg(algo=algo, amp=amp), "cuda", ring)
    again = _learner(_cfg(algo=algo, amp=amp), "cuda", ring)  # eager against eager: the rounding noise
    graphed = _learner(_cfg(algo=algo, amp=amp, cuda_graph=True), "cuda", ring)
    start = _weights(eager)
    n = 12  # 3 eager warm-ups per kind (critic only, critic + actor), then replays of both
    gen_e, gen_g = _run_updates(eager, ring, n, 5), _run_updates(graphed, ring, n, 5)
    _run_updates(again, ring, n, 5)
    assert graphed.graphs.captures == 2 and graphed.graphs.replays == n - 6
    assert torch.equal(gen_e.get_state(), gen_g.get_state()), "the sampling generator"
    a, b, c = _weights(eager), _weights(graphed), _weights(again)
    diffs = {k: float((a[k].float() - b[k].float()).abs().max()) for k in a}
    noise = max(float((a[k].float() - c[k].float()).abs().max()) for k in a)
    moved = {k: float((a[k].float() - start[k].float()).abs().max()) for k in a}
    worst = max(diffs, key=diffs.get)
    print(f"{algo} amp={amp}: max |graph - eager| {diffs[worst]:.3g} ({worst}), max |eager - eager| {noise:.3g}")
    assert diffs[worst] <= TOLERANCE[amp], f"{worst}: {diffs[worst]:.3g}, eager vs eager {noise:.3g} (all: {diffs})"
    # the updates moved the weights far beyond the tolerance: the comparison has teeth
    assert moved["actor.net.0.weight"] > 20 * TOLERANCE[amp] and moved["critic.q1.0.weight"] > 20 * TOLERANCE[amp]
    torch.testing.assert_close(graphed.stats, eager.stats, rtol=1e-3, atol=1e-3)
    assert float(graphed.stats[6]) == n and float(graphed.stats[7]) == n // 2


@cuda
def test_resume_captures_again_and_continues_as_eager_updates_do():
    ring = _ring("cuda")
    eager = _learner(_cfg(), "cuda", ring)
    _run_updates(eager, ring, 4, 1)
    saved = eager.state()  # an eager run's checkpoint (capturable False) into a graph run
    graphed = _learner(_cfg(cuda_graph=True), "cuda", ring)
    gen = _run_updates(graphed, ring, 8, 2)
    graphs = graphed.graphs
    assert graphs.captures == 2
    graphed.load_state(saved)
    assert graphs.graphs == {} and all(g["capturable"] for g in graphed.critic_opt.param_groups)
    # the same generator object: the learner keeps its UpdateGraphs, so only load_state's reset
    # makes these calls warm up and capture again (a new generator would build new graphs anyway)
    _run_updates(graphed, ring, 8, 3, gen)
    assert graphed.graphs is graphs and graphs.captures == 4 and graphed.num_updates == 12
    _run_updates(eager, ring, 8, 3)
    a, b = _weights(eager), _weights(graphed)
    diffs = {k: float((a[k].float() - b[k].float()).abs().max()) for k in a}
    assert max(diffs.values()) <= TOLERANCE[False], diffs


@cuda
def test_final_critic_obs_with_the_env_step_as_a_graph():
    """The CPU test of test_fast_sac_final_obs on CUDA with ``cuda_graph=True`` env steps: the
    replays (step 4 on) must still hand out the critic observations before the resets."""
    from ambulo import envs

    env = envs.make("humanoid-walk", num_envs=3, device="cuda", seed=0, episode_length_s=0.2, cuda_graph=True)
    env.return_final_obs = True
    final = FinalCriticObs(env)
    ended_seen = 0
    for _ in range(24):
        (_, _, dones, extras), before = final.step(lambda: env.step(torch.zeros(3, env.num_actions, device="cuda")))
        after = extras["observations"]["critic"]
        same = (before == after).all(dim=1)
        assert torch.equal(same, ~dones), (same, dones)
        ended_seen += int(dones.sum())
    assert env._graph.replays >= 19 and ended_seen >= 6


@cuda
def test_a_graph_iteration_syncs_nowhere_and_a_resumed_run_captures_again(tmp_path):
    from ambulo import envs
    from ambulo.rl.episodes import EpisodeStats
    from ambulo.rl.offpolicy import OffPolicyRunner
    from cuda_sync import sync_debug

    num_envs = 64
    env = envs.make("humanoid-walk", num_envs=num_envs, device="cuda", seed=0, cuda_graph=True)
    cfg = offpolicy_cfg("humanoid-walk", "fast-sac", num_envs=num_envs, batch_size=1024,
                        actor_hidden_dims=(64,), critic_hidden_dims=(64,), cuda_graph=True)
    runner = OffPolicyRunner(env, cfg, episodes=EpisodeStats(num_envs, env.device))
    runner.learn(2)  # 18 updates: each kind's 3 warm-ups and its capture; the env's capture
    graphs = runner.alg.graphs
    assert graphs.captures == 2 and graphs.replays == 12

    def checked_iteration():  # learn's step path for one iteration; its one sync and log left out
        env.engine.check_overflow()  # the engine's periodic read (every 100 steps), by design
        torch.cuda.synchronize()
        with sync_debug("error"):  # a RuntimeError names the first synchronizing op
            for _ in range(cfg.num_steps_per_env):
                runner._collect()
                for _ in range(cfg.updates_per_step):
                    runner.alg.update_from(runner.ring, runner.generator)
        torch.cuda.synchronize()

    checked_iteration()
    assert graphs.replays == 12 + 16
    runner.save(str(tmp_path / "model.pt"))
    runner.load_for_resume(tmp_path / "model.pt")
    runner.learn(1)  # warm-ups and captures again
    assert runner.alg.graphs.captures == 4
    checked_iteration()
    stats = runner.alg.read_stats()
    assert all(torch.isfinite(torch.tensor(v)) for v in stats.values()), stats
