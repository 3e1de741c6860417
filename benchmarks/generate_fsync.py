"""What flushing dataset files to disk costs `ambulo generate`: frames/s with and without fsync.

    python benchmarks/generate_fsync.py [--frames 300] [--workers 2] [--size 320x240] [--repeats 2] [--dir DIR]

Both runs write the same seeded example dataset with the same worker count into fresh
folders under ``--dir`` (default: the system's temporary folder); only
``WriterCfg.fsync`` differs. With it, every data file and its folder reach the disk before
the frame record that points at them. The ceiling is the same run without fsync. Each run is
one whole ``generate`` call, process start-up (~2 s a worker) included. Runs
alternate and the best of each is kept, to damp other load. Ends with one line
``RESULT {json}``: "ratio" is frames/s with fsync over frames/s without.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import tempfile
import time
from pathlib import Path

from ambulo import replicator as rep


def frames_per_s(config, folder: Path, frames: int, workers: int) -> float:
    shutil.rmtree(folder, ignore_errors=True)
    start = time.perf_counter()
    rep.generate(config, folder, num_frames=frames, seed=0, workers=workers, show_progress=False)
    return frames / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()))
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    base = rep.example_config(width, height)
    configs = {flag: dataclasses.replace(base, writer=dataclasses.replace(base.writer, fsync=flag))
               for flag in (True, False)}
    root = Path(tempfile.mkdtemp(prefix="ambulo-fsync-bench-", dir=args.dir))
    best = {True: 0.0, False: 0.0}
    try:
        for _ in range(args.repeats):
            for flag, config in configs.items():
                fps = frames_per_s(config, root / f"fsync-{flag}", args.frames, args.workers)
                best[flag] = max(best[flag], fps)
                print(f"fsync={flag}: {fps:.1f} frames/s")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    result = {"benchmark": "generate_fsync", "frames": args.frames, "workers": args.workers, "size": args.size,
              "fps_fsync": round(best[True], 1), "fps_no_fsync": round(best[False], 1),
              "ratio": round(best[True] / best[False], 3)}
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
