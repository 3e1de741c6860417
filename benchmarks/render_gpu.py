"""Frames/s of the TiledCamera vs raw MuJoCo Warp ray-cast rendering (the ceiling).

Scene: the bundled humanoid on the default ground and light, N worlds, each with its own
random joint pose and heading, seen by one world-fixed camera 2.3 m away (the robot, the floor
and the horizon in view). Outputs: rgb, depth, instance and semantic segmentation.

The sensor side is what an env reads per step: ``camera.update`` then ``camera.data``, which
writes the camera pose of every world (mount pose x per-world offset), runs ``refit_bvh`` +
``render`` (one CUDA graph) and unpacks the buffers into (N, H, W, C) tensors (rgb bytes,
depth with +inf for misses, geom ids and semantic ids). The ceiling is ``mujoco_warp.refit_bvh``
+ ``mujoco_warp.render`` alone, in the same process, on the same device model and data, with a
render context of the same camera, size and outputs, captured in one CUDA graph
(``wp.ScopedCapture``) on CUDA. Timed loops are bracketed by ``torch.cuda.synchronize``; runs
alternate (sensor, raw, sensor, raw) and the best of each is kept.

    python benchmarks/render_gpu.py [--num-worlds 1024] [--width 128 --height 128] [--steps 100]
    python benchmarks/render_gpu.py --device cpu --num-worlds 4 --width 32 --height 24 --steps 2

frames/s = worlds x renders / s (one frame: one camera image with every output). ratio = sensor
frames/s / raw frames/s. Memory: the render context's arrays (buffers, rays, BVH bounds), what
the device lost while one context was created (CUDA), and the sensor's output tensors. Ends
with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import time

import mujoco_warp as mjw
import torch
import warp as wp

from ambulo.core import GroundCfg, PhysicsCfg, RobotCfg, Simulation, add_ground, add_robot, new_scene
from ambulo.engine.gpu import capture_graph, stack_versions
from ambulo.engine.gpu import synchronize as sync
from ambulo.sensors import TiledCamera

DATA_TYPES = ("rgb", "depth", "instance_segmentation", "semantic_segmentation")
EYE, TARGET = (1.6, -1.6, 1.3), (0.0, 0.0, 0.75)
JOINT_NOISE_RAD = 0.3



def device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    return f"Warp CPU device ({wp.get_device('cpu').name})"


def humanoid_scene(num_worlds: int, device: str, width: int, height: int) -> tuple[Simulation, TiledCamera]:
    """The humanoid in ``num_worlds`` random poses and a camera on it, kinematics computed."""
    spec = new_scene("render_gpu")
    add_ground(spec, GroundCfg())
    add_robot(spec, RobotCfg(file="humanoid", prim_path="/World/robot"))
    sim = Simulation(spec, PhysicsCfg(), num_worlds=num_worlds, device=device, engine="warp")
    camera = sim.add(TiledCamera(prim_path="/World/camera", width=width, height=height, data_types=DATA_TYPES))
    engine = sim.start()
    camera.set_camera_view(EYE, TARGET)
    generator = torch.Generator(device=engine.device).manual_seed(0)
    qpos = engine.qpos
    joints = torch.rand(qpos[:, 7:].shape, generator=generator, device=engine.device) * 2 - 1
    qpos[:, 7:] += JOINT_NOISE_RAD * joints
    yaw = (torch.rand(num_worlds, generator=generator, device=engine.device) * 2 - 1) * math.pi
    qpos[:, 3], qpos[:, 6] = torch.cos(yaw / 2), torch.sin(yaw / 2)
    engine.forward()
    return sim, camera


class RawRender:
    """``refit_bvh`` + ``render`` of the camera's view on the engine's model and data, with a
    render context of its own (the same camera, size, outputs and far clip)."""

    def __init__(self, camera: TiledCamera):
        engine = camera.engine
        self.engine = engine
        model = engine.model.__copy__()
        near, far = camera.cfg.clipping_range_m
        model.vis.map.znear, model.vis.map.zfar = near / model.stat.extent, far / model.stat.extent
        sync(engine.device)
        free_before = torch.cuda.mem_get_info(engine.device)[0] if engine.device.type == "cuda" else None
        with engine.warp_scope():
            self.context = mjw.create_render_context(
                model, engine.num_worlds, cam_res=(camera.cfg.width, camera.cfg.height), render_rgb=True,
                render_depth=True, render_seg=True, cam_active=[camera.cam_id], use_shadows=False)
        sync(engine.device)
        self.device_bytes = None if free_before is None else free_before - torch.cuda.mem_get_info(engine.device)[0]
        self.graph = None
        if engine.device.type == "cuda":
            self._launch()  # compiles the kernels first: a capture cannot
            sync(engine.device)
            self.graph = capture_graph(engine.wp_device, wp.Stream(engine.wp_device), lambda: (
                mjw.refit_bvh(engine.wp_model, engine.wp_data, self.context),
                mjw.render(engine.wp_model, engine.wp_data, self.context)))

    def _launch(self) -> None:
        with self.engine.warp_scope():
            mjw.refit_bvh(self.engine.wp_model, self.engine.wp_data, self.context)
            mjw.render(self.engine.wp_model, self.engine.wp_data, self.context)

    def launch(self) -> None:
        if self.graph is None:
            self._launch()
            return
        with self.engine.warp_scope():
            wp.capture_launch(self.graph)


def context_array_bytes(context) -> int:
    """Bytes of the render context's Warp arrays (output buffers, rays, BVH bounds)."""
    total = 0
    for f in dataclasses.fields(context):
        value = getattr(context, f.name)
        if isinstance(value, wp.array):
            total += value.capacity
    return total


