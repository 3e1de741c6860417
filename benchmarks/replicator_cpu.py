"""Annotated synthetic-data throughput on CPU vs the raw render rate of the same scene.

    python benchmarks/replicator_cpu.py [--frames 300]

For 320x240 and 640x480: (1) raw render rate, the ceiling: one lit rgb pass per
frame of the randomized example scene, nothing read back but the pixels; (2)
annotated frames/s: randomize, render rgb + depth + instance ids, build masks,
COCO RLE and boxes, write PNG rgb, 16-bit depth, instance/semantic PNGs and the
frame record (what ``ambulo generate`` does). Shadows and MSAA off (the
defaults). Prints a table and one ``RESULT {json}`` line; "ratio" is annotated /
raw at 320x240. Target (issue #3): >= 150 annotated frames/s at 320x240 on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

from ambulo import replicator as rep
from ambulo.replicator.generate import FrameProducer, run_frames
from ambulo.replicator.writers import prepare_dirs


def raw_render_fps(producer: FrameProducer, frames: int) -> float:
    camera, renderer = producer.camera, producer.camera.renderer
    engine = producer.engine
    producer.randomize(seed=0, index=0)
    model, data = engine.get_model(0), engine.get_data(0)
    pos, rot = camera._pose_gl()
    clip = camera.cfg.clipping_range_m
    for _ in range(10):  # warm caches and the rasterizer's shader compile
        renderer.update(model, data, camera.cam_id, pos[0], rot[0], clip)
        renderer.render_rgb()
    start = time.perf_counter()
    for _ in range(frames):
        renderer.update(model, data, camera.cam_id, pos[0], rot[0], clip)
        renderer.render_rgb()
    return frames / (time.perf_counter() - start)


def annotated_fps(producer: FrameProducer, config, frames: int) -> float:
    with tempfile.TemporaryDirectory() as out:
        prepare_dirs(__import__("pathlib").Path(out), config.writer)
        run_frames(config, out, seed=1, frames=list(range(10)), producer=producer)  # warm-up
        start = time.perf_counter()
        run_frames(config, out, seed=1, frames=list(range(10, 10 + frames)), producer=producer)
        return frames / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300, help="frames per measurement (640x480 uses half)")
    args = parser.parse_args()
    results = {}
    renderer = ""
    for width, height in ((320, 240), (640, 480)):
        frames = args.frames if width == 320 else max(20, args.frames // 2)
        config = rep.example_config(width, height)
        producer = FrameProducer(config)
        try:
            raw = raw_render_fps(producer, frames)
            annotated = annotated_fps(producer, config, frames)
            renderer = producer.gl_renderer
        finally:
            producer.close()
        results[f"{width}x{height}"] = {"raw_render_fps": round(raw, 1), "annotated_fps": round(annotated, 1),
                                        "ratio": round(annotated / raw, 3)}
        print(f"{width}x{height}: raw render {raw:7.1f} frames/s | annotated+written {annotated:7.1f} frames/s "
              f"| ratio {annotated / raw:.2f}")
    low = results["320x240"]
    summary = {"benchmark": "replicator_cpu", "gl_renderer": renderer, "cpus": os.cpu_count(),
               "annotated_fps_320x240": low["annotated_fps"], "raw_render_fps_320x240": low["raw_render_fps"],
               "annotated_fps_640x480": results["640x480"]["annotated_fps"],
               "raw_render_fps_640x480": results["640x480"]["raw_render_fps"],
               "ratio": low["ratio"], "target_annotated_fps_320x240": 150,
               "meets_target": low["annotated_fps"] >= 150}
    print("RESULT " + json.dumps(summary, sort_keys=True))


if __name__ == "__main__":
    main()
