"""Env-steps/s of humanoid-walk on the GPU engine vs raw MuJoCo Warp stepping (the ceiling).

The env side is what a PPO rollout of ``ambulo train`` runs per step, on the runner training
builds (``rollout_fns``): the algorithm's ``act`` (rsl-rl-lib's actor sampling actions, the
critic, log-probabilities, under ``torch.inference_mode`` as rsl-rl's runner does), then
``env.step`` through ``RslRlVecEnv`` (actions, ``decimation`` physics steps, observations,
rewards, terminations, resets, episode statistics) and the algorithm's and logger's step
bookkeeping. Host syncs per step are counted in a separate short pass (``syncs``, CUDA only).

The ceiling is ``mujoco_warp.step`` alone, in the same process, on the same device model
(``env.engine.wp_model``, with the env's per-world friction and masses), its own ``Data`` of
the same size (``nworld``, ``nconmax``, ``njmax`` as the engine's), ``decimation`` steps per
env step captured in one CUDA graph (``wp.ScopedCapture``). Its work is the env's: each timed
env run records the state every physics call started from (one ``_foreach_copy_`` of the
engine's state fields per env step), and the raw side replays exactly those (one copy back per
env step, then the graph), so falls, pushes and resets cost the ceiling the same contacts and
solver iterations. Both sides pay one copy of the same bytes per env step. A free-running raw
side (no copies, its humanoids falling under the first recorded controls) is reported for
information. Timed loops are bracketed by ``torch.cuda.synchronize``; runs alternate (env, raw,
env, raw) and the best of each is kept.

    python benchmarks/env_gpu.py [--num-envs 1024,4096,16384] [--steps 100] [--warmup 30] [--modes eager,graph]
    python benchmarks/env_gpu.py --device cpu --num-envs 4 --steps 3 --warmup 2   # Warp's CPU device
    python benchmarks/env_gpu.py --num-envs 4096 --modes graph --reset-forward kinematics

``--reset-forward`` is ``EnvCfg.reset_forward``: ``full`` (the default: a reset's whole MuJoCo
forward) or ``kinematics`` (poses and velocities only, the pass a GPU runs every step).

Modes (``--modes``): ``eager`` launches the env step's kernels one by one; ``graph`` is
``EnvCfg.cuda_graph=True`` (``envs.graph_step``: the step's device work replayed as one CUDA
graph after 3 eager steps), the policy's ``act`` still eager. In graph mode the recording copy
is captured into the graph as a copy to a staging buffer, copied to its slot after the step:
graph mode pays two copies of the state per env step where eager mode pays one (a bias against
the graph, of ~1 copy of a few MB at 4096 worlds).

ratio = env physics-steps/s / raw physics-steps/s (the same as the env-steps/s ratio: both
sides run ``decimation`` physics steps per env step). Ends with one ``RESULT {json}`` line;
"ratio" is the smallest over the sizes of the eager mode (``graph_ratio`` of the graph mode),
``target`` the bar of issue 25 (>= 0.8 at 4096 envs) for each mode.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import datetime
import gc
import io
import itertools
import json
import time
import warnings
from collections.abc import Callable

import mujoco
import mujoco_warp as mjw
import torch
import warp as wp

import ambulo.envs
from ambulo.engine.gpu import capture_graph, stack_versions
from ambulo.engine.gpu import synchronize as sync

TASK = "humanoid-walk"
TARGET = {"num_envs": 4096, "min_ratio": 0.8}
"""Issue 25's bar: training's rollout step keeps at least 80 % of raw MuJoCo Warp's throughput
at 4096 envs."""



def device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    return f"Warp CPU device ({wp.get_device('cpu').name})"


# -- the policy ------------------------------------------------------------------------------
def rollout_fns(env) -> tuple[Callable, Callable, object, str]:
    """``act(obs) -> actions``, ``step(actions) -> (obs, dones)``, the first observations and a
    description: one step of rsl-rl's rollout loop (``OnPolicyRunner.learn``) as ``ambulo train``
    runs it, on the runner it builds (``AmbuloRunner`` from ``train.runner_cfg``): the
    algorithm's ``act`` (actor sampled, critic value, log-probability, the transition kept),
    ``RslRlVecEnv.step`` (the env, ambulo's episode returns), ``process_env_step`` (NaN flag,
    time-out bootstrap, rollout storage) and the logger's step bookkeeping. The storage is
    emptied every ``num_steps_per_env`` steps, where training would run its update (not timed
    here). rsl-rl-lib is required: timing another policy would not time training."""
    from ambulo.rl.config import ppo_cfg
    from ambulo.rl.episodes import EpisodeStats
    from ambulo.rl.train import AmbuloRunner, runner_cfg
    from ambulo.rl.vecenv import RslRlVecEnv

    ppo = ppo_cfg(TASK, num_envs=env.num_envs)
    vec = RslRlVecEnv(env, EpisodeStats(env.num_envs, env.device))
    with contextlib.redirect_stdout(io.StringIO()):  # rsl-rl prints the networks
        runner = AmbuloRunner(vec, runner_cfg(env, ppo), log_dir=None, device=str(env.device))
    alg, logger, device = runner.alg, runner.logger, runner.device
    alg.train_mode()  # as learn() does

    def act(obs):
        if alg.storage.step == ppo.num_steps_per_env:
            alg.storage.clear()  # where the update would have used it
        return alg.act(obs)

    def step(actions):
        obs, rewards, dones, extras = vec.step(actions.to(env.device))
        obs, rewards, dones = obs.to(device), rewards.to(device), dones.to(device)
        alg.process_env_step(obs, rewards, dones, extras)
        logger.process_env_step(rewards, dones, extras, None)
        return obs, dones

    actor = alg.actor
    size = f"{env.num_obs}-{'-'.join(map(str, ppo.actor_hidden_dims))}-{env.num_actions} {ppo.activation}"
    policy = (f"AmbuloRunner rollout step: rsl-rl-lib {type(actor).__name__} {size} sampled by "
              f"{type(actor.distribution).__name__}, critic, log-prob, storage")
    return act, step, vec.get_observations(), policy


def count_syncs(act, step, obs, steps: int, device: torch.device):
    """Where the rollout step waits for the device: torch's sync debug mode warns once per
    synchronizing op, naming the Python line (CUDA only; None elsewhere). Returns the last
    observations and ``{"per_step", "where"}``."""
    if device.type != "cuda":
        return obs, None
    with warnings.catch_warnings(record=True) as caught, torch.inference_mode():
        warnings.simplefilter("always")
        torch.cuda.set_sync_debug_mode("warn")
        try:
            for _ in range(steps):
                obs, _ = step(act(obs))
        finally:
            torch.cuda.set_sync_debug_mode("default")
    where = collections.Counter(f"{w.filename}:{w.lineno}" for w in caught
                                if "synchroniz" in str(w.message).lower()
                                and "prototype feature" not in str(w.message).lower())  # torch's notice of the mode
    return obs, {"per_step": round(sum(where.values()) / steps, 2), "where": dict(where.most_common(10))}


# -- the ceiling -----------------------------------------------------------------------------
class RawWarp:
    """``mujoco_warp.step`` x ``nstep`` on the engine's device model and a Data of its own."""

    def __init__(self, engine, nstep: int, nconmax: int | None = None, njmax: int | None = None):
        """``nconmax``/``njmax``: buffer sizes per world (default: the engine's)."""
        self.device, self.nstep = engine.device, nstep
        self.model = engine.wp_model
        data = mujoco.MjData(engine.model)
        mujoco.mj_forward(engine.model, data)
        with wp.ScopedDevice(engine.wp_device):
            self.data = mjw.put_data(engine.model, data, nworld=engine.num_worlds,
                                     nconmax=nconmax or engine.nconmax, njmax=njmax or engine.njmax)
        self.names = list(engine.initial_state)
        self.state = [wp.to_torch(getattr(self.data, n)).view(engine.field(n).shape) for n in self.names]
        self.wp_device = engine.wp_device
        self.model_version = engine.model_version
        """The engine's model arrays this captured: a later per-world expansion replaces them."""
        self.graph = None
        if self.device.type == "cuda":
            self._physics()  # load the modules first: a capture cannot
            sync(self.device)
            self._stream = wp.Stream(self.wp_device)

            def steps():
                for _ in range(self.nstep):
                    mjw.step(self.model, self.data)

            self.graph = capture_graph(self.wp_device, self._stream, steps)

    def _physics(self) -> None:
        with wp.ScopedDevice(self.wp_device):
            for _ in range(self.nstep):
                mjw.step(self.model, self.data)

    def launch(self) -> None:
        """``nstep`` physics steps, ordered after torch's work on its current stream."""
        if self.graph is None:
            self._physics()
            return
        stream = wp.stream_from_torch(torch.cuda.current_stream(self.device))
        with wp.ScopedDevice(self.wp_device), wp.ScopedStream(stream, sync_enter=False):
            wp.capture_launch(self.graph)

    def time_replay(self, recorded: list[torch.Tensor], steps: int) -> float:
        """Seconds for ``steps`` x (copy recorded state ``i`` in, ``nstep`` physics steps)."""
        sync(self.device)
        start = time.perf_counter()
        for i in range(steps):
            torch._foreach_copy_(self.state, [r[i] for r in recorded])
            self.launch()
        sync(self.device)
        return time.perf_counter() - start

    def replay_match(self, recorded: list[torch.Tensor], tol: float = 1e-4) -> float:
        """Fraction of worlds whose qpos after replaying recorded step 0 is the env's at step 1
        within ``tol`` (m, rad): the check that the ceiling redoes the env's physics (worlds the
        env reset in between differ)."""
        qpos = self.names.index("qpos")
        torch._foreach_copy_(self.state, [r[0] for r in recorded])
        self.launch()
        error = (self.state[qpos] - recorded[qpos][1]).abs().amax(dim=1)
        return float((error <= tol).float().mean())

    def time_free(self, recorded: list[torch.Tensor], steps: int) -> float:
        """Seconds for ``steps`` launches from recorded state 0, no copies in between."""
        torch._foreach_copy_(self.state, [r[0] for r in recorded])
        sync(self.device)
        start = time.perf_counter()
        for _ in range(steps):
            self.launch()
        sync(self.device)
        return time.perf_counter() - start


