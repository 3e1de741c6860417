"""NavWorld on a user's MJCF world: ground-truth occupancy by the body-band rule, collision
events (not steps), falls."""

import math

import numpy as np
import torch

from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.ground_truth import world_occupancy
from ambulo.policies.walking import WalkingPolicy


def _cells_meeting_box(grid, x0, y0, x1, y1):
    """Hand count: cells whose square (less 1 um a side) meets the rectangle [x0, x1] x [y0, y1]."""
    (ox, oy), r = grid.origin_xy_m, grid.resolution_m
    ix0, ix1 = math.floor((x0 - ox + 1e-6) / r), math.floor((x1 - ox - 1e-6) / r)
    iy0, iy1 = math.floor((y0 - oy + 1e-6) / r), math.floor((y1 - oy - 1e-6) / r)
    return {(iy, ix) for iy in range(iy0, iy1 + 1) for ix in range(ix0, ix1 + 1)}


def test_user_world_occupancy_follows_the_body_band_rule(room):
    world = NavWorld.from_file(room, start_pose=(0.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    grid = world.occupancy
    occ = grid.occupied()
    # the crate: exactly the cells its 0.6 x 0.4 m footprint meets
    crate = _cells_meeting_box(grid, 1.2, 0.7, 1.8, 1.1)
    near = {(iy, ix) for iy in range(grid.cell_of((0, 0.5))[0], grid.cell_of((0, 1.5))[0] + 1)
            for ix in range(grid.cell_of((1.0, 0))[1], grid.cell_of((2.0, 0))[1] + 1)}
    assert {c for c in near if occ[c]} == crate
    # the post: a disc of 0.1 m: its centre cell, not a cell 0.15 m away
    assert occ[grid.cell_of((1.5, -1.0))] and not occ[grid.cell_of((1.5, -1.16))]
    # the rail lies along x at hip height: from x = -0.45 to 0.45
    assert occ[grid.cell_of((0.4, -1.5))] and not occ[grid.cell_of((0.0, -1.58))]
    assert not occ[grid.cell_of((0.52, -1.5))]
    # the rug (1 cm) is walked over; the shelf (bottom at 1.95 m) passes over the head
    assert not occ[grid.cell_of((3.0, 0.0))]
    assert not occ[grid.cell_of((-1.5, 1.0))]
    # the robot's own geoms are not obstacles
    assert not occ[grid.cell_of((0.0, 0.0))]
    world.close()


def test_occupancy_without_robot_matches_with_robot(room):
    import mujoco

    spec = mujoco.MjSpec.from_file(str(room))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bare = world_occupancy(model, data, include_xy_m=np.array([[0.0, 0.0]]))
    world = NavWorld.from_file(room, start_pose=(0.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    assert bare.shape == world.occupancy.shape
    assert np.array_equal(bare.occupancy, world.occupancy.occupancy)
    world.close()


def _stand(world, seconds):
    policy = WalkingPolicy(world.robot)
    policy.reset()
    world.engine.forward()
    for _ in range(int(seconds / world.dt_s)):
        policy.forward(world.dt_s, (0.0, 0.0, 0.0))
        world.step()
    return policy


def test_a_touching_obstacle_is_one_collision_event_not_one_per_step(room):
    """The robot stands with its left arm against the north wall (its face 0.22 m to the left of
    the pelvis; the arm reaches 0.24 m): one event naming the wall over a second of standing;
    standing in the open: none."""
    world = NavWorld.from_file(room, start_pose=(1.0, 1.95 - 0.22, 0.0), cfg=NavWorldCfg(record_gyro=False))
    _stand(world, 1.0)
    assert [name for _, name in world.collisions] == ["wall_north"]
    assert len(world.collision_parts) == 1 and "left" in world.collision_parts[0], world.collision_parts
    assert not world.fell
    world.close()
    free = NavWorld.from_file(room, start_pose=(0.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    _stand(free, 1.0)
    assert free.collisions == [] and not free.fell
    free.close()


def test_a_fall_is_detected(room):
    world = NavWorld.from_file(room, start_pose=(0.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    policy = WalkingPolicy(world.robot)
    policy.reset()
    world.engine.forward()
    # limp joints (zero targets would hold a pose): a hard shove and no policy
    vel = torch.zeros(1, 3, dtype=torch.float64)
    vel[0, 0] = 3.0
    world.robot.write_root_velocity(lin_vel_w=vel)
    for _ in range(400):
        world.step()
    assert world.fell
    world.close()
