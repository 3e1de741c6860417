"""The terrain curriculum (legged_gym's): robots that walked far move to harder tiles.

Every env has a level (a row of the terrain grid) and a kind (a column, fixed: env ``i`` takes
column ``i % num_kinds``, or by ``kind_weights``). When an episode ends, its env moves up a level if the robot got farther
than ``up_distance_fraction`` of a tile from where it started (legged_gym's rule), or if it covered
``up_command_fraction`` of how far its commands would have carried it, they asked for at least
``up_min_command_m`` and it did not fall (the command rule, below); and down one if it ended closer
to its start than ``down_command_fraction`` of its commands' displacement (not their path length:
commands turn and reverse; robots told to stand never move down for standing). A robot that passes
the hardest level goes to a random level, so the hardest tiles never hold the whole population
(legged_gym does the same).

Why the command rule: legged_gym's half a tile (4 m) is out of reach of most commands. A perfect
tracker of humanoid-rough's commands at the start of training (the command curriculum's 0.4 scale)
ends 2.1 m from its start on average and passes 4 m in 6.5 % of its episodes
(``benchmarks/curriculum_demotions.py``); the command curriculum widens the ranges only while
tracking is good, which the terrain makes hard, so the two curricula held each other back: mean
level 1.96 -> 2.30 of 9 after 8 minutes on an H200 (session 13), while evaluation is on level 9.

Columns can be shared unequally in training (``kind_weights``): session 27's FastSAC runs held
every kind but the stepping stones near level 6 of 9 from iteration ~1500, while the stones, on
1/7 of the envs, were still climbing at 4 of 9 when the runs ended and gave most of the falls the
criterion counts. Evaluation always shares the kinds equally. It did not help FastSAC (session 28:
the stones fell more, 0.56 of their hardest episodes against 0.45, as the policy attempted them), so
it stays off by default.

Everything is (N,) tensors written through row selectors (``core.rows``): no per-env loop, no
host sync.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ...core.rows import num_rows, put_rows, take_rows
from ...utils.validate import Checked, rule
from .generator import TerrainGrid


@dataclass(kw_only=True)
class TerrainCurriculumCfg(Checked):
    enabled: bool = True
    """Move envs between levels at resets; False keeps every env on its first level."""
    init_level: int | None = field(default=None, metadata=rule(signed=True))
    """Every env's first level (negative counts from the hardest: -1 is the hardest); None draws
    it uniformly in [0, ``max_init_level``]."""
    max_init_level: int = 4
    """Highest first level when ``init_level`` is None (clipped to the grid)."""
    up_distance_fraction: float = 0.5
    """Move up after walking farther than this share of a tile's edge (legged_gym: a half)."""
    down_command_fraction: float = 0.5
    """Move down after ending closer to the start than this share of the commanded displacement."""
    up_command_fraction: float | None = field(default=0.8, metadata=rule(minimum=0.0, strict=True))
    """Also move up after covering this share of the commanded displacement without a fall, when the
    commands asked for at least ``up_min_command_m``; None: legged_gym's distance rule only."""
    kind_weights: tuple[float, ...] | None = field(default=None, metadata=rule(minimum=0.0))
    """Share of the envs on each column of ``TerrainCfg.kinds``, in its order (relative weights: (1, 1, 2)
    puts a half of the envs on the third column); None: equal shares, env ``i`` on column ``i % num_kinds``.
    Training only: a rough task's play and evaluation take none of the training curriculum's settings
    (``RoughTerrainCfg.curriculum`` is marked ``PLAY_KEEPS``) and judge every kind on an equal share."""
    up_min_command_m: float = field(default=2.0, metadata=rule(minimum=0.0))
    """The command rule judges only episodes whose commands asked for this much displacement, m: a
    robot starts on a platform whose edge is 1 m away (``TerrainCfg.platform_size_m``), so 2 m takes it
    over a metre of the tile's terrain."""

    def __post_init__(self):
        super().__post_init__()  # each weight finite and >= 0 first: the sum below needs it
        if self.kind_weights is not None and not sum(self.kind_weights) > 0:
            raise ValueError(f"TerrainCurriculumCfg.kind_weights {list(self.kind_weights)} gives no env a "
                             "column; give at least one kind a weight above 0")


def check_kind_weights(weights: tuple[float, ...] | None, kinds: tuple[str, ...], key: str = "kind_weights") -> None:
    """ValueError unless ``weights`` (a ``TerrainCurriculumCfg.kind_weights``, at config ``key``) is None or has
    one weight per column of ``kinds`` (``TerrainCfg.kinds``). A task's cfg checks it as it is built
    (``envs.terrain_ground.TerrainGroundCfg``), the curriculum again for a caller that builds one alone."""
    if weights is not None and len(weights) != len(kinds):
        raise ValueError(f"{key} has {len(weights)} weights for the {len(kinds)} columns of terrain.kinds "
                         f"{list(kinds)}; give one weight per column, in order (set terrain.kinds first when "
                         "changing both)")


