"""3D ground truth the older way (Isaac Sim 2022): boxes, normals and motion vectors from SyntheticDataHelper.

Written with Isaac Sim's module names only. Run it with `ambulo run examples/isaac/synthetic_helper_3d.py`
(or with Isaac Sim's python.sh). A labelled cube turned 30 degrees stands on the ground next to a wall
tilted back by 30 degrees; the viewport looks at them. The script prints each prim's 3D box (extents in
its own frame, position and corners), the normals seen on the ground, the cube's top and the wall, then
moves the viewport camera 0.1 m to its right and the cube 0.2 m along x, printing the motion vectors
each move causes. `--output_dir DIR` also saves the ground truth of each frame as DIR/frame_N.npz.
"""

import argparse

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
from omni.isaac.core import World
from omni.isaac.core.objects import VisualCuboid
from omni.isaac.core.utils.rotations import euler_angles_to_quat
from omni.isaac.core.utils.semantics import add_update_semantics
from omni.isaac.core.utils.viewports import set_camera_view
from omni.isaac.synthetic_utils import SyntheticDataHelper
from omni.kit.viewport.utility import get_active_viewport

parser = argparse.ArgumentParser()
parser.add_argument("--output_dir", default=None, help="save each frame's ground truth as frame_N.npz")
args, _ = parser.parse_known_args()

world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()
cube = world.scene.add(VisualCuboid(prim_path="/World/cube", name="cube", position=np.array([0.0, 0.0, 0.25]),
                                    orientation=euler_angles_to_quat(np.array([0.0, 0.0, 30.0]), degrees=True),
                                    scale=np.array([0.5, 0.5, 0.5]), color=np.array([0.8, 0.3, 0.1])))
world.scene.add(VisualCuboid(prim_path="/World/wall", name="wall", position=np.array([1.0, 0.5, 0.5]),
                             orientation=euler_angles_to_quat(np.array([-30.0, 0.0, 0.0]), degrees=True),
                             scale=np.array([0.8, 0.1, 0.8]), color=np.array([0.2, 0.4, 0.8])))
add_update_semantics("/World/cube", "cube")
add_update_semantics("/World/wall", "wall")
world.reset()

eye, target = np.array([0.0, -3.5, 2.0]), np.array([0.0, 0.0, 0.3])
set_camera_view(eye=eye, target=target, camera_prim_path="/OmniverseKit_Persp")
viewport = get_active_viewport()
viewport.set_texture_resolution((320, 240))

sensors = ["rgb", "depth", "instanceSegmentation", "boundingBox3D", "normals", "motion-vector", "camera"]
sd_helper = SyntheticDataHelper()
sd_helper.initialize(sensor_names=sensors, viewport_api=viewport)
frames = []


def capture(what: str) -> dict:
    world.step(render=True)
    gt = sd_helper.get_groundtruth(sensors, viewport, verify_sensor_init=False)
    frames.append(gt)
    motion = gt["motion-vector"][..., :2]
    moving = np.abs(motion).max(-1) > 0.01
    mean = (np.round(motion[moving].mean(0).astype(float), 2) + 0.0).tolist() if moving.any() else [0.0, 0.0]
    print(f"{what}: {int(moving.sum())} pixels moved, mean motion (x, y) {mean} px")
    return gt


gt = capture("first frame")
for box in gt["boundingBox3D"]:
    lo = [float(box[k]) for k in ("x_min", "y_min", "z_min")]
    hi = [float(box[k]) for k in ("x_max", "y_max", "z_max")]
    at, ldb = (np.round(v.astype(float), 3).tolist() for v in (box["transform"][3, :3], box["corners"][0]))
    print(f"{box['name']} {box['semanticLabel']}: extents {np.round(lo, 3).tolist()} to {np.round(hi, 3).tolist()} m, "
          f"at {at}, corner LDB {ldb}")
instance_ids, mapping = gt["instanceSegmentation"]
regions = {row["name"]: instance_ids == row["uniqueId"] for row in mapping}
regions["ground"] = (instance_ids == 0) & np.isfinite(gt["depth"])
for name, region in regions.items():  # the faces each prim shows, by the normals of its pixels
    faces, counts = np.unique(np.round(gt["normals"][region].astype(float), 3), axis=0, return_counts=True)
    print(f"{name}: normals " + ", ".join(f"{n.tolist()} ({c} px)" for n, c in zip(faces, counts) if c > 50))

# move the viewport 0.1 m to its right (+x here): the scene moves left in the image, by f * 0.1 / depth px
set_camera_view(eye=eye + [0.1, 0.0, 0.0], target=target + [0.1, 0.0, 0.0], camera_prim_path="/OmniverseKit_Persp")
capture("camera moved 0.1 m right")
# move the cube 0.2 m along +x (the image's right): its pixels move right, by f * 0.2 / depth px
cube.set_world_pose(position=np.array([0.2, 0.0, 0.25]))
capture("cube moved 0.2 m right")

if args.output_dir:
    from pathlib import Path

    out = Path(args.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    for i, frame in enumerate(frames):
        np.savez(out / f"frame_{i}.npz", depth=frame["depth"], normals=frame["normals"],
                 motion=frame["motion-vector"], instances=frame["instanceSegmentation"][0],
                 boxes=frame["boundingBox3D"], intrinsics=frame["camera"]["intrinsics"],
                 camera_pose=frame["camera"]["pose"], allow_pickle=True)
simulation_app.close()
