"""FastSAC's gradient update alone: where its ~9 ms per update on an H200 goes.

Builds the real learner (``ambulo.rl.offpolicy.learner.FastOffPolicy``) and replay ring
(``replay.ReplayRing``) with the settings ``ambulo train TASK --algo ALGO`` uses
(``offpolicy_cfg``: worlds, ring length, batch, networks, atoms, bf16 autocast), fills the ring
with random transitions (no MuJoCo env is built: the observation sizes are flags, humanoid-walk's
by default) and times ``update_from`` (a replay sample and one update, as the runner calls it):

* per mode (``--modes``: eager, compile, graph, compile-graph, set through the config's
  ``compile`` / ``cuda_graph`` exactly as training sets them): warm-up updates (compilation and
  graph captures included, ``setup_s``), then ``--updates`` timed ones, ``--repeats`` times:
  ``gpu_ms`` per update (CUDA events around them; on the CPU the wall time), ``host_ms`` per
  update spent issuing them, and ``ratio`` = ``ceiling_ms`` / ``gpu_ms``;
* ``phases`` (eager): the same updates cut at the learner's own seams, timed with CUDA events
  (perf_counter on the CPU): the replay sample, the critic step (``critic.target``: actor sample
  and target critics up to the online critic's forward; ``critic.forward_loss``;
  ``critic.backward``; ``critic.clip``; ``critic.optimizer``; ``critic.stats``), the actor step
  (``actor.actor_forward``, ``actor.forward_loss``, ``actor.backward``, ``actor.clip``,
  ``actor.optimizer``, ``actor.alpha_stats``: the temperature's update), and ``polyak`` (the
  target critics' step). The seams are hooks on the learner's objects (its ``_critic_step`` /
  ``_actor_step``, the online critic's forward, ``Tensor.backward``, the optimizers' step hooks):
  the learner's code runs unchanged. ms per update (actor terms averaged over all updates);
  their sum is at most ``wall_ms``, the same run's time per update;
* ``census``: every matmul (``aten.mm/addmm/bmm/baddbmm``) of ``policy_delay`` eager updates,
  seen below autocast by a dispatch mode: FLOPs and calls per dtype (``float32_matmul``: any ran
  in float32), next to the analytic count ``update_flops``;
* ``--profile``: ``torch.profiler`` over a few eager updates: the top 15 kernels (CUDA) or ops
  (CPU) by self time with their share, time in matmul kernels against the rest, the device's
  busy share of the wall time, and the matmuls' input dtypes (``record_shapes``);
* the ceiling: ``update_flops`` (the matmuls of both critics' forward and backward, the target
  critics' and the actor's forward, the actor's backward) / the throughput of a large square
  matmul timed in the same run (bf16 on CUDA, float32 on the CPU).

Prints ``BENCH {json}`` after each stage and ends with one ``RESULT {json}`` line.

    python benchmarks/fast_sac_update.py --device cuda --modes eager,graph,compile --profile
    python benchmarks/fast_sac_update.py --device cpu --batch-size 256 --updates 8 --warmup 2 \
        --repeats 1 --profile --algo-cfg num_envs=64 buffer_steps_per_env=64   # a CPU smoke run
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import re
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

import torch
from torch.utils._python_dispatch import TorchDispatchMode

from ambulo.envs.symmetry import Reflection, TaskMirror
from ambulo.rl.offpolicy.config import offpolicy_cfg
from ambulo.rl.offpolicy.learner import FastOffPolicy
from ambulo.rl.offpolicy.replay import ReplayRing
from ambulo.utils.overrides import parse_overrides

MODES = ("eager", "compile", "graph", "compile-graph")
MATMUL_OPS = ("mm", "addmm", "bmm", "baddbmm", "_addmm_activation")
"""aten matmul ops (what ``nn.Linear`` and its backward become) counted and classified."""
MATMUL_KERNEL = re.compile(r"gemm|nvjet|cutlass|xmma|cublas|matmul|splitk|wgmma", re.IGNORECASE)
"""CUDA kernel names of matmuls (cuBLAS / cuBLASLt / CUTLASS; ``nvjet`` is cuBLASLt's Hopper family)."""


# -- the ceiling ---------------------------------------------------------------------------------

def _macs(inputs: int, hidden: tuple[int, ...], outputs: int) -> tuple[int, int]:
    """(multiply-adds of one row through ``mlp(inputs, hidden, outputs)``, those of its first layer)."""
    widths = [inputs, *hidden, outputs]
    return sum(a * b for a, b in zip(widths, widths[1:])), widths[0] * widths[1]


def update_flops(batch: int, num_obs: int, num_critic_obs: int, num_actions: int,
                 actor_hidden: tuple[int, ...], critic_hidden: tuple[int, ...], num_atoms: int, *,
                 sac: bool = True, policy_delay: int = 2) -> dict[str, int]:
    """Matmul FLOPs of one gradient update of ``FastOffPolicy`` (2 per multiply-add; the
    elementwise work, LayerNorm, softmax and the projection are not counted).

    With ``C`` the multiply-adds of one row through one critic, ``sum(in * out)`` over its
    Linear layers ``(critic_obs + actions) -> critic_hidden... -> num_atoms``, ``C1`` its first
    layer's, ``P`` and ``P1`` the same for the actor ``obs -> actor_hidden... -> 2 * actions``
    (fast-sac: mean and log std; ``actions`` for fast-td3) and ``B`` the batch::

        critic step = 2B * ( P + 2C          target: actor on next obs, both target critics
                           + 2C              both critics forward
                           + 2C              their weight gradients
                           + 2(C - C1) )     their input gradients (the batch's input needs none)
        actor step  = 2B * ( P + 2C          actor forward, both critics on its actions
                           + 2C + 2C         both critics' weight and input gradients
                           + P + (P - P1) )  the actor's weight and input gradients
        per update  = critic step + actor step / policy_delay

    e.g. humanoid-walk (72 / 78 obs, 21 actions, actor 512-256-128, critics 1024-512-256, 101
    atoms): C = 99*1024 + 1024*512 + 512*256 + 256*101 = 782592, C1 = 101376,
    P = 72*512 + 512*256 + 256*128 + 128*42 = 206080, P1 = 36864; at B = 32768 the critic step is
    2B * (P + 6C + 2(C - C1)) = 2B * 6264064 = 0.411 TFLOP, the actor step 2B * (3P + 6C - P1) =
    2B * 5276928 = 0.346 TFLOP: 0.583 TFLOP per update at policy_delay 2.
    """
    c, c1 = _macs(num_critic_obs + num_actions, tuple(critic_hidden), num_atoms)
    p, p1 = _macs(num_obs, tuple(actor_hidden), (2 if sac else 1) * num_actions)
    critic = 2 * batch * (p + 2 * c + 2 * c + 2 * c + 2 * (c - c1))
    actor = 2 * batch * (p + 2 * c + 2 * c + 2 * c + p + (p - p1))
    per_update = critic + actor / policy_delay
    return dict(critic_step=critic, actor_step=actor,
                per_update=int(per_update) if per_update == int(per_update) else per_update)


def matmul_tflops(device: torch.device, size: int, repeats: int) -> dict:
    """Throughput of a ``size`` square matmul (bf16 on CUDA, float32 on the CPU), best of
    ``repeats`` timed batches."""
    dtype = torch.bfloat16 if device.type == "cuda" else torch.float32
    a = torch.randn(size, size, device=device, dtype=dtype)
    b = torch.randn(size, size, device=device, dtype=dtype)
    per = 10 if device.type == "cuda" else 1
    best = math.inf
    for i in range(repeats + 1):
        with _Clock(device) as clock:
            for _ in range(per):
                torch.mm(a, b)
        if i:  # the first is the warm-up
            best = min(best, clock.ms / per)
    return dict(dtype=str(dtype).removeprefix("torch."), size=size, ms=best, tflops=2 * size**3 / best / 1e9)


# -- timing helpers --------------------------------------------------------------------------------

def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


class _Clock:
    """Milliseconds of a block: CUDA events on CUDA (device time), perf_counter on the CPU."""

    def __init__(self, device: torch.device):
        self.device, self.ms = device, 0.0

    def __enter__(self):
        _sync(self.device)
        if self.device.type == "cuda":
            self.start, self.end = (torch.cuda.Event(enable_timing=True) for _ in range(2))
            self.start.record()
        self.began = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.issued_ms = 1e3 * (time.perf_counter() - self.began)
        if self.device.type == "cuda":
            self.end.record()
        _sync(self.device)
        self.wall_ms = 1e3 * (time.perf_counter() - self.began)
        self.ms = self.start.elapsed_time(self.end) if self.device.type == "cuda" else self.wall_ms


class _Marks:
    """A timeline of labelled marks (CUDA events, or perf_counter on the CPU)."""

    def __init__(self, device: torch.device):
        self.cuda = device.type == "cuda"
        self.items: list[tuple[str, object]] = []

    def __call__(self, label: str) -> None:
        if self.cuda:
            event = torch.cuda.Event(enable_timing=True)
            event.record()
            self.items.append((label, event))
        else:
            self.items.append((label, time.perf_counter()))

    def ms(self, a, b) -> float:
        return a.elapsed_time(b) if self.cuda else 1e3 * (b - a)


# -- the setup -----------------------------------------------------------------------------------

def make_ring(cfg, sizes: dict, device: torch.device, seed: int = 0) -> ReplayRing:
    """A ring of ``cfg.buffer_steps_per_env`` steps of ``cfg.num_envs`` worlds, every slot
    written with random transitions (~1 % episode ends, half of them terminations)."""
    gen = torch.Generator(device).manual_seed(seed)
    n, obs, crit, act = cfg.num_envs, sizes["obs"], sizes["critic_obs"], sizes["actions"]
    ring = ReplayRing(n, cfg.buffer_steps_per_env, obs, crit, act, device)

    def randn(*shape):
        return torch.randn(*shape, generator=gen, device=device)

    bound = cfg.action_bound
    for _ in range(cfg.buffer_steps_per_env):
        ended = torch.rand(n, generator=gen, device=device) < 0.01
        terminated = ended & (torch.rand(n, generator=gen, device=device) < 0.5)
        actions = (torch.rand(n, act, generator=gen, device=device) * 2 - 1) * bound
        ring.add(randn(n, obs), randn(n, crit), actions, randn(n), randn(n, obs), randn(n, crit), terminated, ended)
    _sync(device)
    return ring


def stand_in_mirror(sizes: dict, device: torch.device) -> TaskMirror:
    """Mirror maps of the right sizes for ``--algo-cfg symmetry=true`` without building the task's env:
    a reversed order with alternating signs costs what the task's own gather-and-sign maps cost."""
    def reflection(size: int) -> Reflection:
        sign = torch.ones(size, device=device)
        sign[1::2] = -1.0
        return Reflection(torch.arange(size - 1, -1, -1, device=device), sign)

    return TaskMirror(policy=reflection(sizes["obs"]), critic=reflection(sizes["critic_obs"]),
                      actions=reflection(sizes["actions"]))


def make_learner(cfg, sizes: dict, device: torch.device) -> FastOffPolicy:
    torch.manual_seed(0)
    mirror = stand_in_mirror(sizes, device) if cfg.symmetry else None
    return FastOffPolicy(cfg, sizes["obs"], sizes["critic_obs"], sizes["actions"], device, mirror=mirror)


# -- the stages ----------------------------------------------------------------------------------

def time_mode(alg: FastOffPolicy, ring: ReplayRing, device: torch.device, warmup: int, updates: int,
              repeats: int) -> dict:
    """Warm-up updates (compile, graph captures), then ``repeats`` x ``updates`` timed ones."""
    gen = torch.Generator(device).manual_seed(0)
    began = time.perf_counter()
    for _ in range(warmup):
        alg.update_from(ring, gen)
    _sync(device)
    setup_s = time.perf_counter() - began
    alg.read_stats()
    gpu, host, wall = [], [], []
    for _ in range(repeats):
        with _Clock(device) as clock:
            for _ in range(updates):
                alg.update_from(ring, gen)
        gpu.append(clock.ms / updates)
        host.append(clock.issued_ms / updates)
        wall.append(clock.wall_ms / updates)
    stats = alg.read_stats()
    out = dict(gpu_ms=statistics.median(gpu), host_ms=statistics.median(host), wall_ms=statistics.median(wall),
               gpu_ms_all=gpu, setup_s=setup_s, critic_loss=stats["critic_loss"],
               captures=alg.graphs.captures if alg.graphs is not None else 0,
               graphed=alg.graphed, compiled=alg._critic_step != alg._critic_update)
    if device.type == "cuda":
        out["max_memory_gib"] = torch.cuda.max_memory_allocated(device) / 2**30
    return out


@contextlib.contextmanager
def phase_hooks(alg: FastOffPolicy, marks: _Marks):
    """Marks at the learner's seams (see the module docstring) while inside; all removed after."""
    state = dict(ctx="", backwards=0)
    critic_step, actor_step = alg._critic_step, alg._actor_step
    backward = torch.Tensor.backward

    def wrap(step, ctx, last):
        def run(batch):
            state.update(ctx=ctx, backwards=0)
            step(batch)
            marks(f"{ctx}.{last}")
            state["ctx"] = ""
        return run

    def critic_pre(module, args):
        if state["ctx"]:
            marks("critic.target" if state["ctx"] == "critic" else "actor.actor_forward")

    def marked_backward(tensor, *args, **kwargs):
        first = bool(state["ctx"]) and state["backwards"] == 0  # the actor's alpha loss: not a seam
        state["backwards"] += 1
        if first:
            marks(f"{state['ctx']}.forward_loss")
        backward(tensor, *args, **kwargs)
        if first:
            marks(f"{state['ctx']}.backward")

    handles = [alg.critic.register_forward_pre_hook(critic_pre)]
    for opt, ctx in ((alg.critic_opt, "critic"), (alg.actor_opt, "actor")):
        handles.append(opt.register_step_pre_hook(lambda *a, ctx=ctx: marks(f"{ctx}.clip")))
        handles.append(opt.register_step_post_hook(lambda *a, ctx=ctx: marks(f"{ctx}.optimizer")))
    alg._critic_step = wrap(critic_step, "critic", "stats")
    alg._actor_step = wrap(actor_step, "actor", "alpha_stats")
    torch.Tensor.backward = marked_backward
    try:
        yield
    finally:
        torch.Tensor.backward = backward
        alg._critic_step, alg._actor_step = critic_step, actor_step
        for handle in handles:
            handle.remove()


def time_phases(alg: FastOffPolicy, ring: ReplayRing, device: torch.device, updates: int) -> dict:
    """Eager updates cut at the learner's seams: ms per update of each phase (segments between
    consecutive marks of one update, named by the mark that ends them)."""
    cfg = alg.cfg
    gen = torch.Generator(device).manual_seed(1)
    marks = _Marks(device)
    with phase_hooks(alg, marks):
        _sync(device)
        for _ in range(updates):
            marks("start")
            batch = ring.sample(cfg.batch_size, cfg.n_step, cfg.gamma, gen)
            marks("sample")
            alg.update(batch)  # the critic step, the actor step on its turns, Polyak
            marks("polyak")
        _sync(device)
    phases: dict[str, float] = defaultdict(float)
    for (_, a), (label, b) in zip(marks.items, marks.items[1:]):
        if label != "start":  # the gap between updates belongs to no phase
            phases[label] += marks.ms(a, b)
    wall = marks.ms(marks.items[0][1], marks.items[-1][1]) / updates
    per = {k: v / updates for k, v in phases.items()}
    groups = defaultdict(float)
    for k, v in per.items():
        groups[k.split(".")[0]] += v
    return dict(updates=updates, ms=per, groups=dict(groups), sum_ms=sum(per.values()), wall_ms=wall,
                share={k: v / wall for k, v in per.items()})


class MatmulCensus(TorchDispatchMode):
    """Every matmul run while active (below autocast and autograd: the dtypes the kernels get):
    FLOPs and calls per input dtype."""

    def __init__(self):
        super().__init__()
        self.flops: dict[str, int] = defaultdict(int)
        self.calls: dict[str, int] = defaultdict(int)
        self.shapes: dict[str, int] = defaultdict(int)

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        out = func(*args, **(kwargs or {}))
        name = func.overloadpacket.__name__
        if name in MATMUL_OPS:
            a, b = (args[0], args[1]) if name in ("mm", "bmm") else (args[1], args[2])
            flops = 2 * a.shape[-2] * a.shape[-1] * b.shape[-1] * (a.shape[0] if a.dim() == 3 else 1)
            dtype = str(a.dtype).removeprefix("torch.")
            self.flops[dtype] += flops
            self.calls[dtype] += 1
            self.shapes[f"{name} {dtype} {list(a.shape)}x{list(b.shape)}"] += 1
        return out


def matmul_census(alg: FastOffPolicy, ring: ReplayRing, device: torch.device) -> dict:
    """The matmuls of ``policy_delay`` eager updates (one actor turn): per update."""
    n = alg.cfg.policy_delay
    gen = torch.Generator(device).manual_seed(2)
    census = MatmulCensus()
    with census:
        for _ in range(n):
            alg.update_from(ring, gen)
    _sync(device)
    flops = {k: v / n for k, v in census.flops.items()}
    return dict(flops_per_update=sum(census.flops.values()) / n, flops_by_dtype=flops,
                calls_per_update={k: v / n for k, v in census.calls.items()},
                float32_matmul=census.flops.get("float32", 0) > 0, shapes=dict(census.shapes))


def profile_updates(alg: FastOffPolicy, ring: ReplayRing, device: torch.device, updates: int) -> dict:
    """torch.profiler over ``updates`` eager updates: top 15 kernels (CUDA) or ops (CPU) by self
    time, matmul time against the rest, busy share of the wall, matmul input dtypes."""
    from torch.autograd import DeviceType
    from torch.profiler import ProfilerActivity, profile

    cuda = device.type == "cuda"
    gen = torch.Generator(device).manual_seed(3)
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if cuda else [])
    _sync(device)
    with profile(activities=activities, record_shapes=True) as prof:
        began = time.perf_counter()
        for _ in range(updates):
            alg.update_from(ring, gen)
        _sync(device)
        wall_us = 1e6 * (time.perf_counter() - began)
    events = prof.events()
    kernels: dict[str, list] = defaultdict(lambda: [0.0, 0])
    dtypes: dict[str, int] = defaultdict(int)
    float32 = 0
    for evt in events:
        if getattr(evt, "is_user_annotation", False) or evt.name.startswith(("Optimizer.", "ProfilerStep")):
            if cuda:  # on the GPU timeline these ranges span kernels: counting them would count twice
                continue
        if cuda and evt.device_type == DeviceType.CUDA:
            us = evt.time_range.elapsed_us()
        elif not cuda and evt.device_type == DeviceType.CPU:
            us = evt.self_cpu_time_total
        else:
            us = None
        if us is not None:
            kernels[evt.name][0] += us
            kernels[evt.name][1] += 1
        if evt.device_type == DeviceType.CPU and evt.name.removeprefix("aten::") in MATMUL_OPS:
            found = [str(d) for d in getattr(evt, "input_dtypes", None) or [] if d]
            dtypes["/".join(sorted(set(found))) or "unknown"] += 1
            float32 += "float" in found  # c10's name of float32 (bf16: c10::BFloat16)

    def is_matmul(name: str) -> bool:
        return bool(MATMUL_KERNEL.search(name)) if cuda else name.removeprefix("aten::") in MATMUL_OPS

    total = sum(us for us, _ in kernels.values()) or 1.0
    matmul = sum(us for name, (us, _) in kernels.items() if is_matmul(name))
    top = sorted(kernels.items(), key=lambda kv: -kv[1][0])[:15]
    return dict(updates=updates, kind="cuda kernels" if cuda else "cpu ops (self time)",
                top=[dict(name=name[:160], ms_per_update=us / 1e3 / updates, share=us / total, calls=n,
                          matmul=is_matmul(name)) for name, (us, n) in top],
                total_ms_per_update=total / 1e3 / updates, matmul_ms_per_update=matmul / 1e3 / updates,
                matmul_share=matmul / total, rest_ms_per_update=(total - matmul) / 1e3 / updates,
                busy_share_of_wall=total / wall_us, wall_ms_per_update=wall_us / 1e3 / updates,
                matmul_op_input_dtypes=dict(dtypes), float32_matmul_ops=float32)


