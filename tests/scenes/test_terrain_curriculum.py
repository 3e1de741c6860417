"""The terrain curriculum moves levels as legged_gym's does, for index and mask row selectors alike."""

import pytest
import torch

from ambulo.scenes.terrain import TerrainCfg, TerrainCurriculum, TerrainCurriculumCfg, generate, weighted_columns

GRID = generate(TerrainCfg(num_levels=3, tile_size_m=4.0, platform_size_m=1.0, border_m=1.0,
                           kinds=("flat", "stairs_up")))


def curriculum(levels, **cfg):
    c = TerrainCurriculum(TerrainCurriculumCfg(init_level=0, **cfg), GRID, len(levels),
                          torch.Generator().manual_seed(0), "cpu")
    c.levels[:] = torch.tensor(levels)
    c.origins_w[:] = c.centers_w[c.levels, c.kinds]
    return c


# env:        0 far      1 short of its commands  2 short, told to stand  3 far at the top  4 short at 0
LEVELS = [1, 1, 1, 2, 0]
DISTANCE_M = torch.tensor([2.5, 0.5, 0.1, 3.0, 0.2])  # up when > 0.5 * 4 m = 2 m
COMMAND_PATH_M = torch.tensor([6.0, 4.0, 0.0, 5.0, 6.0])  # down when distance < 0.5 * path (and not up)


@pytest.mark.parametrize("selector", ["indices", "mask"])
def test_levels_move_up_down_and_wrap_from_the_top(selector):
    c = curriculum(LEVELS)
    ids = torch.tensor([0, 1, 2, 3, 4])
    rows = ids if selector == "indices" else torch.ones(5, dtype=torch.bool)
    c.update(rows, DISTANCE_M, COMMAND_PATH_M)
    levels = c.levels.tolist()
    assert levels[:3] == [2, 0, 1]
    assert 0 <= levels[3] <= 2  # passed the hardest level: a random one
    assert levels[4] == 0  # no level below 0
    assert torch.equal(c.origins_w, c.centers_w[c.levels, c.kinds])


def test_only_the_selected_envs_move():
    c = curriculum(LEVELS)
    c.update(torch.tensor([1]), DISTANCE_M, COMMAND_PATH_M)
    assert c.levels.tolist() == [1, 0, 1, 2, 0]
    mask = torch.tensor([True, False, False, False, False])
    c.update(mask, DISTANCE_M, COMMAND_PATH_M)
    assert c.levels.tolist() == [2, 0, 1, 2, 0]


def test_disabled_curriculum_and_fixed_first_levels():
    c = curriculum(LEVELS, enabled=False)
    c.update(None, DISTANCE_M, COMMAND_PATH_M)
    assert c.levels.tolist() == LEVELS
    hardest = TerrainCurriculum(TerrainCurriculumCfg(init_level=-1), GRID, 4, torch.Generator(), "cpu")
    assert hardest.levels.tolist() == [2, 2, 2, 2] and hardest.kinds.tolist() == [0, 1, 0, 1]
    drawn = TerrainCurriculum(TerrainCurriculumCfg(max_init_level=1), GRID, 64, torch.Generator().manual_seed(1),
                              "cpu")
    assert set(drawn.levels.tolist()) == {0, 1}


def test_the_command_rule_moves_up_robots_that_covered_what_they_were_asked_without_falling():
    # tile 4 m: legged_gym's rule needs > 2 m; the command rule 0.8 of an ask of at least 2 m (1.6 m)
    # env:               0 tracked  1 tracked, fell  2 asked too little  3 short of 0.8  4 exactly 0.8
    distance_m = torch.tensor([1.8, 1.8, 1.4, 1.5, 1.6])
    asked_m = torch.tensor([2.0, 2.0, 1.5, 2.0, 2.0])
    fell = torch.tensor([False, True, False, False, False])
    c = curriculum([1, 1, 1, 1, 1])
    c.update(None, distance_m, asked_m, fell)
    assert c.levels.tolist() == [2, 1, 1, 1, 2]
    legged_gym = curriculum([1, 1, 1, 1, 1], up_command_fraction=None)
    legged_gym.update(None, distance_m, asked_m, fell)
    assert legged_gym.levels.tolist() == [1, 1, 1, 1, 1]
    no_falls_given = curriculum([1, 1, 1, 1, 1])
    no_falls_given.update(None, distance_m, asked_m)
    assert no_falls_given.levels.tolist() == [2, 2, 1, 1, 2]


def test_kind_weights_share_the_envs_by_largest_remainder_interleaved():
    stones_twice = weighted_columns((1, 1, 1, 1, 1, 1, 2), 1024)
    assert torch.bincount(stones_twice).tolist() == [128] * 6 + [256]
    assert set(stones_twice[:8].tolist()) == set(range(7))  # the first envs already hold every column
    # 10 envs at 1:1:1 -> 3.33 each: the one left over goes to the lowest column of the tied remainders
    assert torch.bincount(weighted_columns((1, 1, 1), 10)).tolist() == [4, 3, 3]
    assert torch.bincount(weighted_columns((1, 2), 10)).tolist() == [3, 7]  # 3.33, 6.67: the larger remainder
    # 8 at 0:1:3 -> 0, 2, 6; column 2's six spread around column 1's two (at 1/4 and 3/4 of the way)
    assert weighted_columns((0, 1, 3), 8).tolist() == [2, 1, 2, 2, 2, 1, 2, 2]
    assert weighted_columns((1, 1, 1), 9).tolist() == [0, 1, 2] * 3  # equal shares: i % num_kinds


def test_the_curriculum_places_envs_by_kind_weights_and_names_a_wrong_count():
    c = TerrainCurriculum(TerrainCurriculumCfg(kind_weights=(1.0, 3.0), init_level=-1), GRID, 8,
                          torch.Generator(), "cpu")
    assert torch.bincount(c.kinds).tolist() == [2, 6]
    assert torch.equal(c.origins_w, c.centers_w[c.levels, c.kinds])
    with pytest.raises(ValueError, match=r"3 weights for the 2 columns of terrain.kinds \['flat', 'stairs_up'\]"):
        TerrainCurriculum(TerrainCurriculumCfg(kind_weights=(1.0, 1.0, 2.0)), GRID, 8, torch.Generator(), "cpu")
    with pytest.raises(ValueError, match="at least one kind a weight above 0"):
        TerrainCurriculumCfg(kind_weights=(0.0, 0.0))
