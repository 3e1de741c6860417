"""The Isaac module names: answered by ambulo inside ``isaac_names()`` only, with clear misses."""

import importlib
import sys

import numpy as np
import pytest

from ambulo.isaac import IsaacNameError, isaac_names
from ambulo.isaac import names as table


def test_isaac_names_exist_only_inside_the_context():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("isaacsim.core.api")
    with isaac_names():
        from isaacsim.core.api import World

        import ambulo.sim

        assert World is ambulo.sim.World
    assert not [m for m in sys.modules if m.split(".")[0] in ("isaacsim", "omni", "carb")]
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("isaacsim")


def test_new_and_old_module_names_give_the_same_objects():
    with isaac_names():
        from isaacsim.core.api.objects import DynamicCuboid as new
        from isaacsim.core.prims import SingleArticulation
        from omni.isaac.core.articulations import Articulation
        from omni.isaac.core.objects import DynamicCuboid as old

        assert new is old
        assert SingleArticulation is Articulation
        import isaacsim.robot.wheeled_robots.controllers.differential_controller as dc

        assert dc.DifferentialController.__module__ == "ambulo.sim.wheeled"


def test_every_table_entry_resolves_to_an_ambulo_object():
    with isaac_names():
        for module, provided in table.MODULES.items():
            imported = importlib.import_module(module)
            for name in provided:
                assert getattr(imported, name) is not None, f"{module}.{name}"


def test_a_name_ambulo_lacks_fails_at_the_import_line_with_the_alternative():
    with isaac_names():
        with pytest.raises(IsaacNameError, match="DynamicCone.*cylinders and capsules"):
            from isaacsim.core.api.objects import DynamicCone  # noqa: F401
        with pytest.raises(IsaacNameError, match="did you mean DynamicCuboid"):
            from isaacsim.core.api.objects import DynamicCuboidd  # noqa: F401


def test_a_module_ambulo_lacks_names_the_closest_one():
    with isaac_names():
        with pytest.raises(IsaacNameError, match="isaacsim.core.api.robot.*did you mean isaacsim.core.api.robots"):
            importlib.import_module("isaacsim.core.api.robot")
        with pytest.raises(IsaacNameError, match="omni.isaac.dynamic_control"):
            importlib.import_module("omni.isaac.dynamic_control")


def test_carb_settings_and_logging():
    with isaac_names():
        import carb

        settings = carb.settings.get_settings()
        settings.set_int("/physics/numThreads", 2)
        assert settings.get("/physics/numThreads") == 2
        carb.log_info("hello")
        assert carb.Float3(1, 2, 3) == (1.0, 2.0, 3.0)


class TestRotations:
    """Isaac's conventions (SciPy's): extrinsic "xyz" is R = Rz Ry Rx, intrinsic "XYZ" is Rx Ry Rz."""

    def test_yaw_of_90_degrees(self):
        with isaac_names():
            from isaacsim.core.utils.rotations import euler_angles_to_quat

            s = np.sqrt(0.5)
            np.testing.assert_allclose(euler_angles_to_quat([0, 0, 90], degrees=True), [s, 0, 0, s], atol=1e-12)

    def test_extrinsic_and_intrinsic_orders_differ_as_hand_computed(self):
        from ambulo.isaac.rotations import euler_angles_to_quat, quat_to_rot_matrix

        # Rx(90) then Ry(90) about fixed axes: R = Ry Rx maps x -> -z... columns by hand:
        # Rx(90) = [[1,0,0],[0,0,-1],[0,1,0]], Ry(90) = [[0,0,1],[0,1,0],[-1,0,0]]
        rx = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
        ry = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)
        extrinsic = quat_to_rot_matrix(euler_angles_to_quat([np.pi / 2, np.pi / 2, 0]))
        intrinsic = quat_to_rot_matrix(euler_angles_to_quat([np.pi / 2, np.pi / 2, 0], extrinsic=False))
        np.testing.assert_allclose(extrinsic, ry @ rx, atol=1e-12)
        np.testing.assert_allclose(intrinsic, rx @ ry, atol=1e-12)

    @pytest.mark.parametrize("extrinsic", [True, False])
    def test_round_trip(self, extrinsic):
        from ambulo.isaac.rotations import euler_angles_to_quat, quat_to_euler_angles

        angles = np.array([0.3, -0.7, 2.1])
        back = quat_to_euler_angles(euler_angles_to_quat(angles, extrinsic=extrinsic), extrinsic=extrinsic)
        np.testing.assert_allclose(back, angles, atol=1e-12)
