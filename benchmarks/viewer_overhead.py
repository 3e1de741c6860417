"""What the web viewer costs the training run it watches (issue 29: at most 5 % slower), and the
frame rate its page gets.

    python benchmarks/viewer_overhead.py [--task humanoid-walk] [--device cpu] [--num-envs 64]
                                         [--rounds 4] [--round-s 5] [--warmup 2] [--in-process]
    python benchmarks/viewer_overhead.py --device cuda --num-envs 4096 --rounds 4 --round-s 6

Runs ``ambulo train TASK`` (``ambulo.rl.train``, what the command runs: PPO's collection and
update, metrics.csv, TensorBoard, the progress bar) once, and inside that one run alternates
rounds without a viewer (A) and with one (B), A/B/A/B..., so the machine's load swings hit both
alike. A round is whole iterations until it has lasted ``--round-s`` wall seconds (steady state:
the viewer's start-up, a page's first scene, weigh little). A B round is ``ambulo train --viewer
web``: a viewer (``ambulo.viewer.serve(env)``, its server in its own process unless
``--in-process``) watching world ``num_envs // 2``, fed the iteration's curves (``add_scalars``),
followed by a page: a separate process connected to the viewer's websocket as a browser is,
decoding everything it gets and timing each pose update of the drawn world (the browser's own
drawing happens on the user's machine). The viewer is opened and closed between iterations,
through ``train``'s ``watch`` hook; an iteration is timed from the end of the previous one (after
the switch) to its own end, so opening and closing are not counted (they cost a command once).
The first ``--warmup`` iterations (kernel compile, allocation) are not counted.

- ``env_steps_per_s_without`` / ``_with_viewer``: env-steps per wall second over all rounds of
  each kind (median round in ``*_rounds``); ``ratio`` = with / without (the ceiling is the run
  without viewer; 0.95: 5 % slower);
- ``train_thread_cpu_ratio``: CPU time of the training thread per env step, without / with (what
  the viewer adds to the thread that steps: hooks, copies, and GIL waits that spin; less sensitive
  to the machine's load than wall time); ``process_cpu_ratio`` the same for every thread of the
  training process; ``pump_cpu_share``: the viewer's thread in the training process, and
  ``server_cpu_share``: its server process, as parts of the training process's CPU in B rounds;
- ``page_hz``: pose updates of the watched world the page received per wall second of B rounds,
  timed at the page; ``page_hz_while_stepping``: the same over the stretches the simulation
  stepped (gaps under ``STEPPING_GAP_PERIODS`` periods of the cap; PPO's update phase steps
  nothing, so ``page_hz`` is at most the cap times the collection's share of an iteration); ``stream_hz``:
  frames the viewer sent per second, counted at the viewer.

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
import threading
import time

STEPPING_GAP_PERIODS = 2.5
"""Two page updates further apart than this many periods of the cap bracket a stretch without
simulation steps (PPO's update); meaningful when the simulation steps faster than the cap."""

READER = """
import json, sys, time
import msgspec, viser, zstandard
from websockets.sync.client import connect
updates, decompress = [], zstandard.ZstdDecompressor()
with connect(sys.argv[1], subprotocols=["viser-v" + viser.__version__], max_size=None) as ws:
    print("connected", flush=True)
    while True:
        try:
            raw = ws.recv(timeout=float(sys.argv[2]))
        except Exception:  # the viewer closed (or went quiet)
            break
        now = time.perf_counter()
        size, packed = int.from_bytes(raw[:8], "little"), int.from_bytes(raw[8:16], "little")
        inner = msgspec.msgpack.decode(decompress.decompress(raw[16:16 + packed], max_output_size=size))
        counts = {}
        for m in inner["messages"]:  # a frame poses each moving geom's instances once (viewer.scene)
            if (m.get("type") == "SceneNodeUpdateMessage" and m.get("name", "").startswith("/worlds/g")
                    and "batched_positions" in m.get("updates", {})):
                counts[m["name"]] = counts.get(m["name"], 0) + 1
        updates += [now] * max(counts.values(), default=0)
print(json.dumps(updates), flush=True)
"""


class Page:
    """A websocket client process reading all a viewer sends, as a browser tab would."""

    def __init__(self, port: int):
        self.process = subprocess.Popen([sys.executable, "-c", READER, f"ws://127.0.0.1:{port}", "60"],
                                        stdout=subprocess.PIPE, text=True)
        if self.process.stdout.readline().strip() != "connected":
            raise RuntimeError("the page process did not connect to the viewer")

    def updates(self) -> list[float]:
        """perf_counter times of the pose updates it got, once the viewer has closed (it then ends)."""
        out, _ = self.process.communicate(timeout=120)
        return json.loads(out.strip().splitlines()[-1])


def page_rates(updates: list[float], wall_s: float, rate_hz: float) -> tuple[float, float]:
    """(updates per wall second, updates per second over the stretches the simulation stepped)."""
    gaps = [b - a for a, b in zip(updates, updates[1:])]
    stepping = [g for g in gaps if g < STEPPING_GAP_PERIODS / rate_hz]
    return len(updates) / wall_s, (len(stepping) / sum(stepping) if sum(stepping) > 0 else 0.0)


class Rounds:
    """``train``'s ``watch``: receives every iteration's scalars and switches the viewer on and off
    between rounds (A: none, B: viewer + page), timing each iteration under the state it ran in."""

    def __init__(self, warmup: int, round_s: float, rounds: int, steps_per_iteration: int, rate_hz: float,
                 in_process: bool):
        self.warmup, self.round_s, self.rounds, self.rate_hz = warmup, round_s, rounds, rate_hz
        self.steps_per_iteration, self.in_process = steps_per_iteration, in_process
        self.env = self.viewer = self.page = None
        self.done = threading.Event()
        self.rows = {"A": [], "B": []}  # per round: (env steps, wall s, train thread cpu s, process cpu s)
        self.viewer_rows: list[dict] = []
        self._iteration, self._state, self._finished = 0, None, 0
        self._round = [0, 0.0, 0.0, 0.0]
        self._mark()

    def __call__(self, env):  # the watch hook: called once, with the training env
        self.env = env
        return self

    def _mark(self) -> None:
        self._t, self._thread_cpu, self._cpu = time.perf_counter(), time.thread_time(), time.process_time()

    def add_scalars(self, iteration: int, scalars: dict[str, float]) -> None:
        if "env steps/s" not in scalars:  # an evaluation's scalars, not an iteration's end
            return
        now, thread_cpu, cpu = time.perf_counter(), time.thread_time(), time.process_time()
        if self.viewer is not None:
            self.viewer.add_scalars(iteration, scalars)  # what `ambulo train --viewer web` does
        self._iteration += 1
        if self._state is not None:
            r = self._round
            r[0] += self.steps_per_iteration
            r[1] += now - self._t
            r[2] += thread_cpu - self._thread_cpu
            r[3] += cpu - self._cpu
            if r[1] >= self.round_s:
                self._end_round(now)
        if self._iteration >= self.warmup and self._state is None and not self.done.is_set():
            self._state = "A"
        if self._state == "B" and self.viewer is None:
            self._open()
        if self.done.is_set():
            raise _Done
        self._mark()

    def _open(self) -> None:
        import ambulo.viewer

        self.viewer = ambulo.viewer.serve(self.env, port=8800, rate_hz=self.rate_hz, announce=False,
                                          process=not self.in_process)
        self.viewer.watch(self.env.num_envs // 2)
        self.page = Page(self.viewer.port)
        self._opened = time.perf_counter()
        self._viewer0 = (self.viewer.frames_sent, self.viewer.stream_cpu_s, self._server_cpu())

    def _server_cpu(self) -> float:
        return 0.0 if self.viewer.link is None else self.viewer.link.server_cpu_s()

    def _end_round(self, now: float) -> None:
        state = self._state
        self.rows[state].append(tuple(self._round))
        if state == "B":
            frames0, pump0, server0 = self._viewer0
            wall_s = now - self._opened
            row = {"stream_hz": (self.viewer.frames_sent - frames0) / wall_s,
                   "pump_cpu_share": (self.viewer.stream_cpu_s - pump0) / self._round[3],
                   "server_cpu_share": (self._server_cpu() - server0) / self._round[3]}
            self.close()
            row["page_hz"], row["page_hz_while_stepping"] = page_rates(
                [t for t in self._updates if t >= self._opened], wall_s, self.rate_hz)
            self.viewer_rows.append(row)
            self._finished += 1
        self._round = [0, 0.0, 0.0, 0.0]
        self._state = "B" if state == "A" else "A"
        if self._finished >= self.rounds:
            self.done.set()

    def close(self) -> None:
        self._updates = []
        if self.viewer is not None:
            self.viewer.close()
            self._updates = self.page.updates()
            self.viewer = self.page = None

    def result(self) -> dict:
        a, b = (self.rows[s][:len(self.rows["B"])] for s in "AB")  # as many A rounds as B rounds

        def per_s(rows, k):  # env steps per unit of column k over all rounds
            return sum(r[0] for r in rows) / sum(r[k] for r in rows)

        def median(key):
            return round(statistics.median(r[key] for r in self.viewer_rows), 4)

        return {"env_steps_per_s_without": round(per_s(a, 1)), "env_steps_per_s_with_viewer": round(per_s(b, 1)),
                "ratio": round(per_s(b, 1) / per_s(a, 1), 3),
                "train_thread_cpu_ratio": round(per_s(b, 2) / per_s(a, 2), 3),
                "process_cpu_ratio": round(per_s(b, 3) / per_s(a, 3), 3),
                "pump_cpu_share": median("pump_cpu_share"), "server_cpu_share": median("server_cpu_share"),
                "page_hz": round(statistics.median(r["page_hz"] for r in self.viewer_rows), 1),
                "page_hz_while_stepping": round(statistics.median(r["page_hz_while_stepping"]
                                                                  for r in self.viewer_rows), 1),
                "stream_hz": round(statistics.median(r["stream_hz"] for r in self.viewer_rows), 1),
                "without_rounds": [round(r[0] / r[1]) for r in a], "with_rounds": [round(r[0] / r[1]) for r in b],
                "round_wall_s": [round(r[1], 1) for r in a + b],
                "page_hz_rounds": [round(r["page_hz"], 1) for r in self.viewer_rows],
                "page_hz_while_stepping_rounds": [round(r["page_hz_while_stepping"], 1) for r in self.viewer_rows]}


class _Done(Exception):
    """Raised from the watch hook once every round ran: ends training early, as Ctrl-C would."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid-walk")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--num-envs", type=int, default=None, help="default: 64 on the CPU, 4096 on a GPU")
    parser.add_argument("--rounds", type=int, default=4, help="rounds of each kind (A and B)")
    parser.add_argument("--round-s", type=float, default=5.0, help="wall seconds of whole iterations per round")
    parser.add_argument("--warmup", type=int, default=2, help="first iterations not counted")
    parser.add_argument("--rate-hz", type=float, default=30.0)
    parser.add_argument("--in-process", action="store_true", help="the viewer's server on threads of the run")
    args = parser.parse_args()
    if args.rounds < 1 or args.round_s <= 0 or args.warmup < 0:
        parser.error("--rounds must be >= 1, --round-s > 0, --warmup >= 0")
    num_envs = args.num_envs or (64 if args.device == "cpu" else 4096)

    from ambulo.rl import train
    from ambulo.rl.config import ppo_cfg

    ppo = ppo_cfg(args.task, num_envs=num_envs)
    rounds = Rounds(args.warmup, args.round_s, args.rounds, ppo.num_steps_per_env * num_envs, args.rate_hz,
                    args.in_process)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as root, contextlib.ExitStack() as stack:
        stack.callback(rounds.close)
        with contextlib.suppress(_Done):
            train(args.task, num_envs=num_envs, max_iterations=10**6, device=args.device, log_root=root,
                  watch=rounds)
    print("RESULT " + json.dumps({
        "task": args.task, "device": args.device, "num_envs": num_envs, "watched_world": num_envs // 2,
        "server": "in process" if args.in_process else "own process", "rounds": args.rounds,
        "round_s": args.round_s, "env_steps_per_iteration": rounds.steps_per_iteration,
        "rate_cap_hz": args.rate_hz, **rounds.result(), "wall_s": round(time.perf_counter() - started, 1),
    }))


if __name__ == "__main__":
    main()