# -- the env side ----------------------------------------------------------------------------
class Recorder:
    """Wraps ``engine.step`` to copy the state every physics call starts from into a slot.

    ``staged``: for a step replayed as a CUDA graph, where a Python slot index cannot advance:
    the wrapper (installed for good, before the capture) copies into one staging buffer, and
    ``after_step`` copies that into the next slot."""

    def __init__(self, engine, steps: int, staged: bool = False):
        self.engine = engine
        self.live = [engine.field(n) for n in engine.initial_state]
        self.slots = [torch.empty((steps, *t.shape), dtype=t.dtype, device=t.device) for t in self.live]
        self.count = 0
        self.recording = False
        self.stage = [torch.empty_like(t) for t in self.live] if staged else None
        if staged:
            step = type(engine).step

            def staging(num_substeps: int = 1, refresh: bool = False):
                torch._foreach_copy_(self.stage, self.live)
                return step(engine, num_substeps, refresh)

            engine.step = staging

    def __enter__(self):
        self.count = 0
        self.recording = True
        if self.stage is not None:
            return self
        step = type(self.engine).step

        def recording(num_substeps: int = 1, refresh: bool = False):
            torch._foreach_copy_([s[self.count] for s in self.slots], self.live)
            self.count += 1
            return step(self.engine, num_substeps, refresh)

        self.engine.step = recording
        return self

    def after_step(self) -> None:
        """After each env step: the staged copy to its slot (staged mode, while recording)."""
        if self.stage is not None and self.recording:
            torch._foreach_copy_([s[self.count] for s in self.slots], self.stage)
            self.count += 1

    def __exit__(self, *exc):
        self.recording = False
        if self.stage is None:
            del self.engine.step  # the class's method again


