"""An RLEnv step's device work replayed as one CUDA graph (``EnvCfg.cuda_graph``).

On a GPU the eager step launches a few hundred small kernels (torch's ops and MuJoCo Warp's),
and at 4096 worlds the host launching them is the bound (issue 25: device busy 53 %). The step
has no host sync and no Python decision on device values (``RLEnv._device_step``), so its work
is the same sequence of kernels every step and can be captured once and replayed: one
``cudaGraphLaunch`` per step.

What stays outside the graph (Python, every step): the action checks by shape and dtype, the
copy of the actions into the graph's static input, the episode-statistics window
(``EpisodeStats.publish``: a Python counter) and the engine's overflow check (a host sync every
``overflow_check_steps``). What a replay cannot do, and so the captured code must not: advance
a Python counter or cursor (``DelayBuffer``'s head: graph mode is refused while a task uses
one), rebind a persistent tensor instead of writing it in place (the graph keeps reading the
old one), read a device value on the host.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import torch


@dataclass
class StepOutputs:
    """One step's device results (N = num_envs). ``GraphStep`` keeps the graph's static outputs
    as one (the next replay overwrites them) and returns copies."""

    obs: torch.Tensor
    """(N, num_obs) float32, after resets."""
    rewards: torch.Tensor
    """(N,) float32."""
    dones: torch.Tensor
    """(N,) bool: terminated or timed out (those envs were reset)."""
    time_outs: torch.Tensor
    """(N,) bool."""
    terminated: torch.Tensor
    """(N,) bool, diverged worlds included."""
    terminations: dict[str, torch.Tensor]
    """(N,) bool mask per termination term."""
    final_obs: torch.Tensor | None
    """(N, num_obs) float32 before resets when ``env.return_final_obs``, else None."""
    critic_obs: torch.Tensor | None
    """(N, num_privileged_obs) float32, or None when the task has no privileged terms."""


class GraphStep:
    """Runs ``env._device_step`` eagerly for ``cfg.cuda_graph_warmup_steps`` steps, then captures
    it (with the physics) into one CUDA graph and replays that graph per step."""

    def __init__(self, env):
        reason = env._graph_unsafe_reason()
        if reason is not None:
            raise ValueError(f"cuda_graph=True: {type(env).__name__} cannot be captured: {reason}; "
                             "set cuda_graph=False")
        self.env = env
        self.warmup_left = env.cfg.cuda_graph_warmup_steps
        self.graph = None
        self._warp_graph = None  # keeps MuJoCo Warp's scratch arrays of the capture alive
        self.actions: torch.Tensor | None = None
        """(N, num_actions) float32: the graph's static input."""
        self.out: StepOutputs | None = None
        self._engine_calls = 0
        """``engine.step`` calls per replay (``decimation`` when a latency steps one at a time)."""
        self.replays = 0
        self.captures = 0
        self._captured_for: tuple[int, bool] | None = None
        """(engine.model_version, env.return_final_obs) the graph was captured for."""
        self.stream = torch.cuda.Stream(env.device) if env.device.type == "cuda" else None
        """The side stream of the warm-up steps and the capture."""

    def step(self, actions: torch.Tensor) -> StepOutputs:
        env = self.env
        if self.graph is not None and (env.engine.model_version, env.return_final_obs) != self._captured_for:
            # a model array was replaced (a per-world field's first use: the graph reads the old
            # one) or the caller changed what the step computes: capture again
            self.graph = self._warp_graph = None
        if self.graph is None:
            if self.warmup_left > 0:
                # on the stream the capture will use: lazily made handles and workspaces (cuBLAS)
                # exist for it before the capture, which could not create them
                self.warmup_left -= 1
                with self._side_stream():
                    return env._device_step(actions)
            self._capture(actions)
        self.actions.copy_(actions)
        self.graph.replay()
        self.replays += 1
        env.engine.count_steps(self._engine_calls)
        # fresh tensors, as the eager step returns: the next replay overwrites the graph's, and
        # callers keep a step's outputs past the next step (rsl-rl's act() keeps the observations
        # its transition stores after env.step); a few copies against hundreds of launches
        out = _cloned(self.out)
        env.obs_buf, env._critic_buf = out.obs, out.critic_obs
        return out

    @contextlib.contextmanager
    def _side_stream(self):
        """Run on ``self.stream``, ordered after and before the current stream's work."""
        current = torch.cuda.current_stream(self.env.device)
        self.stream.wait_stream(current)
        with torch.cuda.stream(self.stream):
            yield
        current.wait_stream(self.stream)

    def _capture_graph(self, fn):
        """``(torch graph, Warp graph, fn's outputs)``: ``fn`` captured, not run."""
        from ambulo.engine.gpu import capture_torch_graph  # CUDA only: Warp's interop

        torch.cuda.synchronize(self.env.device)  # every eager launch done before the capture starts
        return capture_torch_graph(self.env.device, fn, generators=(self.env.generator,), stream=self.stream)

    def _capture(self, actions: torch.Tensor) -> None:
        env, engine = self.env, self.env.engine
        self.actions = actions.clone()
        before = engine.steps_in_capture
        # capturing runs nothing: the state is unchanged until the first replay
        self.graph, self._warp_graph, self.out = self._capture_graph(lambda: env._device_step(self.actions))
        self.captures += 1
        self._engine_calls = engine.steps_in_capture - before
        self._captured_for = (engine.model_version, env.return_final_obs)


def _cloned(out: StepOutputs) -> StepOutputs:
    def clone(t):
        return None if t is None else t.clone()

    return StepOutputs(obs=clone(out.obs), rewards=clone(out.rewards), dones=clone(out.dones),
                       time_outs=clone(out.time_outs), terminated=clone(out.terminated),
                       terminations={k: v.clone() for k, v in out.terminations.items()},
                       final_obs=clone(out.final_obs), critic_obs=clone(out.critic_obs))


__all__ = ["GraphStep", "StepOutputs"]