def weighted_columns(weights: tuple[float, ...], num_envs: int) -> torch.Tensor:
    """(num_envs,) int64 each env's column when column ``k`` takes a ``weights[k] / sum(weights)`` share
    of the envs: the counts rounded by largest remainder (ties to the lower column), the columns
    interleaved in env order (column ``k``'s ``j``-th env sits at ``(j + 1/2) / count_k`` of the way), so
    the first envs already hold every column in about its share."""
    w = torch.tensor(weights, dtype=torch.float64)
    exact = w / w.sum() * num_envs
    counts = exact.floor().long()
    short = num_envs - int(counts.sum())
    # stable sort by descending remainder: equal remainders keep column order
    order = torch.sort(exact - counts, descending=True, stable=True).indices
    counts[order[:short]] += 1
    columns = torch.repeat_interleave(torch.arange(len(weights)), counts)
    place = torch.cat([(torch.arange(c, dtype=torch.float64) + 0.5) / c for c in counts.tolist() if c > 0])
    return columns[torch.sort(place, stable=True).indices]


class TerrainCurriculum:
    """Per-env terrain levels and start positions.

    Attributes:
      levels: (N,) int64 level of each env.
      kinds: (N,) int64 column (sub-terrain kind) of each env.
      origins_w: (N, 3) float32 world position of each env's tile centre on its platform, m.
    """

    def __init__(self, cfg: TerrainCurriculumCfg, grid: TerrainGrid, num_envs: int,
                 generator: torch.Generator, device: torch.device | str):
        self.cfg, self.num_envs, self.generator = cfg, num_envs, generator
        self.device = torch.device(device)
        self.num_levels, num_kinds = grid.num_levels, grid.num_kinds
        self.max_level = self.num_levels - 1
        self.tile_size_m = float(grid.cfg.tile_size_m)
        self.centers_w = torch.as_tensor(grid.tile_centers_w, dtype=torch.float32, device=self.device)
        check_kind_weights(cfg.kind_weights, grid.cfg.kinds)
        if cfg.kind_weights is None:
            self.kinds = torch.arange(num_envs, device=self.device) % num_kinds
        else:
            self.kinds = weighted_columns(cfg.kind_weights, num_envs).to(self.device)
        if cfg.init_level is None:
            top = min(cfg.max_init_level, self.max_level)
            self.levels = torch.randint(0, top + 1, (num_envs,), generator=generator, device=self.device)
        else:
            level = cfg.init_level % self.num_levels if cfg.init_level < 0 else min(cfg.init_level, self.max_level)
            self.levels = torch.full((num_envs,), level, dtype=torch.long, device=self.device)
        self.origins_w = self.centers_w[self.levels, self.kinds]

    def update(self, rows: torch.Tensor | None, distance_m: torch.Tensor, command_distance_m: torch.Tensor,
               fell: torch.Tensor | None = None) -> None:
        """Move the envs ``rows`` selects (their episodes ended) up or down a level.

        ``distance_m``: (N,) how far each robot got from its start, m (horizontal);
        ``command_distance_m``: (N,) how far from its start its commands would have carried it
        (the norm of the commanded velocity integrated in the world frame), m;
        ``fell``: (N,) bool, whose episode ended in a fall (None: none did)."""
        if not self.cfg.enabled:
            return
        n = num_rows(rows, self.num_envs)
        level = take_rows(self.levels, rows)
        up, down = self.moves(take_rows(distance_m, rows), take_rows(command_distance_m, rows),
                              None if fell is None else take_rows(fell, rows))
        level = level + up.long() - down.long()
        # always drawn (n values), so the generator's stream does not depend on who passed
        anywhere = torch.randint(0, self.num_levels, (n,), generator=self.generator, device=self.device)
        level = torch.where(level > self.max_level, anywhere, level.clamp(min=0))
        put_rows(self.levels[:, None], slice(None), level[:, None], rows)
        origins = self.centers_w[level, take_rows(self.kinds, rows)]
        put_rows(self.origins_w, slice(None), origins, rows)

    def moves(self, distance_m: torch.Tensor, command_distance_m: torch.Tensor,
              fell: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(up, down): (n,) bool, which of the episodes that ended ``distance_m`` (n,) from their start,
        m, after commands that would have carried them ``command_distance_m`` (n,), m, move up a level
        and which down (the rules of the module docstring); ``fell`` (n,) bool: which ended in a fall."""
        cfg = self.cfg
        up = distance_m > cfg.up_distance_fraction * self.tile_size_m
        if cfg.up_command_fraction is not None:
            tracked = (command_distance_m >= cfg.up_min_command_m) \
                & (distance_m >= cfg.up_command_fraction * command_distance_m)
            up = up | (tracked if fell is None else tracked & ~fell)
        down = (distance_m < self.cfg.down_command_fraction * command_distance_m) & ~up
        return up, down

    def mean_level(self) -> torch.Tensor:
        """() float32 mean level over the envs (a device scalar, for logging)."""
        return self.levels.float().mean()

    def mean_level_by_group(self, group: torch.Tensor, num_groups: int) -> torch.Tensor:
        """(num_groups,) float32 mean level of each group's envs (``group``: (N,) int64 on the device,
        each env's group; nan for a group without envs), on the device, for logging."""
        sums = torch.zeros(num_groups, device=self.device).index_add_(0, group, self.levels.float())
        return sums / torch.bincount(group, minlength=num_groups).float()


__all__ = ["TerrainCurriculum", "TerrainCurriculumCfg", "check_kind_weights", "weighted_columns"]
