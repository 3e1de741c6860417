"""Detector speed: exported-model inference at 320x240 on CPU (batch 1), and optionally training
throughput and accuracy on a dataset (CUDA).

    python benchmarks/detector.py [--threads 2] [--model centernet-small]
    python benchmarks/detector.py --train data/ --device cuda --epochs 30 [--batch-size 64]
    python benchmarks/detector.py --checkpoint runs/det/checkpoint.pt --gpu-size 640 480

Inference: the issue's target is >= 10 frames/s at 320x240 on 2 CPU cores, the exported model at
batch 1. ONNX Runtime runs the exported graph (network + NMS-free decoding); the ceiling is the
fastest of ONNX Runtime and torch (eager, no grad) on the same graph; ``ratio`` = ours / ceiling.
Speed does not depend on the weights, so an untrained model is timed unless ``--checkpoint``.

GPU (``--gpu-size W H``): the issue's >= 60 frames/s at 640x480 at batch 1, timed from a uint8 frame
in host memory to detections in host memory (``gpu_inference``).

Training (``--train``): ``ambulo.detection.train`` on the dataset, then ``steps_per_s`` against the
ceiling of the same model's forward + backward + step (masks included) on a batch already on the
device (no reading, no augmentation): ``train_ratio``. The model has the instance-mask branch
(``ModelCfg.mask_prototypes``) unless ``--mask-prototypes 0``. Prints the held-out mAP/mAP50 and one ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from ambulo.detection import ModelCfg, build_model, load_trained
from ambulo.detection.export import export_model
from ambulo.detection.loss import centernet_loss, mask_cells
from ambulo.detection.model import INPUT_CHANNELS, ExportedDetector, depth_channel, height_channel

CANVAS_320x240 = (256, 320)
"""240 rows rounded up to the model's stride of 32."""


