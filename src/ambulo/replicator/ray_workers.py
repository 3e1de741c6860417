"""Shards of a dataset on Ray actors: each actor builds the scene once and renders chunks of frames.

For several machines: on a cluster (``RAY_ADDRESS`` or an earlier ``ray.init``)
the output folder must be shared. On one machine, plain processes
(``processes.py``) are faster: a local Ray is started here only when asked.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .processes import prepare_producer_process
from .producer import FrameProducer, run_frames

CHUNK_FRAMES = 8  # small enough for a live progress bar, large enough to amortize task overhead


def run_on_ray(config, out: Path, seed: int, frames: list[int], workers: int, progress) -> str:
    try:
        import ray
    except ImportError:
        raise RuntimeError("--workers > 1 needs Ray: pip install 'ambulo[data]' (or pip install ray)") from None
    started_here = False
    if not ray.is_initialized():
        # workers import ambulo from wherever this process does
        path = os.pathsep.join(p for p in sys.path if p)
        env = {"PYTHONPATH": path, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "")}
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                 runtime_env={"env_vars": env}, configure_logging=False)
        started_here = True
    try:
        shard = ray.remote(num_cpus=1)(_Shard)
        actors = [shard.remote(config, str(out), seed) for _ in range(workers)]
        chunks = [frames[i:i + CHUNK_FRAMES] for i in range(0, len(frames), CHUNK_FRAMES)]
        running = {}
        renderer = ""
        free = list(actors)
        while chunks or running:
            while chunks and free:
                actor = free.pop()
                chunk = chunks.pop(0)
                running[actor.run.remote(chunk)] = (actor, len(chunk))
            (ref,), _ = ray.wait(list(running), num_returns=1)
            actor, count = running.pop(ref)
            renderer = ray.get(ref)
            progress(count)
            free.append(actor)
        return renderer
    finally:
        if started_here:
            ray.shutdown()


class _Shard:
    def __init__(self, config, out: str, seed: int):
        prepare_producer_process()  # one CPU per actor: llvmpipe renders inline (before the GL context)

        self.producer = FrameProducer(config)
        self.out = Path(out)
        self.seed = seed
        self.config = config

    def run(self, frames: list[int]) -> str:
        return run_frames(self.config, self.out, self.seed, frames, producer=self.producer)
