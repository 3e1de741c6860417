"""An extension-workflow Isaac Sim example (the "Hello Robot" flow): a BaseSample with a Jetbot.

There is no `__main__`: Isaac's Examples browser loads the class (LOAD: `setup_scene`, reset,
`setup_post_load`) and PLAY steps it. `ambulo run examples/isaac/hello_robot_sample.py
--seconds 5` does the same headless. The physics callback drives the wheels forward.
"""

import numpy as np
from isaacsim.core.prims import SingleArticulation
from isaacsim.core.utils.nucleus import get_assets_root_path
from isaacsim.core.utils.stage import add_reference_to_stage
from isaacsim.core.utils.types import ArticulationAction
from isaacsim.examples.interactive.base_sample import BaseSample


class HelloRobot(BaseSample):
    def __init__(self) -> None:
        super().__init__()

    def setup_scene(self):
        world = self.get_world()
        world.scene.add_default_ground_plane()
        assets_root_path = get_assets_root_path()
        jetbot_usd = assets_root_path + "/Isaac/Robots/Jetbot/jetbot.usd"
        add_reference_to_stage(usd_path=jetbot_usd, prim_path="/World/Fancy_Robot")
        self._jetbot = world.scene.add(SingleArticulation(prim_path="/World/Fancy_Robot", name="fancy_robot"))
        print("Num of degrees of freedom before first reset: " + str(self._jetbot.num_dof))

    async def setup_post_load(self):
        self._world = self.get_world()
        self._jetbot = self._world.scene.get_object("fancy_robot")
        print("Num of degrees of freedom after first reset: " + str(self._jetbot.num_dof))
        print("Joint Positions after first reset: " + str(self._jetbot.get_joint_positions()))
        self._jetbot_articulation_controller = self._jetbot.get_articulation_controller()
        self._world.add_physics_callback("sending_actions", callback_fn=self.send_robot_actions)

    def send_robot_actions(self, step_size):
        self._jetbot_articulation_controller.apply_action(
            ArticulationAction(joint_positions=None, joint_efforts=None, joint_velocities=np.array([10.0, 10.0]))
        )