def time_calls(fn, repeats: int, warmup: int = 3) -> float:
    """Median seconds per call."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def inference(model, threads: int, repeats: int) -> dict:
    import onnxruntime as ort

    torch.set_num_threads(threads)
    image = np.random.default_rng(0).random((1, INPUT_CHANNELS[model.cfg.inputs], *CANVAS_320x240), dtype=np.float32)
    with tempfile.TemporaryDirectory() as tmp:
        path = export_model(model, CANVAS_320x240, Path(tmp) / "det.onnx")
        options = ort.SessionOptions()
        options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
        session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        ort_s = time_calls(lambda: session.run(None, {"images": image}), repeats)
    graph = ExportedDetector(model.eval())
    x = torch.from_numpy(image)
    with torch.no_grad():
        torch_s = time_calls(lambda: graph(x), repeats)
    fastest = min(ort_s, torch_s)
    return {"onnxruntime_fps": round(1 / ort_s, 2), "torch_eager_fps": round(1 / torch_s, 2),
            "ratio": round(fastest / ort_s, 3), "target_fps": 10, "threads": threads}


def gpu_inference(model, canvas_hw: tuple[int, int], repeats: int, device: str = "cuda") -> dict:
    """Frames/s at batch 1 on the GPU of a (H, W, 3) uint8 frame in host memory to boxes, scores, classes
    (and mask probabilities) in host memory: the ``Detector``'s path (float32, eager) against bfloat16
    autocast with channels-last tensors and against a CUDA graph of the float32 model, the fastest being
    the ceiling (``ratio`` = the Detector's path over it)."""
    frame = torch.from_numpy(np.random.default_rng(0).integers(0, 256, (*canvas_hw, 3), dtype=np.uint8)).pin_memory()
    # an RGB-D model's frame comes with its depth (H, W) float32 m, encoded on the device as well
    depth_m = torch.from_numpy(np.random.default_rng(1).uniform(0.5, 8.0, canvas_hw).astype(np.float32)).pin_memory()
    # an RGB-D-height model's also with its height above the floor (H, W) m (computed on the host: the Detector's)
    height_m = torch.from_numpy(np.random.default_rng(2).uniform(0.0, 2.0, canvas_hw).astype(np.float32)).pin_memory()
    graph = ExportedDetector(model.to(device).eval())

    def prepare() -> torch.Tensor:
        rgb = frame.to(device, non_blocking=True).permute(2, 0, 1)[None].float() / 255
        if model.cfg.inputs == "rgbd":
            return torch.cat([rgb, depth_channel(depth_m.to(device, non_blocking=True))[None, None]], dim=1)
        if model.cfg.inputs == "rgbdh":
            return torch.cat([rgb, depth_channel(depth_m.to(device, non_blocking=True))[None, None],
                              height_channel(height_m.to(device, non_blocking=True))[None, None]], dim=1)
        return rgb

    def run(fn) -> float:
        def call():
            with torch.no_grad():
                out = fn(prepare())
                [t.cpu() for t in out]  # the host copy synchronises
        return 1 / time_calls(call, repeats, warmup=10)

    graph_bf16 = copy.deepcopy(graph).to(memory_format=torch.channels_last)

    def bf16(x):
        with torch.autocast("cuda", dtype=torch.bfloat16):
            return graph_bf16(x.contiguous(memory_format=torch.channels_last))

    fps = {"float32": run(graph), "bfloat16_channels_last": run(bf16)}
    failed = {}
    try:  # a capture failure is reported, not fatal: the other two figures stand without it
        static_in = prepare()
        stream = torch.cuda.Stream()
        stream.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(stream), torch.no_grad():
            for _ in range(3):
                graph(static_in)
        torch.cuda.current_stream().wait_stream(stream)
        cuda_graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(cuda_graph), torch.no_grad():
            static_out = graph(static_in)

        def replay(x):
            static_in.copy_(x)
            cuda_graph.replay()
            return static_out

        fps["cuda_graph_float32"] = run(replay)
    except RuntimeError as err:
        failed["cuda_graph_error"] = str(err)[:300]
    ceiling = max(fps.values())
    return {"size": [canvas_hw[1], canvas_hw[0]], **{k: round(v, 1) for k, v in fps.items()}, **failed,
            "detector_fps": round(fps["float32"], 1), "ratio": round(fps["float32"] / ceiling, 3), "target_fps": 60,
            "gpu": torch.cuda.get_device_name(0)}


def training_ceiling(model_name: str, num_classes: int, canvas_hw, batch_size: int, device: str, steps: int,
                     mask_prototypes: int = 8) -> float:
    """Steps/s of forward + loss + backward + AdamW step on one resident batch (bf16 autocast on CUDA)."""
    model = build_model(ModelCfg(name=model_name, num_classes=num_classes, mask_prototypes=mask_prototypes))
    cuda = device.startswith("cuda")
    memory_format = torch.channels_last if cuda else torch.contiguous_format  # as train() runs it
    model = model.to(device).train().to(memory_format=memory_format)
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-3)
    images = torch.rand(batch_size, 3, *canvas_hw, device=device).contiguous(memory_format=memory_format)
    boxes = torch.tensor([[10.0, 10.0, 60.0, 50.0], [80.0, 40.0, 120.0, 100.0]], device=device).repeat(batch_size, 1, 1)
    classes = torch.tensor([0, num_classes - 1], device=device).repeat(batch_size, 1)
    instances = torch.zeros(batch_size, *canvas_hw, dtype=torch.uint8, device=device)  # the boxes filled
    instances[:, 10:50, 10:60], instances[:, 40:100, 80:120] = 1, 2

    def step():
        with torch.autocast(torch.device(device).type, dtype=torch.bfloat16, enabled=cuda):
            maps = model(images)
        masks = mask_cells(instances, 2) if mask_prototypes else None
        loss = centernet_loss(maps, boxes, classes, masks)["total"]
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        if cuda:
            torch.cuda.synchronize()

    return 1 / time_calls(step, steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, default=2, help="CPU threads for inference (the target: 2 cores)")
    parser.add_argument("--model", default="centernet-small")
    parser.add_argument("--mask-prototypes", type=int, default=8, help="0: the boxes-only model")
    parser.add_argument("--checkpoint", default=None, help="time this trained model instead of an untrained one")
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--train", default=None, help="dataset folder: also train on it and report mAP")
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--epochs", type=int, default=30)
    parser.add_argument("--batch-size", type=int, default=32)
    parser.add_argument("--workers", type=int, default=min(8, os.cpu_count() or 1))
    parser.add_argument("--out", default=None, help="run folder for --train (default: a temporary one)")
    parser.add_argument("--gpu-size", type=int, nargs=2, default=None, metavar=("W", "H"),
                        help="also time batch-1 inference on the GPU at this size (the issue's: 640 480)")
    args = parser.parse_args()
    summary: dict = {"model": args.model, "mask_prototypes": args.mask_prototypes, "cpus": os.cpu_count()}
    if args.train:
        from ambulo.detection import TrainCfg, train

        cfg = TrainCfg(model=args.model, epochs=args.epochs, batch_size=args.batch_size, device=args.device,
                       num_workers=args.workers, mask_prototypes=args.mask_prototypes)
        out = args.out or tempfile.mkdtemp(prefix="detector_bench_")
        start = time.perf_counter()
        result = train(args.train, out, cfg)
        seconds = time.perf_counter() - start
        state = torch.load(Path(out) / "checkpoint.pt", map_location="cpu", weights_only=False)
        ceiling = training_ceiling(args.model, len(state["categories"]), state["canvas_hw"], args.batch_size,
                                   args.device, 20, args.mask_prototypes)
        steps_per_s = result.step / seconds
        summary["train"] = {"device": args.device, "epochs": args.epochs, "steps": result.step, "seconds": round(seconds, 1),
                            "steps_per_s": round(steps_per_s, 3), "ceiling_steps_per_s": round(ceiling, 3),
                            "train_ratio": round(steps_per_s / ceiling, 3), "evaluations": result.evaluations,
                            "run_dir": str(out)}
        print(f"trained {result.step} steps in {seconds:.0f} s ({steps_per_s:.2f} steps/s, ceiling {ceiling:.2f}); "
              f"held-out {json.dumps(result.evaluations[-1] if result.evaluations else None)}")
        args.checkpoint = args.checkpoint or str(Path(out) / "checkpoint.pt")
    if args.checkpoint:
        model, _ = load_trained(args.checkpoint)
    else:
        model = build_model(ModelCfg(name=args.model, num_classes=4, mask_prototypes=args.mask_prototypes)).eval()
    summary["inference_320x240_cpu"] = inference(model.cpu(), args.threads, args.repeats)
    i = summary["inference_320x240_cpu"]
    print(f"320x240 batch 1 on {args.threads} CPU threads: ONNX Runtime {i['onnxruntime_fps']} frames/s, torch "
          f"{i['torch_eager_fps']} frames/s (target 10); ratio to the fastest {i['ratio']}")
    summary["ratio"] = i["ratio"]
    if args.gpu_size:
        w, h = args.gpu_size
        if w % 32 or h % 32:
            parser.error(f"--gpu-size {w} {h}: both must be multiples of 32 (the model's stride)")
        gpu = summary["inference_gpu"] = gpu_inference(model, (h, w), args.repeats)
        print(f"{w}x{h} batch 1 on {gpu['gpu']}: the Detector's path {gpu['detector_fps']} frames/s (target 60), "
              f"bf16 {gpu['bfloat16_channels_last']}, CUDA graph {gpu.get('cuda_graph_float32')}; ratio {gpu['ratio']}")
    print("RESULT " + json.dumps(summary))


if __name__ == "__main__":
    main()
