"""Camera: depth and projection against analytic geometry, boxes against masks, posing."""

import mujoco
import numpy as np
import pytest

from ambulo.core.semantics import set_semantic_label
from ambulo.engine import CpuEngine
from ambulo.sensors import Camera

BOX = mujoco.mjtGeom.mjGEOM_BOX
ALL = ("rgb", "depth", "distance_to_camera", "semantic_segmentation", "instance_segmentation",
       "normals", "bounding_box_2d_tight", "bounding_box_2d_loose", "bounding_box_3d", "visible_fraction")


def scene(boxes, num_worlds=1, **camera_kwargs):
    """Floor plane z=0 plus labelled boxes {name: (label, center, half_size)}; a world-fixed camera."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_light(pos=[0, 0, 6], dir=[0, 0, -1])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1])
    for name, (label, center, half) in boxes.items():
        body = spec.worldbody.add_body(name=name, pos=center)
        body.add_geom(type=BOX, size=half, rgba=[0.8, 0.2, 0.2, 1])
        set_semantic_label(spec, name, label)
    camera = Camera(prim_path="/World/camera", annotators=ALL, **camera_kwargs)
    camera.build(spec)
    engine = CpuEngine(spec.compile(), num_worlds, num_threads=1)
    camera.initialize(engine)
    return engine, camera


def pixel_rays_w(camera, world=0):
    """Unit-depth ray per pixel (H, W, 3) in the world frame and the camera centre."""
    k = camera.get_intrinsics_matrix()
    t_cw = camera.get_extrinsics_matrix()[world]
    w, h = camera.resolution
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    rays_c = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u, float)], -1)
    r_wc = t_cw[:3, :3].T
    return rays_c @ r_wc.T, -r_wc @ t_cw[:3, 3]


def test_depth_matches_analytic_floor_and_box_top_within_1mm():
    _engine, camera = scene({"/World/box": ("box", [0.4, 0.1, 0.3], [0.3, 0.3, 0.3])})
    camera.set_camera_view(eye=[-2.0, -1.5, 2.5], target=[0.3, 0.2, 0.0])
    frame = camera.capture(0)
    rays, centre = pixel_rays_w(camera)
    floor_t = -centre[2] / rays[..., 2]  # ray parameter at z = 0 is the depth (ray has unit z_c)
    top_t = (0.6 - centre[2]) / rays[..., 2]
    on_floor = frame["geom_ids"] == 0
    on_box = frame["instance_segmentation"] == 1
    hit = centre + top_t[..., None] * rays
    on_top = on_box & (np.abs(hit[..., 0] - 0.4) < 0.28) & (np.abs(hit[..., 1] - 0.1) < 0.28)
    assert on_floor.sum() > 10000 and on_top.sum() > 200
    assert np.abs(frame["depth"][on_floor] - floor_t[on_floor]).max() < 1e-3
    assert np.abs(frame["depth"][on_top] - top_t[on_top]).max() < 1e-3
    distance = np.linalg.norm(floor_t[..., None] * rays, axis=-1)
    assert np.abs(frame["distance_to_camera"][on_floor] - distance[on_floor]).max() < 1e-3
    # floor normals point up in the world frame
    assert np.allclose(frame["normals"][on_floor][::50], [0, 0, 1], atol=1e-3)


def test_intrinsics_project_a_known_point_into_its_mask():
    _engine, camera = scene({"/World/box": ("box", [0.5, -0.3, 0.1], [0.1, 0.1, 0.1])})
    camera.set_camera_view(eye=[-1.5, 1.0, 1.8], target=[0.0, 0.0, 0.0])
    frame = camera.capture(0)
    t_cw = camera.get_extrinsics_matrix()[0]
    point_c = t_cw[:3, :3] @ np.array([0.5, -0.3, 0.2]) + t_cw[:3, 3]  # centre of the top face
    u, v, _ = camera.get_intrinsics_matrix() @ (point_c / point_c[2])
    mask = frame["instance_segmentation"] == 1
    assert mask[round(v), round(u)]

    def pixel(point_w):
        p = t_cw[:3, :3] @ np.asarray(point_w) + t_cw[:3, 3]
        u, v, _ = camera.get_intrinsics_matrix() @ (p / p[2])
        return round(v), round(u)

    # floor points on the camera side of the box are not covered by it
    assert not mask[pixel([0.5, -0.05, 0.0])] and not mask[pixel([0.25, -0.3, 0.0])]
    # near the far top corner: 3 cm inside the box is covered, 3 cm beyond it (seen past the box) is not
    assert mask[pixel([0.57, -0.37, 0.17])] and not mask[pixel([0.63, -0.43, 0.23])]


def test_set_camera_view_puts_the_target_at_the_principal_point():
    _engine, camera = scene({"/World/box": ("box", [1.0, 2.0, 0.1], [0.1, 0.1, 0.1])}, width=321, height=241)
    camera.set_camera_view(eye=[3.0, -1.0, 2.0], target=[1.0, 2.0, 0.1])
    frame = camera.capture(0)
    assert frame["instance_segmentation"][120, 160] == 1
    k, t_cw = camera.get_intrinsics_matrix(), camera.get_extrinsics_matrix()[0]
    p = t_cw[:3, :3] @ np.array([1.0, 2.0, 0.1]) + t_cw[:3, 3]
    assert np.allclose((k @ p / p[2])[:2], [160, 120], atol=1e-9)
    pos, _ = camera.get_world_pose()
    assert np.allclose(pos[0].numpy(), [3.0, -1.0, 2.0])


def test_tight_boxes_equal_mask_boxes_and_loose_boxes_contain_them():
    boxes = {f"/World/b{i}": ("crate" if i % 2 else "can", [0.6 * i - 1.2, 0.4 * (i % 2), 0.15],
                              [0.15, 0.12, 0.15]) for i in range(5)}
    _engine, camera = scene(boxes)
    camera.set_camera_view(eye=[0.0, -3.0, 1.6], target=[0.0, 0.2, 0.0])
    frame = camera.capture(0)
    inst = frame["instance_segmentation"]
    tight = frame["bounding_box_2d_tight"]
    loose = dict(zip(frame["bounding_box_2d_loose"]["instance_id"], frame["bounding_box_2d_loose"]["box"]))
    assert len(tight["instance_id"]) == 5
    for iid, box, pixels in zip(tight["instance_id"], tight["box"], tight["pixels"]):
        ys, xs = np.nonzero(inst == iid)
        assert list(box) == [xs.min(), ys.min(), xs.max(), ys.max()] and pixels == len(xs)
        lb = loose[iid]
        assert lb[0] <= box[0] + 0.5 and lb[1] <= box[1] + 0.5 and lb[2] >= box[2] - 0.5 and lb[3] >= box[3] - 0.5
    # semantic ids follow sorted labels: can=1, crate=2
    sem = frame["semantic_segmentation"]
    assert set(np.unique(sem)) == {0, 1, 2}
    assert np.all(sem[inst == 1] == 1) and np.all(sem[inst == 2] == 2)


def test_unoccluded_box_has_loose_equal_tight_and_3d_box_matches_geometry():
    _engine, camera = scene({"/World/box": ("box", [0.2, 0.3, 0.25], [0.2, 0.1, 0.25])})
    camera.set_camera_view(eye=[1.5, -1.5, 1.5], target=[0.2, 0.3, 0.25])
    frame = camera.capture(0)
    tight = frame["bounding_box_2d_tight"]["box"][0]
    loose = frame["bounding_box_2d_loose"]["box"][0]
    # a convex box's silhouette is the hull of its projected corners: boxes agree to a pixel
    assert np.abs(loose - (tight + [-0.5, -0.5, 0.5, 0.5])).max() < 1.0
    assert frame["visible_fraction"][0] == pytest.approx(1.0)
    b3 = frame["bounding_box_3d"]
    assert np.allclose(b3["center_w"][0], [0.2, 0.3, 0.25]) and np.allclose(b3["half_extent"][0], [0.2, 0.1, 0.25])
    t_cw = camera.get_extrinsics_matrix()[0]
    assert np.allclose(b3["center_c"][0], t_cw[:3, :3] @ [0.2, 0.3, 0.25] + t_cw[:3, 3])


def test_occlusion_partial_and_full():
    boxes = {
        "/World/front": ("wall", [0.0, 0.0, 0.5], [0.05, 0.6, 0.5]),
        "/World/half_hidden": ("box", [0.5, 0.55, 0.2], [0.2, 0.2, 0.2]),
        "/World/hidden": ("box", [0.5, -0.2, 0.15], [0.1, 0.1, 0.1]),
    }
    _engine, camera = scene(boxes)
    camera.set_camera_view(eye=[-2.5, 0.0, 0.5], target=[0.5, 0.0, 0.3])
    frame = camera.capture(0)
    ids = {camera.table.names[i - 1]: i for i in range(1, 4)}
    visible = set(frame["bounding_box_2d_tight"]["instance_id"])
    assert ids["/World/hidden"] not in visible and ids["/World/half_hidden"] in visible
    fraction = frame["visible_fraction"]
    assert fraction[ids["/World/hidden"] - 1] == 0.0
    assert 0.05 < fraction[ids["/World/half_hidden"] - 1] < 0.95
    assert fraction[ids["/World/front"] - 1] == pytest.approx(1.0)


def test_worlds_have_their_own_pose_and_frames_are_deterministic():
    _engine, camera = scene({"/World/box": ("box", [0.0, 0.0, 0.2], [0.2, 0.2, 0.2])}, num_worlds=2)
    camera.set_camera_view(eye=[2.0, 0.0, 1.0], target=[0, 0, 0.2], world_ids=[0])
    camera.set_camera_view(eye=[0.0, 2.0, 3.0], target=[0, 0, 0.2], world_ids=[1])
    frame = camera.get_current_frame()
    assert tuple(frame["rgb"].shape) == (2, 240, 320, 3) and frame["rgb"].dtype.is_floating_point is False
    assert not np.array_equal(frame["rgb"][0].numpy(), frame["rgb"][1].numpy())
    again = camera.capture(1)
    assert np.array_equal(again["rgb"], frame["rgb"][1].numpy())
    assert np.array_equal(again["depth"], frame["depth"][1].numpy())


def test_mounted_camera_follows_its_body():
    spec = mujoco.MjSpec()
    spec.worldbody.add_light(pos=[0, 0, 6], dir=[0, 0, -1])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1])
    robot = spec.worldbody.add_body(name="/World/robot", pos=[0, 0, 1], mocap=True)
    robot.add_geom(type=BOX, size=[0.05, 0.05, 0.05], contype=0, conaffinity=0)
    # looks down: world-convention camera (x forward) pitched 90 deg about y
    camera = Camera(prim_path="/World/robot/camera", offset_pos=(0.1, 0, 0),
                    offset_quat=(np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0))
    camera.build(spec)
    engine = CpuEngine(spec.compile(), 1, num_threads=1)
    camera.initialize(engine)
    engine.mocap_pos[0, 0] = engine.mocap_pos.new_tensor([2.0, 1.0, 1.5])
    engine.forward()
    pos, _quat = camera.get_world_pose(convention="opengl")
    assert np.allclose(pos[0].numpy(), [2.1, 1.0, 1.5])
    depth = camera.capture(0)["depth"]
    assert depth[120, 160] == pytest.approx(1.5, abs=1e-3)
    # the model camera (what viewers use) sits on the same pose after kinematics
    data = engine.get_data(0)
    assert np.allclose(data.cam_xpos[camera.cam_id], [2.1, 1.0, 1.5])


def test_bad_prim_path_and_annotator_give_clear_errors():
    spec = mujoco.MjSpec()
    with pytest.raises(ValueError, match="names no body or site"):
        Camera(prim_path="/World/nothing/here/camera").build(spec)
    with pytest.raises(ValueError, match="unknown camera annotator"):
        Camera(prim_path="/World/cam", annotators=("rgb", "lidar"))
