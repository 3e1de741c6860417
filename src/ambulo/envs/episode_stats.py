"""Episode statistics of an RLEnv without host syncs: device-side sums over windows of steps."""

from __future__ import annotations

import torch


class EpisodeStats:
    """Per-term means over the episodes that end within windows of ``stats_interval_steps``.

    Sums and counts stay on the device; a window is published every that many steps (a Python
    counter decides, so nothing waits for the device).
    """

    def __init__(self, env):
        self.env = env
        self.interval = max(1, env.cfg.stats_interval_steps)
        self.steps = 0
        self.keys: list[str] | None = None
        self.sums: torch.Tensor | None = None
        """(K + 1,) masked sums of each statistic over the window, then the episode count."""

    def add(self, dones, terminations, time_outs, diverged) -> dict[str, torch.Tensor] | None:
        # on the CPU a step where no episode ended adds nothing (asking is free there)
        if dones.device.type != "cpu" or bool(dones.any()):
            self._add(dones, terminations, time_outs, diverged)
        self.steps += 1
        if self.steps < self.interval:
            return None
        self.steps = 0
        if self.sums is None:  # no episode ended in this window: nothing to report
            return None
        count = self.sums[-1]
        means = self.sums[:-1] / count.clamp(min=1.0)
        out = dict(zip(self.keys, means.unbind()))
        out["Episode/num_ended"] = count
        out["Episode/nonfinite_actions"] = self.env._nonfinite_actions.float()
        self.sums = None
        return out

    def _add(self, dones, terminations, time_outs, diverged) -> None:
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
        self.sums = total if self.sums is None else self.sums + total


__all__ = ["EpisodeStats"]
