"""legged_gym's ``train.py --task=anymal_c_flat``, unmodified, under ``ambulo run``: how fast it trains.

Runs, in its own process and working directory,

    PYTHONPATH=<legged_gym>:<rsl_rl> ambulo run --seconds 1e9 <legged_gym>/legged_gym/scripts/train.py \
        --task=anymal_c_flat --headless --num_envs N --max_iterations I --sim_device D --rl_device R

(legged_gym's own flags, ``helpers.get_args``), with the two source trees given by path: a
checkout of ``leggedrobotics/legged_gym`` and ``leggedrobotics/rsl_rl`` at tag v1.0.2 (the API
legged_gym calls; the rsl-rl-lib 5.x in ambulo's venv is another API, so v1.0.2 goes first on
PYTHONPATH and is not installed). ``--extract`` writes both trees from git snapshots first.

It reads rsl_rl's per-iteration log: fps (``Computation``), mean reward, mean episode length and
``Mean episode rew_tracking_lin_vel`` (the episode's tracking reward per second; its maximum is
the reward scale, 1.0). "Walking" is legged_gym's own test for raising the command curriculum:
tracking above 80 % of that maximum; the time to it is rsl_rl's ``Total time`` (training, from
the first iteration) and the wall time from the process start (imports and env build included).

The ceiling is the physics alone: ``simulate`` of the same anymal_c asset (legged_gym's asset
options and sim params) in the same number of worlds through ambulo's Isaac Gym layer, no
policy and no rewards, in env-steps/s (simulate calls / decimation 4); ``ratio`` = training
env-steps/s / that ceiling.

    python benchmarks/legged_gym_anymal.py --legged-gym /tmp/F/legged_gym --rsl-rl /tmp/F/rsl_rl \
        --sim-device cpu --rl-device cpu --num-envs 128 --max-iterations 40     # a CPU run
    python benchmarks/legged_gym_anymal.py --legged-gym LG --rsl-rl RR --sim-device cuda:0 \
        --rl-device cuda:0 --num-envs 4096 --max-iterations 300                  # legged_gym's defaults

Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MIRRORS = Path("/work/.mirror")
LEGGED_GYM_GIT = MIRRORS / "leggedrobotics+legged_gym" / "repo"
RSL_RL_GIT = MIRRORS / "leggedrobotics+rsl_rl" / "repo"
TRACKING_MAX = 1.0
"""legged_gym's ``rewards.scales.tracking_lin_vel``: the per-second episode reward of perfect tracking."""
WALKING_SHARE = 0.8
"""legged_gym's ``update_command_curriculum`` threshold: tracking above 80 % of its maximum."""
DECIMATION = 4
"""anymal_c's ``control.decimation``: simulate calls per policy step."""
ANSI = re.compile(r"\x1b\[[0-9;]*m")
FIELDS = {
    "fps": re.compile(r"Computation:\s+([\d.]+) steps/s"),
    "mean_reward": re.compile(r"Mean reward:\s+(-?[\d.]+)"),
    "mean_episode_length": re.compile(r"Mean episode length:\s+([\d.]+)"),
    "tracking_lin_vel": re.compile(r"Mean episode rew_tracking_lin_vel:\s+(-?[\d.]+)"),
    "total_time_s": re.compile(r"Total time:\s+([\d.]+)s"),
}


def extract(git_dir: Path, ref: str, dest: Path) -> Path:
    """``git archive`` of ``ref`` into ``dest``, leaving out blobs the snapshot lacks (the mirror
    of legged_gym misses two meshes of robots anymal_c_flat does not load)."""
    dest.mkdir(parents=True, exist_ok=True)
    names = subprocess.run(["git", "-C", str(git_dir), "ls-tree", "-r", ref], check=True, capture_output=True,
                           text=True).stdout.splitlines()
    present = []
    for line in names:
        meta, path = line.split("\t", 1)
        blob = meta.split()[2]
        if subprocess.run(["git", "-C", str(git_dir), "cat-file", "-e", blob], capture_output=True).returncode == 0:
            present.append(path)
    archive = subprocess.run(["git", "-C", str(git_dir), "archive", ref, "--", *present], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "x", "-C", str(dest)], input=archive, check=True)
    return dest