def time_env(env, act, step, obs, steps: int, recorder: Recorder | None):
    """Seconds for ``steps`` rollout steps (policy + env), the last observations, episodes ended."""
    ended = torch.zeros((), dtype=torch.long, device=env.device)
    with torch.inference_mode(), recorder or contextlib.nullcontext():
        sync(env.device)
        start = time.perf_counter()
        for _ in range(steps):
            obs, dones = step(act(obs))
            ended += dones.sum()
            if recorder is not None:
                recorder.after_step()
        sync(env.device)
        seconds = time.perf_counter() - start
    return seconds, obs, int(ended)


def measure(num_envs: int, device: str, steps: int, warmup: int, repeats: int, mode: str = "eager",
            reset_forward: str = "full") -> dict:
    graph = mode == "graph"
    env = ambulo.envs.make(TASK, num_envs=num_envs, device=device, engine="warp", seed=0, cuda_graph=graph,
                           reset_forward=reset_forward)
    if graph and env._graph is None:
        raise RuntimeError("graph mode needs CUDA (EnvCfg.cuda_graph is ignored elsewhere)")
    decimation = env.cfg.decimation
    act, step, obs, policy = rollout_fns(env)
    # staged: the recording copy must be in the step when its graph is captured (in the warm-up)
    recorder = Recorder(env.engine, steps, staged=True) if graph else None
    _, obs, _ = time_env(env, act, step, obs, warmup, None)  # graphs captured, resets under way
    raw = RawWarp(env.engine, decimation)
    recorder = recorder or Recorder(env.engine, steps)
    env_s, replay_s, free_s, ended = [], [], [], 0
    for _ in range(repeats):
        seconds, obs, ended_run = time_env(env, act, step, obs, steps, recorder)
        if recorder.count != steps:
            raise RuntimeError(f"{recorder.count} physics calls in {steps} env steps; expected one each")
        env_s.append(seconds)
        ended += ended_run
        replay_s.append(raw.time_replay(recorder.slots, steps))
        free_s.append(raw.time_free(recorder.slots, steps))
    if env.engine.model_version != raw.model_version:
        raise RuntimeError("the env replaced model arrays after the ceiling captured them; warm up longer")
    match = raw.replay_match(recorder.slots) if steps > 1 else None
    obs, syncs = count_syncs(act, step, obs, min(steps, 20), env.device)  # after timing: warnings cost time
    env_rate = num_envs * steps / min(env_s)
    raw_rate = num_envs * steps / min(replay_s)
    row = {
        "num_envs": num_envs,
        "mode": mode,
        "reset_forward": reset_forward,
        "env_steps_per_s": round(env_rate),
        "physics_steps_per_s": round(env_rate * decimation),
        "raw_physics_steps_per_s": round(raw_rate * decimation),
        "ratio": round(env_rate / raw_rate, 3),
        "env_ms_per_step": round(1e3 * min(env_s) / steps, 3),
        "raw_ms_per_step": round(1e3 * min(replay_s) / steps, 3),
        "raw_free_ms_per_step": round(1e3 * min(free_s) / steps, 3),
        "episodes_ended_per_step": round(ended / (repeats * steps), 2),
        "replay_match": match,
        "nconmax": env.engine.nconmax,
        "njmax": env.engine.njmax,
        "syncs": syncs,
        "policy": policy,
    }
    del env, raw, recorder, act, step, obs
    gc.collect()
    if torch.cuda.is_available():
        torch.cuda.empty_cache()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", nargs="+", default=["1024,4096,16384"],
                        help="sizes, comma- or space-separated")
    parser.add_argument("--device", default="cuda", help="cuda[:k], or cpu (Warp's CPU device)")
    parser.add_argument("--steps", type=int, default=100, help="env steps per timed run")
    parser.add_argument("--warmup", type=int, default=30, help="env steps before timing")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--modes", default=None,
                        help="eager and/or graph (EnvCfg.cuda_graph: the env step as one CUDA graph), comma-separated; "
                             "default both on CUDA, eager elsewhere (graph mode needs CUDA)")
    parser.add_argument("--reset-forward", choices=("full", "kinematics"), default="full",
                        help="EnvCfg.reset_forward: a reset's full forward, or its kinematics only (default full)")
    args = parser.parse_args()
    sizes = [int(s) for arg in args.num_envs for s in arg.split(",") if s]
    device = torch.device(args.device)
    modes = [m for m in (args.modes or ("eager,graph" if device.type == "cuda" else "eager")).split(",") if m]
    if set(modes) - {"eager", "graph"}:
        parser.error(f"--modes: eager and/or graph, got {args.modes!r}")
    rows = []
    for n, mode in itertools.product(sizes, modes):
        rows.append(measure(n, args.device, args.steps, args.warmup, args.repeats, mode, args.reset_forward))
        r = rows[-1]
        print(f"N={n:6d} {mode:>5} reset_forward={args.reset_forward}: env {r['env_steps_per_s']:>9} env-steps/s ({r['env_ms_per_step']:.2f} ms)   raw "
              f"{r['raw_ms_per_step']:.2f} ms/step (free-running {r['raw_free_ms_per_step']:.2f})   "
              f"ratio {r['ratio']:.3f}   {r['episodes_ended_per_step']} episodes ended/step   "
              f"host syncs/step {None if r['syncs'] is None else r['syncs']['per_step']}", flush=True)

    def at_target(mode):
        return next((r["ratio"] for r in rows if r["num_envs"] == TARGET["num_envs"] and r["mode"] == mode), None)

    def smallest(mode):
        ratios = [r["ratio"] for r in rows if r["mode"] == mode]
        return min(ratios) if ratios else None

    targets = {mode: {**TARGET, "ratio": at_target(mode),
                      "met": None if at_target(mode) is None else at_target(mode) >= TARGET["min_ratio"]}
               for mode in modes}
    result = {
        "benchmark": "env_gpu", "task": TASK, "device": device_name(device),
        "decimation": ambulo.envs.make_cfg(TASK).decimation, "steps": args.steps, "policy": rows[0]["policy"],
        "reset_forward": args.reset_forward,
        "versions": stack_versions(), "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "sizes": rows, "ratio": smallest("eager"), "graph_ratio": smallest("graph"),
        "target": targets.get("eager", {**TARGET, "ratio": None, "met": None}),
        "graph_target": targets.get("graph"),
    }
    print("RESULT " + json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
