"""``isaacgym.gymutil`` under ``ambulo run``: Isaac Gym's command line and ``SimParams`` from it."""

from __future__ import annotations

import argparse

from .types import SIM_FLEX, SIM_PHYSX, UP_AXIS_Y, UP_AXIS_Z, SimParams, Vec3


def parse_device_str(device: str) -> tuple[str, int]:
    """``"cuda:1"`` -> ``("cuda", 1)``; ``"cpu"`` -> ``("cpu", 0)``."""
    kind, _, index = device.partition(":")
    if kind not in ("cpu", "cuda"):
        raise ValueError(f"isaacgym: device {device!r} is not 'cpu' or 'cuda[:N]'")
    return kind, int(index or 0)


def parse_arguments(description: str = "Isaac Gym Example", headless: bool = False, no_graphics: bool = False,
                    custom_parameters: list[dict] | None = None) -> argparse.Namespace:
    """Isaac Gym's standard flags (``--sim_device``, ``--pipeline``, ``--physx``/``--flex``,
    ``--num_threads``, ``--headless``, ...) plus the script's ``custom_parameters``."""
    parser = argparse.ArgumentParser(description=description)
    if headless:
        parser.add_argument("--headless", action="store_true", help="Run headless without creating a viewer window")
    if no_graphics:
        parser.add_argument("--nographics", action="store_true", help="Disable graphics context creation")
    parser.add_argument("--sim_device", type=str, default="cuda:0", help="Physics device, 'cpu' or 'cuda:N'")
    parser.add_argument("--pipeline", type=str, default="gpu", help="Tensor API pipeline (cpu/gpu)")
    parser.add_argument("--graphics_device_id", type=int, default=0, help="Graphics device ID")
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument("--flex", action="store_true", help="Use FleX for physics")
    engine.add_argument("--physx", action="store_true", help="Use PhysX for physics")
    parser.add_argument("--num_threads", type=int, default=0, help="Number of cores used by PhysX")
    parser.add_argument("--subscenes", type=int, default=0, help="Number of PhysX subscenes to simulate in parallel")
    parser.add_argument("--slices", type=int, help="Number of client threads that process env slices")
    for param in custom_parameters or []:
        name = param["name"]
        kwargs = {k: v for k, v in param.items() if k != "name"}
        parser.add_argument(name, **kwargs)
    args = parser.parse_args()
    args.sim_device_type, args.compute_device_id = parse_device_str(args.sim_device)
    pipeline = args.pipeline.lower()
    if pipeline not in ("cpu", "gpu", "cuda"):
        parser.error(f"--pipeline {args.pipeline}: use cpu or gpu")
    args.use_gpu_pipeline = pipeline in ("gpu", "cuda")
    if args.sim_device_type != "cuda" and args.flex:
        parser.error("Flex needs a CUDA --sim_device")
    args.use_gpu = args.sim_device_type == "cuda"
    args.physics_engine = SIM_FLEX if args.flex else SIM_PHYSX
    if args.slices is None:
        args.slices = args.subscenes
    return args


def parse_sim_params(args: argparse.Namespace, cfg: dict | None = None, cfg_train: dict | None = None) -> SimParams:
    """``SimParams`` from ``parse_arguments``'s flags (and a ``cfg["sim"]`` dict of field values)."""
    params = SimParams()
    params.use_gpu_pipeline = getattr(args, "use_gpu_pipeline", False)
    params.physx.use_gpu = getattr(args, "use_gpu", False)
    params.physx.num_threads = getattr(args, "num_threads", 0)
    params.physx.num_subscenes = getattr(args, "subscenes", 0)
    if (cfg or {}).get("sim"):
        parse_sim_config(cfg["sim"], params)
    return params


def parse_sim_config(values: dict, sim_params: SimParams) -> None:
    """Set ``sim_params`` from a config dict (a task's ``sim`` section, as legged_gym and
    IsaacGymEnvs write it): ``gravity`` a 3-list (m/s^2), ``up_axis`` 0 (y) or 1 (z), ``physx`` and
    ``flex`` dicts of their fields, any other key a ``SimParams`` field. Keys ``SimParams`` does
    not have fail, as a misspelt field would otherwise be silently dropped."""
    for key, value in values.items():
        if key == "gravity":
            sim_params.gravity = Vec3(*value)
        elif key == "up_axis":
            sim_params.up_axis = UP_AXIS_Z if int(value) == UP_AXIS_Z else UP_AXIS_Y
        elif key in ("physx", "flex"):
            section = getattr(sim_params, key)
            for name, v in value.items():
                if not hasattr(section, name):
                    raise ValueError(f"isaacgym: sim config {key}.{name} is not a {type(section).__name__} field")
                setattr(section, name, v)
        elif hasattr(sim_params, key):
            setattr(sim_params, key, value)
        else:
            raise ValueError(f"isaacgym: sim config key {key!r} is not a SimParams field")


__all__ = ["parse_arguments", "parse_device_str", "parse_sim_config", "parse_sim_params"]