# -- main ----------------------------------------------------------------------------------------

def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--task", default="humanoid-walk", help="offpolicy_cfg's task (its worlds, ring, batch, networks)")
    p.add_argument("--algo", default="fast-sac", choices=("fast-sac", "fast-td3"))
    p.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    p.add_argument("--modes", default=None, help="comma list of " + ", ".join(MODES)
                   + " (default eager,graph on cuda, eager on cpu)")
    p.add_argument("--batch-size", default=None, help="comma list (default the task's batch_size)")
    p.add_argument("--updates", type=int, default=64, help="timed updates per repeat")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--warmup", type=int, default=12, help="updates before timing (graph captures: 3 per kind)")
    p.add_argument("--phase-updates", type=int, default=None, help="eager updates cut into phases (default --updates)")
    p.add_argument("--profile", action="store_true", help="torch.profiler over --profile-updates eager updates")
    p.add_argument("--profile-updates", type=int, default=4)
    p.add_argument("--obs", type=int, default=72, help="policy observations (humanoid-walk: 72)")
    p.add_argument("--critic-obs", type=int, default=78, help="critic observations (humanoid-walk: 78)")
    p.add_argument("--actions", type=int, default=21, help="actions (humanoid-walk: 21)")
    p.add_argument("--algo-cfg", nargs="*", default=[], metavar="KEY=VALUE",
                   help="offpolicy_cfg overrides, as ambulo train's --algo-cfg (e.g. num_envs=64)")
    p.add_argument("--matmul-size", type=int, default=None, help="the ceiling's square matmul (8192 cuda, 512 cpu)")
    p.add_argument("--threads", type=int, default=None, help="CPU torch threads (default the config's cpu_threads)")
    return p.parse_args(argv)