def time_sensor(camera: TiledCamera, steps: int) -> float:
    sync(camera.engine.device)
    start = time.perf_counter()
    for _ in range(steps):
        camera.update(0.0)
        camera.data  # noqa: B018 - the read renders
    sync(camera.engine.device)
    return time.perf_counter() - start


def time_raw(raw: RawRender, steps: int) -> float:
    sync(raw.engine.device)
    start = time.perf_counter()
    for _ in range(steps):
        raw.launch()
    sync(raw.engine.device)
    return time.perf_counter() - start


def measure(args) -> dict:
    sim, camera = humanoid_scene(args.num_worlds, args.device, args.width, args.height)
    engine = sim.engine
    start = time.perf_counter()
    camera.render()  # kernels compiled or loaded, graph captured
    sync(engine.device)
    first_render_s = time.perf_counter() - start
    raw = RawRender(camera)
    raw.launch()
    sensor_s, raw_s = [], []
    for _ in range(args.repeats):
        sensor_s.append(time_sensor(camera, args.steps))
        raw_s.append(time_raw(raw, args.steps))
    # the ceiling renders what the sensor renders: the same geom ids in every pixel
    camera.render()
    raw.launch()
    seg_raw = wp.to_torch(raw.context.seg_data)[..., 0].view(args.num_worlds, args.height, args.width)
    same = float((camera.data.output["instance_segmentation"][..., 0] == seg_raw).float().mean())
    model = engine.model
    robot_geoms = torch.tensor([model.body(int(b)).name.startswith("/World/robot/") for b in model.geom_bodyid],
                               device=engine.device)
    ids = camera.data.output["instance_segmentation"][..., 0].long()
    robot_fraction = float(robot_geoms[ids.clamp(min=0)][ids >= 0].float().sum() / ids.numel())
    frames = args.num_worlds * args.steps
    sensor_rate, raw_rate = frames / min(sensor_s), frames / min(raw_s)
    output_bytes = sum(t.numel() * t.element_size() for t in camera.data.output.values())
    return {
        "num_worlds": args.num_worlds, "width": args.width, "height": args.height,
        "data_types": list(DATA_TYPES),
        "frames_per_s": round(sensor_rate), "raw_frames_per_s": round(raw_rate),
        "ratio": round(sensor_rate / raw_rate, 3),
        "sensor_ms_per_render": round(1e3 * min(sensor_s) / args.steps, 3),
        "raw_ms_per_render": round(1e3 * min(raw_s) / args.steps, 3),
        "first_render_s": round(first_render_s, 2),
        "same_segmentation_as_raw": round(same, 6),
        "robot_pixel_fraction": round(robot_fraction, 3),
        "render_context_array_mib": round(context_array_bytes(camera._context) / 2**20, 2),
        "render_context_device_mib": None if raw.device_bytes is None else round(raw.device_bytes / 2**20, 2),
        "sensor_output_mib": round(output_bytes / 2**20, 2),
        "cuda_graphs": engine.device.type == "cuda",
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-worlds", type=int, default=1024)
    parser.add_argument("--width", type=int, default=128)
    parser.add_argument("--height", type=int, default=128)
    parser.add_argument("--steps", type=int, default=100, help="renders per timed run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--device", default="cuda", help="cuda[:k], or cpu (Warp's CPU device)")
    args = parser.parse_args(argv)
    row = measure(args)
    print(f"N={row['num_worlds']} {row['width']}x{row['height']} {'+'.join(DATA_TYPES)}: "
          f"TiledCamera {row['frames_per_s']} frames/s ({row['sensor_ms_per_render']:.2f} ms/render), raw "
          f"{row['raw_frames_per_s']} frames/s ({row['raw_ms_per_render']:.2f} ms), ratio {row['ratio']:.3f}; "
          f"render context {row['render_context_array_mib']} MiB of arrays"
          + (f", {row['render_context_device_mib']} MiB of device memory" if row["render_context_device_mib"] else ""),
          flush=True)
    result = {"benchmark": "render_gpu", "device": device_name(torch.device(args.device)),
              "versions": stack_versions(), "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              **row}
    print("RESULT " + json.dumps(result), flush=True)
    return result


if __name__ == "__main__":
    main()
