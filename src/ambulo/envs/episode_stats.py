"""Episode statistics of an RLEnv without host syncs: device-side sums over windows of steps."""

from __future__ import annotations

import torch


class EpisodeStats:
    """Per-term means over the episodes that end within windows of ``stats_interval_steps``.

    Sums and counts stay on the device, in one buffer changed in place (``add``: device work a
    CUDA graph of the step can hold); a window is published every that many steps by
    ``publish``, outside the step's device work (a Python counter decides, so nothing waits for
    the device).
    """

    def __init__(self, env):
        self.env = env
        self.interval = max(1, env.cfg.stats_interval_steps)
        self.steps = 0
        self.keys: list[str] | None = None
        self.sums: torch.Tensor | None = None
        """(K + 1,) masked sums of each statistic over the window, then the episode count;
        allocated at the first ``add``, zeroed in place when published."""
        self._added = False
        """Whether an ``add`` summed anything in this window (on a GPU, every ``add`` does)."""

    def add(self, dones, terminations, time_outs, diverged) -> None:
        """Sum this step's ended episodes into the window (device work, no sync on a GPU)."""
        # on the CPU a step where no episode ended adds nothing (asking is free there)
        if dones.device.type == "cpu" and not bool(dones.any()):
            return
        env = self.env
        flags = torch.stack([*terminations.values(), time_outs, diverged, torch.ones_like(dones)], dim=1)
        columns = [env.episode_sums, (env.episode_length_buf * env.step_dt_s)[:, None], flags]
        if self.keys is None:
            self.keys = ([f"Episode_Reward/{name}" for name in env.reward_names] + ["Episode/length_s"]
                         + [f"Episode_Termination/{name}" for name in terminations]
                         + ["Episode_Termination/time_out", "Episode_Termination/diverged"])
        # one (N, K + 1) table, one masked reduction: the last column counts ended episodes
        table = torch.cat(columns, dim=1).float()
        total = dones.float() @ table
        if self.sums is None:
            self.sums = torch.zeros_like(total)
        self.sums += total  # in place (0 + x == x: the first window's values are unchanged)
        self._added = True

    def publish(self) -> dict[str, torch.Tensor] | None:
        """Count one step; every ``interval`` steps, the window's means (new tensors) and a new
        window, else None (also when no episode ended in the window)."""
        self.steps += 1
        if self.steps < self.interval:
            return None
        self.steps = 0
        if not self._added:  # no episode ended in this window: nothing to report
            return None
        self._added = self.env.device.type != "cpu"  # a graph's replays add without Python
        count = self.sums[-1].clone()
        means = self.sums[:-1] / count.clamp(min=1.0)
        out = dict(zip(self.keys, means.unbind()))
        out["Episode/num_ended"] = count
        out["Episode/nonfinite_actions"] = self.env._nonfinite_actions.float()
        self.sums.zero_()
        return out


__all__ = ["EpisodeStats"]