def emit(tag: str, payload: dict) -> None:
    print(f"{tag} " + json.dumps(payload), flush=True)


def main(argv=None) -> dict:
    args = parse_args(argv)
    device = torch.device(args.device)
    cuda = device.type == "cuda"
    modes = (args.modes or ("eager,graph" if cuda else "eager")).split(",")
    for mode in modes:
        if mode not in MODES:
            raise SystemExit(f"--modes: unknown mode {mode!r}; one of {', '.join(MODES)}")
    overrides = parse_overrides(offpolicy_cfg(args.task, args.algo), args.algo_cfg)
    base = offpolicy_cfg(args.task, args.algo, **overrides)
    if not cuda:
        threads = base.cpu_threads if args.threads is None else args.threads
        if threads > 0:
            torch.set_num_threads(threads)
    batches = [int(b) for b in args.batch_size.split(",")] if args.batch_size else [base.batch_size]
    sizes = dict(obs=args.obs, critic_obs=args.critic_obs, actions=args.actions)
    ceiling = matmul_tflops(device, args.matmul_size or (8192 if cuda else 512), repeats=5)
    result = dict(task=args.task, algo=args.algo, device=str(device), torch=torch.__version__,
                  gpu=torch.cuda.get_device_name(device) if cuda else None,
                  threads=None if cuda else torch.get_num_threads(), sizes=sizes,
                  cfg=dict(num_envs=base.num_envs, buffer_steps_per_env=base.buffer_steps_per_env,
                           actor_hidden_dims=base.actor_hidden_dims, critic_hidden_dims=base.critic_hidden_dims,
                           num_atoms=base.num_atoms, policy_delay=base.policy_delay, n_step=base.n_step,
                           amp=base.amp and cuda, critic_layer_norm=base.critic_layer_norm, symmetry=base.symmetry),
                  ceiling=ceiling, updates=args.updates, repeats=args.repeats, warmup=args.warmup,
                  batches={}, skipped={})
    emit("BENCH", dict(stage="ceiling", **ceiling))
    ring = make_ring(base, sizes, device)
    for batch in batches:
        flops = update_flops(batch, sizes["obs"], sizes["critic_obs"], sizes["actions"], base.actor_hidden_dims,
                             base.critic_hidden_dims, base.num_atoms, sac=base.algo == "fast-sac",
                             policy_delay=base.policy_delay)
        ceiling_ms = flops["per_update"] / (ceiling["tflops"] * 1e9)
        entry = result["batches"][str(batch)] = dict(flops=flops, ceiling_ms=ceiling_ms, modes={})
        for mode in ["eager", *[m for m in modes if m != "eager"]]:  # eager first: phases, census, profile
            if mode != "eager" and not cuda:
                result["skipped"][mode] = "compile and cuda_graph apply on CUDA only (the learner ignores them on the CPU)"
                continue
            cfg = offpolicy_cfg(args.task, args.algo, **{**overrides, "batch_size": batch,
                                                         "compile": mode.startswith("compile"),
                                                         "cuda_graph": mode.endswith("graph")})
            alg = make_learner(cfg, sizes, device)
            timed = time_mode(alg, ring, device, args.warmup, args.updates, args.repeats)
            timed["ratio"] = ceiling_ms / timed["gpu_ms"]
            if mode in modes:
                entry["modes"][mode] = timed
                emit("BENCH", dict(stage="mode", batch=batch, mode=mode, **timed))
            if mode == "eager":
                entry["phases"] = time_phases(alg, ring, device, args.phase_updates or args.updates)
                emit("BENCH", dict(stage="phases", batch=batch, **entry["phases"]))
                entry["census"] = matmul_census(alg, ring, device)
                emit("BENCH", dict(stage="census", batch=batch, **entry["census"]))
                if args.profile:
                    entry["profile"] = profile_updates(alg, ring, device, args.profile_updates)
                    emit("BENCH", dict(stage="profile", batch=batch, **entry["profile"]))
            del alg
            if cuda:
                torch.cuda.empty_cache()
    first = result["batches"][str(batches[0])]
    result["ratio"] = {mode: m["ratio"] for mode, m in first["modes"].items()}
    emit("RESULT", result)
    return result


if __name__ == "__main__":
    main()
