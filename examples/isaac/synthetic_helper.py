"""Ground truth the older way (Isaac Sim 2022): a World, labelled cubes, SyntheticDataHelper.

Written with Isaac Sim's module names only. Run it with `ambulo run examples/isaac/synthetic_helper.py`
(or with Isaac Sim's python.sh): it aims the viewport at three labelled cubes on the ground and prints
each cube's tight 2D box and the depth at the box centre.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
from omni.isaac.core import World
from omni.isaac.core.objects import VisualCuboid
from omni.isaac.core.utils.semantics import add_update_semantics
from omni.isaac.core.utils.viewports import set_camera_view
from omni.isaac.synthetic_utils import SyntheticDataHelper
from omni.kit.viewport.utility import get_active_viewport

world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()
for name, x, color in (("left", -1.0, (1, 0, 0)), ("middle", 0.0, (0, 1, 0)), ("right", 1.0, (0, 0, 1))):
    world.scene.add(VisualCuboid(prim_path=f"/World/{name}_cube", name=name, position=np.array([x, 0.0, 0.25]),
                                 scale=np.array([0.5, 0.5, 0.5]), color=np.array(color, float)))
    add_update_semantics(f"/World/{name}_cube", "cube")
world.reset()

set_camera_view(eye=np.array([0.0, -4.0, 1.5]), target=np.array([0.0, 0.0, 0.25]),
                camera_prim_path="/OmniverseKit_Persp")
viewport = get_active_viewport()
viewport.set_texture_resolution((256, 192))

sensors = ["rgb", "depth", "boundingBox2DTight", "semanticSegmentation", "camera"]
sd_helper = SyntheticDataHelper()
sd_helper.initialize(sensor_names=sensors, viewport_api=viewport)
world.step(render=True)
gt = sd_helper.get_groundtruth(sensors, viewport, verify_sensor_init=False)

print("rgb", gt["rgb"].shape, "labels", sd_helper.get_semantic_label_map(sd_helper.get_semantic_ids(gt["semanticSegmentation"])))
for box in np.sort(gt["boundingBox2DTight"], order="x_min"):
    u, v = (box["x_min"] + box["x_max"]) // 2, (box["y_min"] + box["y_max"]) // 2
    print(f"{box['name']} {box['semanticLabel']}: box ({box['x_min']}, {box['y_min']})-({box['x_max']}, "
          f"{box['y_max']}), depth at centre {gt['depth'][v, u]:.2f} m")
simulation_app.close()
