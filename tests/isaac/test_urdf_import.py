"""Isaac's URDF importer under ``ambulo run``: Kit's commands and the ``_urdf`` interface put the URDF
on the stage as an articulation, with the import settings honoured where MuJoCo has a meaning."""

import math
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

pytest.importorskip("pxr")

from ambulo import assets
from ambulo.core import AssetError
from ambulo.isaac import isaac_names, run_script
from ambulo.sim.usd_stage import forget_stages
from ambulo.utils.checks import InvalidValueError

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"
POLE_GRAVITY_NM = 0.1 * 9.81 * 0.5
"""m g d of the cart-pole's pole (0.1 kg, centre of mass 0.5 m above the hinge), N*m."""

ARM_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"><inertial><mass value="2"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
    </inertial><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
  <link name="upper"><inertial><origin xyz="0 0 0.25"/><mass value="1"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001"/></inertial>
    <collision><origin xyz="0 0 0.25"/><geometry><cylinder radius="0.03" length="0.5"/></geometry></collision></link>
  <joint name="tool_mount" type="fixed"><parent link="upper"/><child link="tool"/><origin xyz="0 0 0.5"/></joint>
  <link name="tool"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
</robot>
"""
"""A base, an upper arm on a revolute joint and a tool on a fixed joint; the tool has no <inertial>."""


def _held_angle(target: float, kp: float) -> float:
    """The hinge angle where the drive's torque kp (target - q) balances the pole's gravity torque
    m g d sin q (which tips it further: the pole stands up)."""
    q = target
    for _ in range(50):  # Newton on kp (target - q) + m g d sin q = 0
        q -= (kp * (target - q) + POLE_GRAVITY_NM * math.sin(q)) / (-kp + POLE_GRAVITY_NM * math.cos(q))
    return q


def _value(out: str, before: str, after: str = " ") -> float:
    return float(out.split(before, 1)[1].split(after, 1)[0])


def test_import_urdf_tutorial_holds_the_pose_its_drives_are_given(capsys):
    run_script(ISAAC_EXAMPLES / "import_urdf.py", seconds=10.0)
    out = capsys.readouterr().out
    assert "imported cartpole.urdf at /World/cartpole: status True, prim valid True" in out
    assert "joints: ['slider', 'hinge'], drive stiffness [20.0, 20.0], damping [2.0, 2.0]" in out
    assert _value(out, "slider ") == pytest.approx(0.5, abs=3e-4)
    hinge = _value(out, "hinge ")
    assert hinge == pytest.approx(_held_angle(0.3, 20.0), abs=3e-4)
    assert hinge - 0.3 > 5e-3  # the 20 N m/rad drive gives way to gravity measurably
    assert _value(out, "fixed base moved ") == 0.0


def test_interface_import_before_the_world_with_an_edited_joint_drive(capsys):
    run_script(ISAAC_EXAMPLES / "import_urdf_interface.py", seconds=10.0)
    out = capsys.readouterr().out
    assert "parsed cartpole: links ['cart', 'pole', 'rail'], joints ['hinge', 'slider']" in out
    assert "imported at /World/cartpole" in out and "joints ['slider', 'hinge']" in out
    # the slider's velocity drive (kd = 50 N s/m) holds 0.2 m/s after a lag of m / kd = 1.1 kg / 50 N s/m
    assert _value(out, "cart speed ") == pytest.approx(0.2, abs=1e-4)
    assert _value(out, "m/s (commanded 0.2), at ") == pytest.approx(0.2 * (2.0 - 1.1 / 50.0), abs=2e-3)
    assert _value(out, "hinge ") == pytest.approx(_held_angle(0.3, 400.0), abs=1e-4)


def _import(config_edits: dict, urdf: str = "", name: str = "robot", place=None):
    """Import ``urdf`` (default: the cart-pole) into a fresh World with ``config_edits``; returns
    (world, articulation, prim path)."""
    import omni.kit.commands
    from isaacsim.core.api import World
    from isaacsim.core.prims import SingleArticulation
    from pxr import Gf

    world = World()
    world.scene.add_default_ground_plane()
    _, config = omni.kit.commands.execute("URDFCreateImportConfig")
    for key, value in config_edits.items():
        setattr(config, key, value)
    _, path = omni.kit.commands.execute("URDFParseAndImportFile", urdf_path=urdf or assets.path("cartpole"),
                                        import_config=config)
    if place is not None:
        omni.kit.commands.execute("TransformPrimSRT", path=path, new_translation=Gf.Vec3d(*place))
    robot = world.scene.add(SingleArticulation(prim_path=path, name=name))
    world.reset()
    return world, robot, path


def _robot_geoms(world, path: str = "/World/cartpole") -> list[int]:
    model = world.model
    return [g for g in range(model.ngeom) if model.body(model.geom_bodyid[g]).name.startswith(path + "/")]


def _body_mass(world, name: str) -> float:
    return float(world.model.body_mass[world.model.body(name).id])


def test_fix_base_merge_fixed_joints_density_and_self_collision_are_honoured(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    forget_stages()
    with isaac_names():
        # Isaac's defaults: a fixed base, links on fixed joints merged, self-collisions off
        world, arm, path = _import({}, str(urdf), "fixed", place=(0.0, 0.0, 0.5))
        assert path == "/World/arm"
        bodies = {world.model.body(i).name for i in range(world.model.nbody)}
        assert f"{path}/tool" not in bodies and f"{path}/upper" in bodies
        # the tool, 0.1 m edge at MuJoCo's (and PhysX's) default 1000 kg/m^3, is part of the upper arm
        assert _body_mass(world, f"{path}/upper") == pytest.approx(1.0 + 1.0, abs=1e-6)
        assert world.model.nexclude == 1  # base / upper: the only two links left
        for _ in range(60):
            world.step(render=False)
        assert arm.get_world_pose()[0].tolist() == pytest.approx([0.0, 0.0, 0.5])  # fixed where placed
        # a floating base falls to the ground; the tool keeps its own body; 500 kg/m^3 for it
        world, arm, path = _import({"fix_base": False, "merge_fixed_joints": False, "density": 500.0,
                                    "self_collision": True}, str(urdf), "free", place=(0.0, 0.0, 0.5))
        assert _body_mass(world, f"{path}/tool") == pytest.approx(500.0 * 0.1 ** 3)
        assert world.model.nexclude == 0
        for _ in range(120):
            world.step(render=False)
        assert arm.get_world_pose()[0][2] == pytest.approx(0.05, abs=2e-3)  # the 0.1 m base box on the ground


def test_drive_types_collision_from_visuals_and_capsules():
    forget_stages()
    with isaac_names():
        from isaacsim.asset.importer.urdf import _urdf

        world, robot, _ = _import({"default_drive_type": _urdf.UrdfJointTargetType.JOINT_DRIVE_VELOCITY,
                                   "default_drive_strength": 30.0, "collision_from_visuals": True,
                                   "replace_cylinders_with_capsules": True})
        kps, kds = robot.get_articulation_controller().get_gains()
        assert kps.tolist() == [0.0, 0.0] and kds.tolist() == [30.0, 30.0]
        geoms = _robot_geoms(world)
        assert all(world.model.geom_contype[g] == 1 for g in geoms)  # the visual-only cart-pole collides
        types = world.model.geom_type[geoms].tolist()
        assert int(mujoco.mjtGeom.mjGEOM_CAPSULE) in types and int(mujoco.mjtGeom.mjGEOM_CYLINDER) not in types
        world, robot, _ = _import({"default_drive_type": _urdf.UrdfJointTargetType.JOINT_DRIVE_NONE})
        kps, kds = robot.get_articulation_controller().get_gains()
        assert np.all(kps == 0) and np.all(kds == 0)
        world, robot, _ = _import({})  # Isaac's defaults: the visual-only cart-pole collides with nothing
        assert all(world.model.geom_contype[g] == 0 for g in _robot_geoms(world))


def test_make_default_prim_places_the_robot_at_the_stage_root_and_says_what_it_ignores():
    forget_stages()
    with isaac_names():
        with pytest.warns(UserWarning) as caught:
            world, robot, path = _import({"make_default_prim": True, "convex_decomp": True}, name="root")
        assert path == "/cartpole" and robot.num_dof == 2
        assert world.stage.GetPrimAtPath("/cartpole/pole").IsValid()
        lines = [str(w.message) for w in caught if "URDF import" in str(w.message)]
        assert len(lines) == 1 and "\n" not in lines[0]
        assert "convex_decomp=True" in lines[0] and "make_default_prim=True" in lines[0]
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # Isaac's defaults warn about nothing
            _import({}, name="quiet")


def test_bad_settings_and_files_fail_in_one_line(tmp_path):
    forget_stages()
    with isaac_names():
        import omni.kit.commands
        from omni.importer.urdf import _urdf

        config = _urdf.ImportConfig()
        with pytest.raises(AttributeError, match="no setting 'fix_bas'; its settings are merge_fixed_joints"):
            config.fix_bas = True
        with pytest.raises(AssetError, match="URDF file not found: '.*nope.urdf'"):
            omni.kit.commands.execute("URDFParseAndImportFile", urdf_path=str(tmp_path / "nope.urdf"),
                                      import_config=config)
        (tmp_path / "bad.urdf").write_text("<robot name='x'><link name='a'></robot>")
        with pytest.raises(AssetError, match="malformed XML"):
            _urdf.acquire_urdf_interface().parse_urdf(str(tmp_path), "bad.urdf", config)
        (tmp_path / "ball.urdf").write_text("<robot name='x'><link name='a'/><link name='b'/><joint name='j' "
                                            "type='ball'><parent link='a'/><child link='b'/></joint></robot>")
        with pytest.raises(AssetError, match='<joint name="j" type="ball"> needs a type of revolute'):
            _urdf.acquire_urdf_interface().parse_urdf(str(tmp_path), "ball.urdf", config)
        config.set_density(-1000.0)  # set after it was built: refused when importing, in one line
        with pytest.raises(InvalidValueError, match="density") as info:
            omni.kit.commands.execute("URDFParseAndImportFile", urdf_path=assets.path("cartpole"),
                                      import_config=config)
        assert "\n" not in str(info.value)
        with pytest.raises(InvalidValueError, match="distance_scale"):
            _urdf.ImportConfig(distance_scale=0.0)


def test_a_robot_placed_before_the_world_exists_is_simulated_where_it_was_placed():
    forget_stages()
    with isaac_names():
        import omni.kit.commands
        from isaacsim.core.api import World
        from isaacsim.core.prims import SingleArticulation
        from pxr import Gf

        _, config = omni.kit.commands.execute("URDFCreateImportConfig")
        _, path = omni.kit.commands.execute("URDFParseAndImportFile", urdf_path=assets.path("cartpole"),
                                            import_config=config)
        omni.kit.commands.execute("TransformPrimSRT", path=path, new_translation=Gf.Vec3d(0.0, 1.0, 0.25),
                                  new_rotation_euler=Gf.Vec3d(0.0, 0.0, 90.0))
        world = World()
        robot = world.scene.add(SingleArticulation(prim_path=path, name="cartpole"))
        world.reset()
        position, orientation = robot.get_world_pose()
        assert position.tolist() == pytest.approx([0.0, 1.0, 0.25])
        assert orientation.tolist() == pytest.approx([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
