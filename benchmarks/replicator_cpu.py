"""Annotated synthetic-data frames/s on CPU vs the two-pass render floor, with the same process count.

    python benchmarks/replicator_cpu.py [--frames 600] [--workers 1 2] [--repeats 2] [--sizes 320x240 640x480]
                                        [--dir DIR]

For each image size and worker count P, in the same run:

- floor: P processes each render only what a frame can't do without: the scene
  loaded into the renderer, one lit rgb pass and one id pass read back as geom
  ids + depth, over and over (the randomized example scenes of frames 0-15 in
  turn, made and their kinematics computed once, outside the timing); frames/s
  summed over the processes. It is no slower than what ``generate`` renders:
  the same two passes of scenes made by the producer into its own buffers
  cost the same CPU (results/cpu-2026-11-28-replicator-producer.md).
- annotated: what ``ambulo generate --workers P`` does in steady state with the
  example config: randomize, render both passes, the instance map, 2D/3D
  boxes, COCO RLE, PNG rgb + 16-bit depth + instance PNGs (no semantic PNG: the
  default annotators, as Replicator's BasicWriter, ask for none) and the frame
  record (after the files: a line of the process's journal), written into ``--dir`` (default: the system's temporary
  folder).
  P = 1 runs in this process (llvmpipe's default threads), P > 1 on
  ``ProducerPool`` (spawned processes, llvmpipe inline).

Both also report CPU ms per frame (all threads of all producer processes),
which other load on the machine barely moves: 1000 * cores / (CPU ms per
frame) is the frames/s the cores would give if nothing else ran. Process
start-up (imports, scene, GL context; ~2 s a process) is left out of both,
and shown as ``end_to_end_fps_320x240``: the wall-clock rate of one whole
``generate`` call (start-up and the COCO merge included). Floor and annotated
runs alternate and the best of each is kept, which damps noise from other
load; the table shows every run's range. ``file_create_ms`` is the CPU cost of
creating one file in ``--dir`` (three a frame: the images; the record is a
line appended to a journal, ``replicator.records``): on an ext4 without journal it
grows with the files deleted there in the last ~50 min. Shadows and MSAA off
(the defaults). Ends with one line ``RESULT {json}``; "ratio" is annotated /
floor at 320x240 for the RESULT's worker count (the most measured);
"stage_cpu_ms_320x240" splits a frame's CPU by stage (``stage_cpu_ms``), and
"capture_split_ms_320x240" a capture into the floor's passes and the rest (``capture_split_ms``). Targets:
>= 150 annotated frames/s at 320x240 on 2 cores (issue 7, item 8; ``meets_target``)
and annotated >= 0.5 of the floor (issue 22, item 6; ``meets_ratio``).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from ambulo import replicator as rep
from ambulo.replicator.io import PNG_DEFLATE
from ambulo.replicator.processes import LP_THREADS_ENV, ProducerPool, usable_cpus
from ambulo.replicator.producer import FrameProducer, run_frames
from ambulo.replicator.writers import FrameWriter, prepare_dirs
from ambulo.utils.rotations import quat_to_mat

try:
    from ambulo.replicator.producer import _heap_frozen  # as run_frames does
except ImportError:  # a tree from before it (PYTHONPATH=<old tree>/src, for before/after runs)
    _heap_frozen = contextlib.nullcontext

TARGET_FPS = 150
TARGET_RATIO = 0.5
SEED = 1


FLOOR_SCENES = 16


def render_floor(producer: FrameProducer, frames: int) -> tuple[float, float]:
    """(wall s, CPU s) for ``frames`` x (scene update + rgb pass + id/depth pass, read back), after a warm-up.

    Rendering only, the fastest a frame can be made at this size with these passes: the
    randomized worlds of frames 0-15 (models and states with kinematics computed) are made
    once, outside the timing; each timed frame loads the next of them into the renderer
    (``mjv_updateScene``), draws the lit pass and reads it back, and draws the id pass and
    reads back geom ids and depth.
    """
    camera, engine = producer.camera, producer.engine
    scenes = []
    for index in range(FLOOR_SCENES):
        producer.randomize(SEED, index)
        pose = camera.capture(0, annotators=("rgb",))["camera"]
        scenes.append((copy.copy(engine.get_model(0)), copy.copy(engine.get_data(0)), pose["pos_w"],
                       quat_to_mat(pose["quat_w_opengl"])))
    renderer, cam_id, clip = camera.renderer, camera.cam_id, camera.cfg.clipping_range_m

    def two_passes(k: int):
        model, data, pos, rot_gl = scenes[k % FLOOR_SCENES]
        renderer.update(model, data, cam_id, pos, rot_gl, clip)
        renderer.render_rgb()  # lit pass, rgb read back
        renderer.render_ids(want_depth=True)  # id pass, ids + depth read back

    for k in range(FLOOR_SCENES):  # warm caches and the rasterizer's shader compile
        two_passes(k)
    start, cpu = time.perf_counter(), time.process_time()
    for k in range(frames):
        two_passes(k)
    return time.perf_counter() - start, time.process_time() - cpu


STAGES = ("randomize", "capture", "write_files", "records")


def stage_cpu_ms(producer: FrameProducer, out: str, frames: int) -> dict[str, float]:
    """CPU ms a frame of each stage of ``run_frames``, called in line on one thread (and llvmpipe's).

    randomize: ``FrameProducer.randomize``; capture: both passes, the camera's bookkeeping and the
    annotators (``Camera.capture``); write_files: PNG/COCO/KITTI encoding and the atomic data files
    (``write_frame_files``); records: the batch's flush (``syncfs``), its frame records appended to the
    journal and the journal's ``fsync``, every 8 frames. Fresh frame indices, into a folder of this process; the heap frozen as ``run_frames``
    does. The stages add up to a little more than an annotated frame's CPU: in ``run_frames`` the
    id pass rasterizes while the next frame is randomized.
    """
    folder = Path(out) / f"stages_{os.getpid()}"
    prepare_dirs(folder, producer.config.writer)
    writer = FrameWriter(folder, producer.config.writer, batch=1 << 30)  # flushed here, every 8 frames
    totals = dict.fromkeys(STAGES, 0.0)
    clock = time.process_time
    with _heap_frozen():
        for k, index in enumerate(range(10_000_000, 10_000_000 + frames)):
            start = clock()
            log = producer.randomize(SEED, index)
            randomized = clock()
            capture = producer.capture()
            captured = clock()
            writer.write(index, capture, producer.table, log)
            written = clock()
            if k % 8 == 7 or k == frames - 1:
                writer.flush()
            totals["randomize"] += randomized - start
            totals["capture"] += captured - randomized
            totals["write_files"] += written - captured
            totals["records"] += clock() - written
    return {stage: 1000 * seconds / frames for stage, seconds in totals.items()}


def capture_split_ms(producer: FrameProducer, frames: int) -> dict[str, float]:
    """What a capture costs beyond the floor's two passes, CPU ms a frame (one thread, in line).

    Each frame is randomized and captured as in ``run_frames`` (``capture_cold``); then, on the same
    state, the floor's two passes run (``passes``: scene update, lit pass, id pass, read back) and
    the capture once more (``capture_warm``). ``extra_work`` = capture_warm - passes is what a
    capture does besides rendering (model and state copies, the camera's pose, the instance and
    semantic maps, the annotators); ``cold`` = capture_cold - capture_warm is what randomizing
    before it costs the render in cache misses.
    """
    camera, renderer = producer.camera, producer.camera.renderer
    clip = camera.cfg.clipping_range_m
    clock = time.process_time
    cold = warm = passes = 0.0
    for index in range(20_000_000, 20_000_000 + frames):
        producer.randomize(SEED, index)
        start = clock()
        pose = producer.capture()["camera"]
        cold += clock() - start
        model, data = camera._model_buf, camera._data_buf  # the state the capture rendered
        rot_gl = quat_to_mat(pose["quat_w_opengl"])
        start = clock()
        renderer.update(model, data, camera.cam_id, pose["pos_w"], rot_gl, clip)
        renderer.render_rgb()
        renderer.render_ids(want_depth=True)
        passes += clock() - start
        start = clock()
        producer.capture()
        warm += clock() - start
    ms = {"capture_cold": cold, "capture_warm": warm, "passes": passes}
    ms = {key: 1000 * value / frames for key, value in ms.items()}
    ms["extra_work"] = ms["capture_warm"] - ms["passes"]
    ms["cold"] = ms["capture_cold"] - ms["capture_warm"]
    return ms


def _warm(producer: FrameProducer) -> tuple[float, float]:
    return render_floor(producer, 1)


def _cpu_seconds(producer: FrameProducer) -> float:
    return time.process_time()  # every thread of the worker: main, writer, llvmpipe's


class InProcess:
    """P = 1: the producer and writer thread of ``generate(workers=1)``, in this process."""

    workers = 1

    def __init__(self, config, out: Path):
        self.config, self.out = config, out
        self.producer = FrameProducer(config)

    def floor(self, frames: int) -> tuple[float, float]:
        """(frames/s, CPU ms a frame)"""
        wall, cpu = render_floor(self.producer, frames)
        return frames / wall, 1000 * cpu / frames

    def annotated(self, frames: list[int]) -> tuple[float, float]:
        start, cpu = time.perf_counter(), time.process_time()
        run_frames(self.config, self.out, SEED, frames, producer=self.producer)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        return len(frames) / wall, 1000 * cpu / len(frames)

    def stages(self, out: Path, frames: int) -> dict[str, float]:
        return stage_cpu_ms(self.producer, str(out), frames)

    def capture_split(self, frames: int) -> dict[str, float]:
        return capture_split_ms(self.producer, frames)

    def renderer(self) -> str:
        return self.producer.gl_renderer

    def close(self) -> None:
        self.producer.close()


class Pool:
    """P > 1: the spawned processes of ``generate(workers=P)``, started and warmed before timing."""

    def __init__(self, config, out: Path, workers: int):
        self.workers = workers
        self.pool = ProducerPool(config, out, SEED, workers)
        self.pool.run_on_each(_warm)  # every process built its scene and GL context
        self._renderer = ""

    def floor(self, frames: int) -> tuple[float, float]:
        # started together by a barrier; the slowest process bounds the wall time
        runs = self.pool.run_on_each(render_floor, frames)
        total = self.workers * frames
        return total / max(wall for wall, _ in runs), 1000 * sum(cpu for _, cpu in runs) / total

    def annotated(self, frames: list[int]) -> tuple[float, float]:
        cpu = sum(self.pool.run_on_each(_cpu_seconds))
        start = time.perf_counter()
        self._renderer = self.pool.run(frames)
        wall = time.perf_counter() - start
        cpu = sum(self.pool.run_on_each(_cpu_seconds)) - cpu
        return len(frames) / wall, 1000 * cpu / len(frames)

    def stages(self, out: Path, frames: int) -> dict[str, float]:
        """Each process's stages, averaged over the processes (they ran at the same time)."""
        runs = self.pool.run_on_each(stage_cpu_ms, str(out), frames)
        return {stage: sum(run[stage] for run in runs) / len(runs) for stage in STAGES}

    def capture_split(self, frames: int) -> dict[str, float]:
        runs = self.pool.run_on_each(capture_split_ms, frames)
        return {key: sum(run[key] for run in runs) / len(runs) for key in runs[0]}

    def renderer(self) -> str:
        return self._renderer

    def close(self) -> None:
        self.pool.close()


SLOW_CREATE_MS = 0.2
"""A file create above this (CPU ms) is the file system's transient, not ambulo's cost: said in a note."""


def file_create_ms(folder: Path, count: int = 200) -> float:
    """CPU ms to create one empty file in ``folder`` (the files stay: deleting them would slow later creates)."""
    folder.mkdir(parents=True, exist_ok=True)
    cpu = time.process_time()
    for i in range(count):
        os.close(os.open(folder / f"{i:06d}", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    return 1000 * (time.process_time() - cpu) / count


def measure(out: Path, width: int, height: int, workers: int, frames: int, repeats: int) -> dict:
    config = rep.example_config(width, height)
    prepare_dirs(out, config.writer)
    side = InProcess(config, out) if workers == 1 else Pool(config, out, workers)
    try:
        side.annotated(list(range(8 * workers)))  # warm the writer path
        floor, annotated = [], []
        first = 8 * workers
        for _ in range(repeats):
            floor.append(side.floor(frames // workers))
            # fresh frame indices each time: every frame is randomized and written anew
            annotated.append(side.annotated(list(range(first, first + frames))))
            first += frames
        renderer = side.renderer()
        stages = side.stages(out, max(48, frames // (2 * workers)))
        split = side.capture_split(max(48, frames // (4 * workers)))
    finally:
        side.close()
    return {"floor_fps": max(fps for fps, _ in floor), "floor_cpu_ms": min(cpu for _, cpu in floor),
            "annotated_fps": max(fps for fps, _ in annotated), "annotated_cpu_ms": min(cpu for _, cpu in annotated),
            "floor_runs": [fps for fps, _ in floor], "annotated_runs": [fps for fps, _ in annotated],
            "gl_renderer": renderer, "stage_cpu_ms": stages, "capture_split_ms": split}


def end_to_end_fps(out: Path, width: int, height: int, workers: int, frames: int) -> float:
    """Frames/s of one whole ``generate`` call into an empty folder, start-up and COCO merge included."""
    config = rep.example_config(width, height)
    start = time.perf_counter()
    rep.generate(config, out, num_frames=frames, seed=SEED, workers=workers, show_progress=False,
                 backend="processes")
    return frames / (time.perf_counter() - start)


def _span(values: list[float]) -> str:
    return f"{min(values):6.1f}-{max(values):6.1f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=600, help="frames per timed run (640x480 uses half)")
    parser.add_argument("--workers", type=int, nargs="+", default=sorted({1, usable_cpus()}),
                        help="process counts to measure (default: 1 and one per usable CPU)")
    parser.add_argument("--repeats", type=int, default=2, help="floor/annotated runs per case; the best is kept")
    parser.add_argument("--sizes", nargs="+", default=["320x240", "640x480"], help="WxH; 320x240 is required")
    parser.add_argument("--dir", type=Path, default=None,
                        help="folder for the frames (a temporary folder is made in it; default: the system's)")
    args = parser.parse_args()
    sizes = [tuple(int(v) for v in size.split("x")) for size in args.sizes]
    if (320, 240) not in sizes:
        parser.error("--sizes must include 320x240 (the target's size)")
    results = {}
    print(f"{'size':>8} {'P':>2} | {'floor fps (runs)':>22} {'CPU ms':>6} | {'annotated fps (runs)':>22} {'CPU ms':>6} "
          "| ratio")
    # Everything written stays until the end: deleting thousands of files makes ext4 slow to create
    # new ones for a while (it skips recently freed inodes), which would tax the cases after it.
    if args.dir is not None:  # a folder that does not exist yet is made, as --out folders are
        args.dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        create_ms = file_create_ms(Path(tmp) / "create_probe")
        for width, height in sizes:
            frames = args.frames if width == 320 else max(40, args.frames // 2)
            for workers in args.workers:
                r = measure(Path(tmp) / f"{width}x{height}_p{workers}", width, height, workers, frames,
                            args.repeats)
                results[(width, workers)] = r
                print(f"{width}x{height:<4} {workers:>2} | {r['floor_fps']:6.1f} ({_span(r['floor_runs'])}) "
                      f"{r['floor_cpu_ms']:6.2f} | {r['annotated_fps']:6.1f} ({_span(r['annotated_runs'])}) "
                      f"{r['annotated_cpu_ms']:6.2f} | {r['annotated_fps'] / r['floor_fps']:.2f}", flush=True)
                print("    CPU ms a frame by stage (one thread, in line): " + ", ".join(
                    f"{stage} {ms:.2f}" for stage, ms in r["stage_cpu_ms"].items()), flush=True)
                print("    a capture beyond the two passes: " + ", ".join(
                    f"{key} {ms:.2f}" for key, ms in r["capture_split_ms"].items()), flush=True)
        workers = max(args.workers)
        e2e = end_to_end_fps(Path(tmp) / "end_to_end", 320, 240, workers, args.frames)
    print(f"ambulo generate --workers {workers} --frames {args.frames} at 320x240, end to end: {e2e:.1f} frames/s; "
          f"creating a file in {args.dir or tempfile.gettempdir()}: {create_ms:.3f} ms CPU")
    if create_ms > SLOW_CREATE_MS:  # three files a frame: the annotated rate pays ~3x this, the floor nothing
        print(f"note: creating a file costs {create_ms:.2f} ms of CPU here now (usually < {SLOW_CREATE_MS} ms): an ext4 "
              "without journal scans past inodes freed in the last minutes (this benchmark's last run deletes ~5,000); "
              "rerun after ~6 minutes for the file system's steady state", file=sys.stderr)
    low = results[(320, workers)]
    summary = {
        "benchmark": "replicator_cpu", "workers": workers, "cpus": usable_cpus(),
        "gl_renderer": low["gl_renderer"], "png_deflate": PNG_DEFLATE,
        "lp_num_threads": os.environ.get(LP_THREADS_ENV, "0 in workers" if workers > 1 else "llvmpipe default"),
        "annotated_fps_320x240": round(low["annotated_fps"], 1),
        "floor_fps_320x240": round(low["floor_fps"], 1),
        "ratio": round(low["annotated_fps"] / low["floor_fps"], 3),
        "end_to_end_fps_320x240": round(e2e, 1),
        "cpu_ms_per_frame_320x240": {"annotated": round(low["annotated_cpu_ms"], 2),
                                     "floor": round(low["floor_cpu_ms"], 2)},
        "file_create_ms": round(create_ms, 3),
        "stage_cpu_ms_320x240": {stage: round(ms, 2) for stage, ms in low["stage_cpu_ms"].items()},
        "capture_split_ms_320x240": {key: round(ms, 2) for key, ms in low["capture_split_ms"].items()},
        "annotated_fps_320x240_by_workers": {p: round(results[(320, p)]["annotated_fps"], 1) for p in args.workers},
        "target_annotated_fps_320x240": TARGET_FPS,
        "meets_target": low["annotated_fps"] >= TARGET_FPS,
        "target_ratio": TARGET_RATIO, "meets_ratio": low["annotated_fps"] / low["floor_fps"] >= TARGET_RATIO,
    }
    for width, height in sizes:
        if width != 320:
            summary[f"annotated_fps_{width}x{height}"] = round(results[(width, workers)]["annotated_fps"], 1)
            summary[f"floor_fps_{width}x{height}"] = round(results[(width, workers)]["floor_fps"], 1)
    print("RESULT " + json.dumps(summary, sort_keys=True))


if __name__ == "__main__":
    main()
