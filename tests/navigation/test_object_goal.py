"""Object goals: a detection's 3D point from depth and pose, views fused, the stance that faces it."""

import math

import numpy as np
import pytest

from ambulo.maps import Grid2D
from ambulo.navigation.object_goal import ObjectMap, ObjectMapCfg, localize, standoff_goal


def camera_pose_wc(xyz, yaw_rad, pitch_down_rad):
    """Camera-to-world (OpenCV axes: x right, y down, z forward) of a camera at ``xyz`` looking along yaw, pitched down."""
    cy, sy, cp, sp = math.cos(yaw_rad), math.sin(yaw_rad), math.cos(pitch_down_rad), math.sin(pitch_down_rad)
    forward = np.array([cp * cy, cp * sy, -sp])
    right = np.array([sy, -cy, 0.0])
    down = np.cross(forward, right)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, down, forward], 1)
    pose[:3, 3] = xyz
    return pose


def render_box(pose_wc, k, hw, center, half, yaw_rad):
    """Depth (z along the optical axis) and the box's mask: rays against a yawed box and the floor z = 0."""
    h, w = hw
    v, u = np.mgrid[0:h, 0:w].astype(float)
    rays_c = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u)], -1)
    rays_w = rays_c @ pose_wc[:3, :3].T
    o = pose_wc[:3, 3]
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])  # box to world
    o_b, d_b = (o - center) @ rot, rays_w @ rot
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-np.asarray(half) - o_b) / d_b, (np.asarray(half) - o_b) / d_b
    t_near = np.nanmax(np.minimum(t1, t2), -1)
    t_far = np.nanmin(np.maximum(t1, t2), -1)
    hit_box = (t_near <= t_far) & (t_near > 0)
    t_floor = np.where(rays_w[..., 2] < 0, -o[2] / rays_w[..., 2], np.inf)
    t = np.where(hit_box & (t_near < t_floor), t_near, t_floor)
    mask = hit_box & (t_near < t_floor)
    depth = np.where(np.isfinite(t), t, 0.0).astype(np.float32)  # z-depth = t with rays of z = 1 in the camera
    return depth, mask


K = np.array([[262.5, 0, 159.5], [0, 262.5, 119.5], [0, 0, 1.0]])


@pytest.mark.parametrize("use_mask", [True, False])
def test_a_box_seen_by_a_posed_camera_is_placed_on_its_visible_surface(use_mask):
    center, half, box_yaw = np.array([2.4, 1.3, 0.45]), (0.4, 0.3, 0.45), 0.5
    pose = camera_pose_wc((0.3, 0.2, 1.5), math.atan2(1.1, 2.1), math.radians(18))
    depth, mask = render_box(pose, K, (240, 320), center, half, box_yaw)
    assert mask.sum() > 500
    v, u = np.nonzero(mask)
    box_px = (u.min(), v.min(), u.max() + 1, v.max() + 1)
    point = localize(depth, K, pose, box_px, mask if use_mask else None)
    assert point is not None
    c, s = math.cos(box_yaw), math.sin(box_yaw)
    local = (point - center) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    # on the box (its visible faces: within 3 cm of its extent) and nearer than its far half
    assert (np.abs(local) <= np.asarray(half) + 0.03).all(), local
    assert np.linalg.norm(point[:2] - pose[:2, 3]) < np.linalg.norm(center[:2] - pose[:2, 3])


def test_a_detection_with_no_depth_on_it_gives_no_point():
    pose = camera_pose_wc((0.0, 0.0, 1.5), 0.0, math.radians(18))
    depth = np.zeros((240, 320), np.float32)
    assert localize(depth, K, pose, (100, 100, 140, 140)) is None


def test_views_of_one_object_fuse_and_a_single_false_view_is_not_confirmed():
    objects = ObjectMap(ObjectMapCfg(merge_radius_m=0.5, min_views=3, min_score=0.4))
    rng = np.random.default_rng(0)
    for _ in range(4):
        objects.add("bed", np.array([2.0, 1.0, 0.3]) + rng.normal(0, 0.05, 3), 0.8)
    objects.add("bed", np.array([5.0, -1.0, 0.3]), 0.9)  # one stray view elsewhere
    objects.add("bed", np.array([2.0, 1.0, 0.3]), 0.2)  # too weak to count
    (track,) = objects.confirmed("bed")
    assert track.views == 4 and np.linalg.norm(track.point_w[:2] - [2.0, 1.0]) < 0.1
    assert len(objects.tracks) == 2 and objects.confirmed("sofa") == []


def test_the_stance_is_free_within_range_on_the_robots_side_and_faces_the_object():
    occ = np.zeros((80, 80), bool)
    occ[35:45, 35:45] = True  # a 0.5 m table at the centre of a 4 m room (5 cm cells)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    grid = Grid2D.from_masks(occ, origin_xy_m=(0.0, 0.0), resolution_m=0.05)
    obj = np.array([1.75, 2.0])  # the table's west face, seen from the west
    goal, yaw = standoff_goal(obj, (0.5, 2.0), grid, distance_range_m=(0.45, 0.8), clearance_m=0.3)
    assert 0.45 <= np.linalg.norm(goal - obj) <= 0.8
    assert goal[0] < obj[0]  # the side it was seen from
    assert abs(math.atan2(obj[1] - goal[1], obj[0] - goal[0]) - yaw) < 1e-9
    iy, ix = grid.cell_of(goal)
    assert not occ[max(iy - 5, 0):iy + 6, max(ix - 5, 0):ix + 6].any()  # 0.25 m of room all round


def test_apartment_furniture_labels_and_goal_names():
    from ambulo.scenes.apartment_labels import canonical_label, furniture_label

    assert furniture_label("/World/apartment/room_2/armchair_3") == "armchair"
    assert furniture_label("/World/apartment/room_2/round_table_1/top") == "table"
    assert furniture_label("/World/apartment/room_2/table_4/leg_0") is None  # the top carries the label
    assert furniture_label("/World/apartment/room_2/lamp_5/pole") is None
    assert furniture_label("/World/apartment/walls/wall_3") is None
    assert canonical_label("Chair") == "armchair" and canonical_label("potted plant") == "plant"
    with pytest.raises(ValueError, match="known"):
        canonical_label("piano")
