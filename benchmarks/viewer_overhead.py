"""What the web viewer costs the simulation it watches (issue 29: at most 5 %).

    python benchmarks/viewer_overhead.py [--task humanoid-walk] [--num-envs 64] [--device cpu]
                                         [--steps 200] [--rounds 3] [--rate-hz 30]

Env-steps/s of the task's step loop (zero actions: the same physics work as training's rollout,
without the learner) with no viewer and with one (``ambulo.viewer.serve(env)``) watching world
``num_envs // 2`` and followed by a page: a separate process that connects to the viewer's
websocket as the browser does and reads everything it streams (the server serializes and sends
every frame; a real browser would add its own rendering, on the user's machine, not the
simulation's). The loops alternate, ``rounds`` times each, so a busy machine slows both alike;
the figure is the median round. ``ratio`` = with / without (1.0: free; 0.95: 5 % slower).
``stream_hz`` is the frames the viewer sent per second of the viewed loops: the page's frame rate
(at most one per env step, so a slow loop caps it). On a shared, overloaded machine wall-clock
ratios swing by tens of percent between identical rounds; ``cpu_s_per_env_step_ratio`` (CPU time
of every thread of the process per env-step, without / with) and ``stream_thread_cpu_share`` (the
streaming thread's part of it) say what the viewer costs independently of that.

Prints ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

import torch

from ambulo import envs

READER = """
import sys, time
import viser
from websockets.sync.client import connect
messages = 0
with connect(sys.argv[1], subprotocols=["viser-v" + viser.__version__], max_size=None) as ws:
    print("connected", flush=True)
    while True:
        try:
            ws.recv(timeout=float(sys.argv[2]))
        except Exception:  # the viewer closed (or went quiet)
            break
        messages += 1
print(messages, flush=True)
"""


def steps_per_s(env, actions: torch.Tensor, steps: int, cpu: list | None = None) -> float:
    """Env-steps per wall second; appends CPU seconds (every thread of this process) per env-step to ``cpu``."""
    start, cpu0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        env.step(actions)
    if cpu is not None:
        cpu.append((time.process_time() - cpu0) / (steps * env.num_envs))
    return steps * env.num_envs / (time.perf_counter() - start)


def watched_round(env, actions, steps: int, rate_hz: float, cpu: list) -> tuple[float, float, float, int]:
    """Env-steps/s with a viewer and a connected page: (steps/s, frames sent per s, the streaming
    thread's share of the process' CPU time, page messages)."""
    import ambulo.viewer

    viewer = ambulo.viewer.serve(env, port=8800, rate_hz=rate_hz, announce=False)
    reader = subprocess.Popen([sys.executable, "-c", READER, f"ws://127.0.0.1:{viewer.port}", "30"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert reader.stdout.readline().strip() == "connected", "the page process did not connect"
        viewer.controls.watch(env.num_envs // 2)
        frames0, stream_cpu0, start = viewer.frames_sent, viewer.stream_cpu_s, time.perf_counter()
        rate = steps_per_s(env, actions, steps, cpu)
        stream_hz = (viewer.frames_sent - frames0) / (time.perf_counter() - start)
        stream_share = (viewer.stream_cpu_s - stream_cpu0) / (cpu[-1] * steps * env.num_envs)
    finally:
        viewer.close()
    out, _ = reader.communicate(timeout=120)
    return rate, stream_hz, stream_share, int(out.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid-walk")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--steps", type=int, default=200, help="policy steps per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--rate-hz", type=float, default=30.0)
    args = parser.parse_args()

    env = envs.make(args.task, num_envs=args.num_envs, device=args.device, seed=0)
    actions = torch.zeros(env.num_envs, env.num_actions, device=env.device)
    steps_per_s(env, actions, 20)  # warm-up
    without, with_viewer, stream, shares, messages, cpu_without, cpu_with = [], [], [], [], [], [], []
    for _ in range(args.rounds):
        without.append(steps_per_s(env, actions, args.steps, cpu_without))
        rate, hz, share, n = watched_round(env, actions, args.steps, args.rate_hz, cpu_with)
        with_viewer.append(rate)
        stream.append(hz)
        shares.append(share)
        messages.append(n)
    a, b = statistics.median(without), statistics.median(with_viewer)
    cpu_a, cpu_b = statistics.median(cpu_without), statistics.median(cpu_with)
    print("RESULT " + json.dumps({
        "task": args.task, "num_envs": args.num_envs, "device": args.device, "steps_per_round": args.steps,
        "rounds": args.rounds, "env_steps_per_s_without": round(a), "env_steps_per_s_with_viewer": round(b),
        "ratio": round(b / a, 3), "stream_hz": round(statistics.median(stream), 1), "rate_cap_hz": args.rate_hz,
        "cpu_s_per_env_step_ratio": round(cpu_a / cpu_b, 3),
        "stream_thread_cpu_share": round(statistics.median(shares), 4),
        "page_messages_per_round": messages, "without_rounds": [round(x) for x in without],
        "with_rounds": [round(x) for x in with_viewer],
    }))


if __name__ == "__main__":
    main()
