"""Where a terrain walker falls: its robots' paths over the hardest tile of chosen kinds, seen from above.

    python scripts/plot_falls.py RUN --checkpoint model_2051.pt --kinds stepping_stones,stairs_down \\
        --episodes 70 --out docs/images/rough_falls.png
    python scripts/plot_falls.py --shipped humanoid-rough --kinds stepping_stones --out /tmp/shipped_falls.png

For each kind, ``--episodes`` robots walk one evaluation episode each (the play variant, as ``ambulo eval``
runs it) on a terrain of that kind alone, every robot on the hardest level, on the CPU engine. The plot
draws that tile's heights and each robot's base path: grey for the robots that finished their episode,
red ending in a cross for those that fell. Prints one line a kind: its fall rate and where the falls
were, as the distance from the tile's centre (the robots start on its flat platform).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from ambulo import envs
from ambulo.rl import runs
from ambulo.rl.evaluate import episode_records, eval_episode_length_s
from ambulo.rl.vecenv import RslRlVecEnv


def kind_paths(run: Path | None, checkpoint: str | None, kind: str, episodes: int, seed: int,
               episode_length_s: float | None, shipped: str | None = None):
    """One episode per robot on the hardest ``kind`` tile, with ``run``'s ``checkpoint`` or the policy
    ambulo ships for task ``shipped``: (paths (T, N, 2) base xy in the world frame, m, nan after its
    episode ended; fell (N,) bool; the env's terrain grid)."""
    overrides = {"terrain.kinds": (kind,)}
    if shipped is not None:
        from ambulo.policies.shipped import load_policy

        task, policy_file = envs.spec(shipped), load_policy(shipped)
        env = envs.make(shipped, num_envs=episodes, device="cpu", seed=seed, play=True,
                        episode_length_s=eval_episode_length_s(task, episode_length_s), **overrides)
        policy = lambda obs: policy_file(obs["policy"])
    else:
        info = runs.read_run_info(run)
        task = envs.spec(info["task"])
        env = runs.make_env_for_run(info, num_envs=episodes, seed=seed, device="cpu", play=True, engine="mujoco",
                                    episode_length_s=eval_episode_length_s(task, episode_length_s), **overrides)
        policy = runs.load_runner(run, env, run / checkpoint).get_inference_policy(device="cpu")
    try:
        paths = []

        def record(running: torch.Tensor) -> None:  # each robot's base before the policy acts, nan once ended
            xy = env.robot.data.root_pos_w[:, :2].float()
            paths.append(torch.where(running[:, None], xy, torch.nan))

        records = episode_records(env, RslRlVecEnv(env), policy, task, on_step=record)
        return torch.stack(paths).cpu().numpy(), records.failed.cpu().numpy(), env.terrain
    finally:
        env.close()


def plot(panels, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 5.2), squeeze=False)
    for ax, (kind, paths, fell, grid) in zip(axes[0], panels):
        sx, sy = grid.cfg.tile_slices(grid.num_levels - 1, 0)
        heights = grid.heights_m[sx, sy]
        x0, y0 = grid.origin_xy_m + np.array([sx.start, sy.start]) * grid.spacing_m
        extent = (x0, x0 + heights.shape[0] * grid.spacing_m, y0, y0 + heights.shape[1] * grid.spacing_m)
        image = ax.imshow(heights.T, origin="lower", extent=extent, cmap="terrain")
        fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04, label="height, m")
        for i in range(paths.shape[1]):
            path = paths[~np.isnan(paths[:, i, 0]), i]
            ax.plot(path[:, 0], path[:, 1], color="red" if fell[i] else "0.35", lw=0.8, alpha=0.9 if fell[i] else 0.5)
            if fell[i]:
                ax.plot(*path[-1], marker="x", color="red", ms=7, mew=2)
        ax.set_title(f"{kind}: {int(fell.sum())} of {len(fell)} fell")
        ax.set_xlim(extent[:2])
        ax.set_ylim(extent[2:])
        ax.set_xlabel("x, m (world)")
        ax.set_ylabel("y, m (world)")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, nargs="?", help="a run folder (with --checkpoint)")
    p.add_argument("--checkpoint")
    p.add_argument("--shipped", metavar="TASK", help="the policy ambulo ships for TASK, in place of a run")
    p.add_argument("--kinds", default="stepping_stones", help="comma list of tile kinds (one panel each)")
    p.add_argument("--episodes", type=int, default=70)
    p.add_argument("--seed", type=int, default=12345)
    p.add_argument("--episode-length-s", type=float)
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    if (args.shipped is None) == (args.run is None) or (args.run is not None and not args.checkpoint):
        p.error("give a run folder with --checkpoint, or --shipped TASK")
    task = args.shipped or runs.read_run_info(args.run)["task"]
    if not hasattr(envs.spec(task).cfg_fn(), "terrain"):
        p.error(f"task {task} has no terrain tiles; give a run or --shipped task of a terrain task (humanoid-rough, ...)")
    panels = []
    for kind in args.kinds.split(","):
        try:
            paths, fell, grid = kind_paths(args.run, args.checkpoint, kind, args.episodes, args.seed,
                                           args.episode_length_s, shipped=args.shipped)
        except (ValueError, KeyError, OSError) as error:  # a task without terrain, an unknown kind or run
            p.error(f"{str(error).splitlines()[0]} (a terrain task's run or --shipped task, and its kinds)")
        centre = grid.tile_centers_w[-1, 0, :2]
        last = np.array([paths[~np.isnan(paths[:, i, 0]), i][-1] for i in range(paths.shape[1])])
        where = np.linalg.norm(last[fell] - centre, axis=1)
        print(f"{kind}: fall rate {fell.mean():.3f} ({int(fell.sum())} of {len(fell)}); falls at "
              f"{', '.join(f'{d:.1f}' for d in sorted(where)) or '-'} m from the tile's centre")
        panels.append((kind, paths, fell, grid))
    plot(panels, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
