"""What the web viewer costs the training run it watches (issue 29: at most 5 % slower).

    python benchmarks/viewer_overhead.py [--task humanoid-walk] [--device cpu] [--num-envs 64]
                                         [--rounds 4] [--iterations-per-round 2] [--warmup 2]
    python benchmarks/viewer_overhead.py --device cuda --num-envs 4096 --rounds 5

Runs ``ambulo train TASK`` (``ambulo.rl.train``, what the command runs: PPO's collection and
update, metrics.csv, TensorBoard, the progress bar) once, and inside that one run alternates
rounds of ``--iterations-per-round`` iterations without a viewer (A) and with one (B), A/B/A/B...,
so the machine's load swings hit both alike. A B round is ``ambulo train --viewer web``: a viewer
(``ambulo.viewer.serve(env)``) watching world ``num_envs // 2`` of the batch, fed the iteration's
curves (``add_scalars``), followed by a page: a separate process connected to the viewer's
websocket as a browser is, reading everything it streams (the browser's own drawing happens on
the user's machine, not the simulation's). The viewer is opened and closed between iterations,
through ``train``'s ``watch`` hook and its per-iteration scalars; an iteration is timed from the
end of the previous one (after the switch) to its own end, so opening and closing cost nothing
here (they cost a command once). The first ``--warmup`` iterations (kernel compile, allocation)
are not counted.

- ``env_steps_per_s_without`` / ``_with_viewer``: the median round's env-steps per wall second;
  ``ratio`` = with / without (1.0: free; 0.95: 5 % slower; the ceiling is the run without viewer);
- ``stream_hz``: pose frames the viewer actually sent per wall second during B rounds, for the one
  selected world among ``num_envs`` (capped at ``--rate-hz`` and at one per policy step);
- ``cpu_s_per_env_step_ratio``: CPU time of every thread of the process per env-step, without /
  with (what the viewer takes from a busy machine, less sensitive to its load than wall time), and
  ``stream_thread_cpu_share``: the viewer's streaming thread's part of the B rounds' CPU time.

Prints ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import subprocess
import sys
import tempfile
import time

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


class Page:
    """A websocket client process reading all a viewer sends, as a browser tab would."""

    def __init__(self, port: int):
        self.process = subprocess.Popen([sys.executable, "-c", READER, f"ws://127.0.0.1:{port}", "60"],
                                        stdout=subprocess.PIPE, text=True)
        if self.process.stdout.readline().strip() != "connected":
            raise RuntimeError("the page process did not connect to the viewer")

    def messages(self) -> int:
        """Messages read, once the viewer has closed (the process then ends)."""
        out, _ = self.process.communicate(timeout=120)
        return int(out.split()[-1])


class Rounds:
    """``train``'s ``watch``: receives every iteration's scalars and switches the viewer on and off
    between rounds (A: none, B: viewer + page), timing each iteration under the state it ran in."""

    def __init__(self, warmup: int, per_round: int, steps_per_iteration: int, rate_hz: float):
        self.warmup, self.per_round, self.rate_hz = warmup, per_round, rate_hz
        self.steps_per_iteration = steps_per_iteration
        self.env = self.viewer = self.page = None
        self.wall_s = {"A": [], "B": []}  # per round: summed iteration seconds
        self.cpu_s = {"A": [], "B": []}
        self.stream_hz: list[float] = []
        self.stream_cpu_share: list[float] = []
        self.page_messages: list[int] = []
        self._iteration = 0
        self._round_wall = self._round_cpu = 0.0
        self._t, self._cpu = time.perf_counter(), time.process_time()

    def __call__(self, env):  # the watch hook: called once, with the training env
        self.env = env
        return self

    @property
    def state(self) -> str | None:
        """The state of the iteration under way: None in warm-up, else A or B by round."""
        k = self._iteration - self.warmup
        return None if k < 0 else "AB"[(k // self.per_round) % 2]

    def add_scalars(self, iteration: int, scalars: dict[str, float]) -> None:
        if "env steps/s" not in scalars:  # an evaluation's scalars, not an iteration's end
            return
        now, cpu = time.perf_counter(), time.process_time()
        state = self.state
        if self.viewer is not None:
            self.viewer.add_scalars(iteration, scalars)  # what `ambulo train --viewer web` does
        if state is not None:
            self._round_wall += now - self._t
            self._round_cpu += cpu - self._cpu
        self._iteration += 1
        if state is not None and self.state != state:  # the round ended
            self._end_round(state, now)
        if self.state == "B" and self.viewer is None:
            self._open()
        self._t, self._cpu = time.perf_counter(), time.process_time()

    def _open(self) -> None:
        import ambulo.viewer

        self.viewer = ambulo.viewer.serve(self.env, port=8800, rate_hz=self.rate_hz, announce=False)
        self.viewer.watch(self.env.num_envs // 2)
        self.page = Page(self.viewer.port)
        self._frames0, self._stream_cpu0, self._opened = (self.viewer.frames_sent, self.viewer.stream_cpu_s,
                                                          time.perf_counter())

    def _end_round(self, state: str, now: float) -> None:
        self.wall_s[state].append(self._round_wall)
        self.cpu_s[state].append(self._round_cpu)
        if state == "B":
            self.stream_hz.append((self.viewer.frames_sent - self._frames0) / (now - self._opened))
            self.stream_cpu_share.append((self.viewer.stream_cpu_s - self._stream_cpu0) / self._round_cpu)
            self.close()
        self._round_wall = self._round_cpu = 0.0

    def close(self) -> None:
        if self.viewer is not None:
            self.viewer.close()
            self.page_messages.append(self.page.messages())
            self.viewer = self.page = None

    def result(self) -> dict:
        steps = self.per_round * self.steps_per_iteration
        rate = {s: [steps / w for w in self.wall_s[s]] for s in "AB"}
        cpu = {s: statistics.median(c / steps for c in self.cpu_s[s]) for s in "AB"}
        a, b = statistics.median(rate["A"]), statistics.median(rate["B"])
        return {"env_steps_per_s_without": round(a), "env_steps_per_s_with_viewer": round(b),
                "ratio": round(b / a, 3), "stream_hz": round(statistics.median(self.stream_hz), 1),
                "cpu_s_per_env_step_ratio": round(cpu["A"] / cpu["B"], 3),
                "stream_thread_cpu_share": round(statistics.median(self.stream_cpu_share), 4),
                "without_rounds": [round(x) for x in rate["A"]], "with_rounds": [round(x) for x in rate["B"]],
                "stream_hz_rounds": [round(x, 1) for x in self.stream_hz], "page_messages_per_round": self.page_messages}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid-walk")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--num-envs", type=int, default=None, help="default: 64 on the CPU, 4096 on a GPU")
    parser.add_argument("--rounds", type=int, default=4, help="rounds of each kind (A and B)")
    parser.add_argument("--iterations-per-round", type=int, default=2)
    parser.add_argument("--warmup", type=int, default=2, help="first iterations not counted")
    parser.add_argument("--rate-hz", type=float, default=30.0)
    args = parser.parse_args()
    if min(args.rounds, args.iterations_per_round) < 1 or args.warmup < 0:
        parser.error("--rounds and --iterations-per-round must be >= 1, --warmup >= 0")
    num_envs = args.num_envs or (64 if args.device == "cpu" else 4096)

    from ambulo.rl import train
    from ambulo.rl.config import ppo_cfg

    ppo = ppo_cfg(args.task, num_envs=num_envs)
    rounds = Rounds(args.warmup, args.iterations_per_round, ppo.num_steps_per_env * num_envs, args.rate_hz)
    iterations = args.warmup + 2 * args.rounds * args.iterations_per_round
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as root, contextlib.ExitStack() as stack:
        stack.callback(rounds.close)
        train(args.task, num_envs=num_envs, max_iterations=iterations, device=args.device, log_root=root,
              watch=rounds)
    print("RESULT " + json.dumps({
        "task": args.task, "device": args.device, "num_envs": num_envs, "watched_world": num_envs // 2,
        "rounds": args.rounds, "iterations_per_round": args.iterations_per_round,
        "env_steps_per_iteration": rounds.steps_per_iteration, "rate_cap_hz": args.rate_hz, **rounds.result(),
        "wall_s": round(time.perf_counter() - started, 1),
    }))


if __name__ == "__main__":
    main()