def parse_iterations(lines: list[str]) -> list[dict]:
    """One dict per rsl_rl log block (``Learning iteration k/N`` up to the next)."""
    rows, current = [], None
    for raw in lines:
        line = ANSI.sub("", raw)
        m = re.search(r"Learning iteration (\d+)/(\d+)", line)
        if m:
            current = {"iteration": int(m.group(1))}
            rows.append(current)
            continue
        if current is None:
            continue
        for key, pattern in FIELDS.items():
            hit = pattern.search(line)
            if hit:
                current[key] = float(hit.group(1))
    return rows


def train(args, workdir: Path) -> tuple[list[dict], float, int, list[float]]:
    """Run train.py under ``ambulo run``; (iterations, wall s, return code, wall time of each iteration's log).
    The command is kept in ``args.command`` for the result."""
    script = Path(args.legged_gym) / "legged_gym" / "scripts" / "train.py"
    cmd = [sys.executable, "-m", "ambulo.cli", "run", "--seconds", "1e9", str(script), f"--task={args.task}",
           "--headless", "--num_envs", str(args.num_envs), "--max_iterations", str(args.max_iterations),
           "--sim_device", args.sim_device, "--rl_device", args.rl_device, "--seed", str(args.seed)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(Path(args.legged_gym).resolve()), str(Path(args.rsl_rl).resolve()), os.environ.get("PYTHONPATH", "")]))
    args.command = f"PYTHONPATH={env['PYTHONPATH']} " + " ".join(cmd)
    print("$", args.command, flush=True)
    log = open(workdir / "train.log", "w")
    start = time.perf_counter()
    lines, stamps = [], []
    with subprocess.Popen(cmd, cwd=workdir, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as p:
        for line in p.stdout:
            log.write(line)
            lines.append(line)
            if "Learning iteration" in line:
                stamps.append(time.perf_counter() - start)
                print(ANSI.sub("", line).strip(), flush=True)
    log.close()
    wall = time.perf_counter() - start
    if p.returncode:
        print("".join(lines[-40:]), file=sys.stderr)
    return parse_iterations(lines), wall, p.returncode, stamps


def physics_ceiling(args) -> float | None:
    """Env-steps/s of ``simulate`` alone for anymal_c in ``num_envs`` worlds (module docstring)."""
    if args.ceiling_steps <= 0:
        return None
    import torch

    from ambulo.isaac.gym import gymapi, gymtorch

    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.dt, params.substeps, params.up_axis = 0.005, 1, gymapi.UP_AXIS_Z
    params.gravity = gymapi.Vec3(0.0, 0.0, -9.81)
    params.physx.contact_offset, params.physx.rest_offset = 0.01, 0.0
    params.use_gpu_pipeline = args.sim_device.startswith("cuda")
    sim = gym.create_sim(int(args.sim_device.partition(":")[2] or 0), -1, gymapi.SIM_PHYSX, params)
    gym.add_ground(sim, gymapi.PlaneParams())
    options = gymapi.AssetOptions()
    options.collapse_fixed_joints = options.replace_cylinder_with_capsule = True
    options.default_dof_drive_mode = gymapi.DOF_MODE_EFFORT
    root = Path(args.legged_gym) / "resources" / "robots" / "anymal_c" / "urdf"
    asset = gym.load_asset(sim, str(root), "anymal_c.urdf", options)
    side = int(args.num_envs ** 0.5)
    for i in range(args.num_envs):
        env = gym.create_env(sim, gymapi.Vec3(), gymapi.Vec3(), side)
        gym.create_actor(env, asset, gymapi.Transform(gymapi.Vec3(3.0 * (i % side), 3.0 * (i // side), 0.6)),
                         "anymal_c", i, 0, 0)
    gym.prepare_sim(sim)
    torques = torch.zeros(args.num_envs * gym.get_asset_dof_count(asset), device=sim.device)
    for _ in range(10):  # warm-up (kernels compile on the GPU engine)
        gym.set_dof_actuation_force_tensor(sim, gymtorch.unwrap_tensor(torques))
        gym.simulate(sim)
    if torch.cuda.is_available():
        torch.cuda.synchronize()
    start = time.perf_counter()
    for _ in range(args.ceiling_steps):
        gym.set_dof_actuation_force_tensor(sim, gymtorch.unwrap_tensor(torques))
        gym.simulate(sim)
        gym.refresh_dof_state_tensor(sim)
    if torch.cuda.is_available():
        torch.cuda.synchronize()
    elapsed = time.perf_counter() - start
    return args.ceiling_steps * args.num_envs / DECIMATION / elapsed


def summarize(args, rows: list[dict], wall_s: float, stamps: list[float], ceiling: float | None, rc: int) -> dict:
    fps = [r["fps"] for r in rows if "fps" in r]
    walking = next((k for k, r in enumerate(rows) if r.get("tracking_lin_vel", 0.0) >= WALKING_SHARE * TRACKING_MAX),
                   None)
    last = rows[-1] if rows else {}
    mean_fps = sum(fps) / len(fps) if fps else None
    return {
        "task": args.task, "num_envs": args.num_envs, "sim_device": args.sim_device, "rl_device": args.rl_device,
        "command": getattr(args, "command", None), "returncode": rc, "iterations": len(rows), "wall_s": round(wall_s, 1),
        "mean_fps_env_steps_per_s": None if mean_fps is None else round(mean_fps, 1),
        "first": {k: rows[0].get(k) for k in ("mean_reward", "mean_episode_length", "tracking_lin_vel")} if rows else None,
        "last": {k: last.get(k) for k in ("mean_reward", "mean_episode_length", "tracking_lin_vel", "total_time_s")},
        "best_tracking_lin_vel": max((r.get("tracking_lin_vel", 0.0) for r in rows), default=None),
        "walking_criterion": f"rew_tracking_lin_vel >= {WALKING_SHARE} x {TRACKING_MAX}",
        "walking_iteration": walking,
        "time_to_walking_train_s": None if walking is None else rows[walking].get("total_time_s"),
        "time_to_walking_wall_s": None if walking is None or walking >= len(stamps) else round(stamps[walking], 1),
        "isaac_gym_reference_s": args.isaac_reference_s,
        "ceiling_env_steps_per_s": None if ceiling is None else round(ceiling, 1),
        "ratio": None if ceiling is None or mean_fps is None else round(mean_fps / ceiling, 3),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--legged-gym", help="a legged_gym source tree (the folder holding legged_gym/ and resources/)")
    parser.add_argument("--rsl-rl", help="an rsl_rl v1.0.2 source tree (the folder holding rsl_rl/)")
    parser.add_argument("--extract", metavar="DIR", help="first write both trees under DIR from the git snapshots "
                        f"({LEGGED_GYM_GIT}, {RSL_RL_GIT} at v1.0.2) and use them")
    parser.add_argument("--task", default="anymal_c_flat")
    parser.add_argument("--num-envs", type=int, default=4096)
    parser.add_argument("--max-iterations", type=int, default=300)
    parser.add_argument("--sim-device", default="cuda:0")
    parser.add_argument("--rl-device", default="cuda:0")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--ceiling-steps", type=int, default=200, help="simulate calls timed for the ceiling; 0: skip")
    parser.add_argument("--isaac-reference-s", type=float, default=240.0,
                        help="Isaac Gym's time to walk on flat ground, s, for the report (Rudin et al. 2021, "
                             "'Learning to Walk in Minutes...': flat terrain in under four minutes)")
    parser.add_argument("--out", help="folder for train.log and result.json (default: a temporary folder)")
    args = parser.parse_args(argv)
    if args.extract:
        args.legged_gym = str(extract(LEGGED_GYM_GIT, "HEAD", Path(args.extract) / "legged_gym"))
        args.rsl_rl = str(extract(RSL_RL_GIT, "v1.0.2", Path(args.extract) / "rsl_rl"))
    if not (args.legged_gym and args.rsl_rl):
        parser.error("give --legged-gym and --rsl-rl (source trees) or --extract DIR")
    workdir = Path(args.out or tempfile.mkdtemp(prefix="legged_gym_"))
    workdir.mkdir(parents=True, exist_ok=True)
    rows, wall_s, rc, stamps = train(args, workdir)
    ceiling = physics_ceiling(args)
    result = summarize(args, rows, wall_s, stamps, ceiling, rc)
    (workdir / "result.json").write_text(json.dumps({**result, "per_iteration": rows}, indent=1))
    print("RESULT " + json.dumps(result))
    return 0 if rc == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
