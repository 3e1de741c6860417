"""Ship a trained policy: export it into the package's assets with its contract.

    python scripts/ship_policy.py runs/humanoid-walk/<time> [--checkpoint model_867.pt]

Exports ONNX + TorchScript (``ambulo export``: both checked against torch) into
``src/ambulo/assets/data/policies/<task>/``, evaluates it on the CPU engine as ``ambulo eval
--device cpu`` does (the sim-to-sim check for a GPU-trained run), and writes ``contract.json``:
the observation terms (names, sizes, scales) read from the task's env, the joint order, default
pose, action scale and control period, the run's settings, its evaluations and the commit.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import subprocess
from pathlib import Path

import torch

from ambulo import envs
from ambulo.assets import policy_folder
from ambulo.rl import evaluate, export, runs


def contract_for(run_dir: Path, checkpoint: str, info: dict, cpu_eval: dict) -> dict:
    env = runs.make_env_for_run(info, num_envs=1, device="cpu", play=True)
    env.reset()
    terms = {name: int(t.shape[1]) for name, t in env._policy_terms().items()}
    cfg = env.cfg
    scales = {"velocity_commands": list(cfg.obs_scale_command), "joint_vel": cfg.obs_scale_joint_vel,
              "base_ang_vel": cfg.obs_scale_ang_vel}
    spec = envs.spec(info["task"])
    robot = env.robot
    contract = {
        "task": info["task"],
        "robot_file": Path(cfg.robot.file).name,
        "num_obs": env.num_obs,
        "num_actions": env.num_actions,
        "observation_terms": [{"name": n, "size": s, "scale": scales.get(n, 1.0)} for n, s in terms.items()],
        "observation_notes": {
            "projected_gravity": "gravity direction (unit) in the base frame",
            "velocity_commands": "(vx, vy) m/s in the heading frame and yaw rate rad/s, times scale",
            "footsteps": "the next two footsteps (the swing foot's target first) in the base's heading frame: "
                         "per footstep sole centre x, y m, cos and sin of its yaw relative to the heading, "
                         "side (+1 left, -1 right)",
            "joint_pos_rel": "joint positions minus default_joint_pos, rad, joint_names order",
            "joint_vel": "joint velocities rad/s, times scale",
            "base_ang_vel": "base angular velocity in the base frame rad/s, times scale",
            "actions": "the previous action (zeros at start)",
            "height_scan": "base z minus the ground's z under each point of a grid in the base's heading frame "
                           "(x forward, y left, yaw only), minus height_scan.height_offset_m, clipped to "
                           "+-height_scan.clip_m, m; x-major: x from -length_m/2 to +length_m/2 (shifted by "
                           "forward_offset_m), y from -width_m/2 to +width_m/2 within each x, resolution_m apart",
        },
        "joint_names": list(robot.joint_names),
        "default_joint_pos": [round(float(v), 6) for v in robot.default_joint_pos.reshape(-1)],
        "default_root_height_m": round(float(robot.data.root_pos_w[0, 2]), 4),
        "action": "joint position targets default_joint_pos + action_scale * action, tracked by the "
                  "robot's PD drives",
        "action_scale": cfg.action_scale,
        "control_dt_s": env.step_dt_s,
        "physics_dt_s": cfg.physics.timestep_s,
        "trained": {"run": run_dir.name, "checkpoint": checkpoint, "device": info["device"],
                    "seed": info["seed"], "num_envs": info["ppo"]["num_envs"], "commit": None},
        # the task's own step metrics (means over the episodes) and each of its criteria; a task judged in
        # blocks (humanoid-walk-robust: nominal + 16 transfer corners) adds its worst and failing blocks
        "eval_cpu": {k: v for k, v in cpu_eval.items()
                     if k in ("device", "episodes", "episode_length_s", "fall_rate", "worst_block", "blocks_failed")
                     or (k.startswith("mean_") and k != "mean_return")
                     or k in {c.name for c in spec.criteria}},
    }
    if "velocity_commands" in terms:  # a velocity-command policy: the ranges it was trained on
        contract["command_ranges"] = {"lin_vel_x_m_s": list(cfg.commands.lin_vel_x_m_s),
                                      "lin_vel_y_m_s": list(cfg.commands.lin_vel_y_m_s),
                                      "yaw_rate_rad_s": list(cfg.commands.yaw_rate_rad_s)}
    if "height_scan" in terms:  # a terrain policy: the grid its scan samples, which a user must rebuild
        contract["height_scan"] = dataclasses.asdict(cfg.height_scan)
    reached = run_dir / "time_to_criterion.json"
    if reached.is_file():
        r = json.loads(reached.read_text())
        contract["time_to_criterion"] = {k: r[k] for k in ("iteration", "wall_s", "env_steps")}
    env.close()
    return contract


def _head() -> str | None:
    """This checkout's commit."""
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run")
    p.add_argument("--checkpoint")
    p.add_argument("--commit", help="the commit that trained the run (default: this checkout's HEAD)")
    args = p.parse_args()
    run_dir, ckpt = runs.resolve_policy(args.run, args.checkpoint)
    info = runs.read_run_info(run_dir)
    out = policy_folder(info["task"])
    tmp = out.with_name(out.name + ".new")
    shutil.rmtree(tmp, ignore_errors=True)
    exported = export(run_dir, checkpoint=ckpt, out_dir=tmp)
    cpu_eval = evaluate(run_dir, checkpoint=ckpt, device="cpu", quiet=True)
    contract = contract_for(run_dir, ckpt.name, info, cpu_eval)
    contract["trained"]["commit"] = args.commit or _head()
    contract["export"] = {"onnx_max_abs_diff": exported["onnx_max_abs_diff"],
                          "torchscript_max_abs_diff": exported["torchscript_max_abs_diff"],
                          "torch": torch.__version__}
    (tmp / "contract.json").write_text(json.dumps(contract, indent=2) + "\n")
    shutil.rmtree(out, ignore_errors=True)
    tmp.rename(out)
    print(f"shipped {info['task']} policy ({ckpt.name}) to {out}: CPU eval {contract['eval_cpu']}")


if __name__ == "__main__":
    envs.names()
    main()
