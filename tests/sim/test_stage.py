"""Referencing USD, URDF and MJCF files at prim paths, and the errors for bad files."""

import glob

import numpy as np
import pytest

from ambulo import assets
from ambulo.sim import (
    AssetError,
    PrimNotFoundError,
    RigidPrim,
    Robot,
    World,
    XFormPrim,
    add_reference_to_stage,
)

pxr = pytest.importorskip("pxr")


def _author_crate_usd(path):
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Crate")
    stage.SetDefaultPrim(root.GetPrim())
    for name, size, z, mass in (("box", 0.4, 0.5, 2.0), ("lid", 0.2, 0.8, 0.5)):
        cube = UsdGeom.Cube.Define(stage, f"/Crate/{name}")
        cube.CreateSizeAttr(size)
        cube.AddTranslateOp().Set(Gf.Vec3d(0, 0, z))
        UsdPhysics.RigidBodyAPI.Apply(cube.GetPrim())
        UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
        UsdPhysics.MassAPI.Apply(cube.GetPrim()).CreateMassAttr(mass)
    hinge = UsdPhysics.RevoluteJoint.Define(stage, "/Crate/hinge")
    hinge.CreateBody0Rel().SetTargets(["/Crate/box"])
    hinge.CreateBody1Rel().SetTargets(["/Crate/lid"])
    hinge.CreateAxisAttr("X")
    hinge.CreateLocalPos0Attr(Gf.Vec3f(0, 0, 0.2))
    hinge.CreateLocalPos1Attr(Gf.Vec3f(0, 0, -0.1))
    stage.Save()


def test_usd_stage_loads_with_bodies_masses_and_joints_at_the_prim_path(tmp_path):
    file = tmp_path / "crate.usda"
    _author_crate_usd(file)
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=str(file), prim_path="/World/Crate")
    crate = world.scene.add(Robot(prim_path="/World/Crate", name="crate"))
    box = world.scene.add(RigidPrim(prim_path="/World/Crate/box"))
    lid = world.scene.add(RigidPrim(prim_path="/World/Crate/lid"))
    world.reset()
    model = world.model
    assert model.body("/World/Crate/box").id > 0 and model.body("/World/Crate/lid").id > 0
    assert box.get_mass() == pytest.approx(2.0) and lid.get_mass() == pytest.approx(0.5)
    assert crate.dof_names == ["hinge"]
    np.testing.assert_allclose(box.get_world_pose()[0], [0, 0, 0.5], atol=1e-9)
    for _ in range(400):
        world.step()
    # the crate (free root) falls onto the ground: box bottom at z = 0
    assert box.get_world_pose()[0][2] == pytest.approx(0.2, abs=0.005)


def test_mjcf_reference_maps_the_default_prim_to_the_prim_path():
    world = World()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Fancy_Robot")
    chassis = world.scene.add(XFormPrim(prim_path="/World/Fancy_Robot/chassis"))
    robot = world.scene.add(Robot(prim_path="/World/Fancy_Robot", position=[1.0, 2.0, 0.0]))
    world.reset()
    assert robot.get_world_pose()[0][:2] == pytest.approx([1.0, 2.0])
    np.testing.assert_allclose(chassis.get_world_pose()[0], robot.get_world_pose()[0])
    assert set(robot.dof_names) >= {"left_wheel_joint", "right_wheel_joint"}


def test_properties_are_none_before_the_first_reset():
    world = World()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    robot = world.scene.add(Robot(prim_path="/World/Jetbot"))
    assert robot.num_dof is None and robot.dof_names is None
    with pytest.raises(RuntimeError, match="world.reset"):
        robot.get_joint_positions()
    world.reset()
    assert robot.num_dof == len(robot.dof_names) >= 2


URDF = """<robot name="arm">
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="upper"><inertial><origin xyz="0 0 0.25"/><mass value="0.5"/><inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="30" velocity="5"/></joint>
</robot>"""

CUBE_OBJ = "v 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nv 0 0 0.5\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def test_urdf_gets_joint_drives_and_resolves_relative_and_package_meshes(tmp_path, monkeypatch):
    pkg = tmp_path / "my_robot_description"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "urdf").mkdir()
    (pkg / "meshes" / "upper.obj").write_text(CUBE_OBJ)
    for uri, name in (("../meshes/upper.obj", "rel.urdf"), ("package://my_robot_description/meshes/upper.obj", "pkg.urdf")):
        (pkg / "urdf" / name).write_text(URDF.format(mesh=uri))
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path))
    for name in ("rel.urdf", "pkg.urdf"):
        world = World()
        add_reference_to_stage(usd_path=str(pkg / "urdf" / name), prim_path="/World/Arm", fixed_base=True,
                               drive_stiffness=400.0, drive_damping=20.0)
        arm = world.scene.add(Robot(prim_path="/World/Arm"))
        world.reset()
        assert arm.dof_names == ["shoulder"]
        kps, kds = arm.get_articulation_controller().get_gains()
        assert kps[0] == pytest.approx(400.0) and kds[0] == pytest.approx(20.0)
        np.testing.assert_allclose(arm.get_dof_limits()[0], [-1.5, 1.5])
        # the URDF effort limit caps the drive torque
        assert world.model.jnt_actfrcrange[world.model.joint("/World/Arm/shoulder").id][1] == pytest.approx(30.0)


def test_unknown_package_names_the_fix(tmp_path, monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    file = tmp_path / "r.urdf"
    file.write_text(URDF.format(mesh="package://nowhere_pkg/m.obj"))
    World()
    with pytest.raises(FileNotFoundError, match="ROS_PACKAGE_PATH"):
        add_reference_to_stage(usd_path=str(file), prim_path="/World/R")


@pytest.mark.parametrize("content, suffix, match", [
    (None, ".urdf", "file not found"),
    ("<robot name='x'><link name='a'>", ".urdf", "malformed"),
    ("<mujoco><worldbody><body><geom type='box'/></body></worldbody>", ".xml", "malformed|cannot be loaded"),
    ("<mujoco><worldbody><geom type='nonsense' size='1'/></worldbody></mujoco>", ".xml", "cannot be loaded"),
    ("#usda 1.0\n def Xform \"A\" { bad", ".usda", "cannot be loaded|not a readable"),
    ("hello", ".obj", "unknown file kind"),
])
def test_bad_files_raise_errors_naming_the_problem(tmp_path, content, suffix, match):
    file = tmp_path / f"bad{suffix}"
    if content is not None:
        file.write_text(content)
    World()
    with pytest.raises((AssetError, ValueError), match=match):
        add_reference_to_stage(usd_path=str(file), prim_path="/World/Bad")


def test_unknown_prim_path_suggests_close_names():
    world = World()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    world.scene.add(XFormPrim(prim_path="/World/Jetbot/chasis"))
    with pytest.raises(PrimNotFoundError, match="chassis"):
        world.reset()


def test_a_shell_style_star_in_a_view_expression_names_the_regular_expression_it_meant():
    # Isaac's view expressions are regular expressions per component: "cube_*" is "cube" and underscores
    # and matches none of cube_0..2; the error names "cube_.*" and what it matches
    from ambulo.sim import DynamicCuboid
    from ambulo.sim.views import RigidPrimView

    world = World()
    for i in range(3):
        world.scene.add(DynamicCuboid(prim_path=f"/World/cube_{i}", name=f"cube_{i}", position=np.array([i, 0, 1.0])))
    with pytest.raises(PrimNotFoundError, match=r"did you mean '/World/cube_\.\*' \(3 prims\)"):
        RigidPrimView(prim_paths_expr="/World/cube_*", name="cubes")
    with pytest.raises(PrimNotFoundError) as nothing_close:
        RigidPrimView(prim_paths_expr="/World/sphere_*", name="spheres")
    assert "did you mean" not in str(nothing_close.value)
    assert len(RigidPrimView(prim_paths_expr="/World/cube_.*", name="cubes").prim_paths) == 3


def _g1_urdf():
    from ambulo.core.importers.packages import package_search_path

    for folder in package_search_path():
        hits = glob.glob(str(folder / "example-robot-data" / "robots" / "g1_description" / "urdf" / "g1_29dof_rev_1_0.urdf"))
        if hits:
            return hits[0]
    pytest.skip("example-robot-data (Unitree G1 URDF) is not installed")


def test_unitree_g1_urdf_from_example_robot_data_loads_and_stands_briefly():
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=_g1_urdf(), prim_path="/World/G1", drive_stiffness=150.0, drive_damping=5.0)
    g1 = world.scene.add(Robot(prim_path="/World/G1", position=[0, 0, 0.8]))
    world.reset()
    assert g1.num_dof == 29
    assert {"left_knee_joint", "right_hip_pitch_joint", "waist_yaw_joint"} <= set(g1.dof_names)
    assert world.model.body("/World/G1/pelvis").id == g1.entity.root_body_id
    total_mass = world.model.body_subtreemass[g1.entity.root_body_id]
    assert 25.0 < total_mass < 45.0  # the G1 weighs about 35 kg
    for _ in range(30):  # 0.5 s at 1/60 s per step
        world.step()
    # a diverged world would be reset silently (finite state), so count divergences instead
    assert world.engine.num_diverged == 0
    # holding its start pose with stiff drives, the pelvis has not dropped to the floor yet
    assert world.current_time == pytest.approx(0.5)
    assert g1.get_world_pose()[0][2] > 0.3


def _author_arm_usd(path, body0=None):
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/Arm").GetPrim())
    UsdPhysics.CollisionAPI.Apply(UsdGeom.Cube.Define(stage, "/Arm/base").GetPrim())
    link = UsdGeom.Cube.Define(stage, "/Arm/link")
    link.CreateSizeAttr(0.1)
    link.AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.3))
    UsdPhysics.RigidBodyAPI.Apply(link.GetPrim())
    UsdPhysics.MassAPI.Apply(link.GetPrim()).CreateMassAttr(1.0)
    joint = UsdPhysics.RevoluteJoint.Define(stage, "/Arm/shoulder")
    if body0:
        joint.CreateBody0Rel().SetTargets([body0])
    joint.CreateBody1Rel().SetTargets(["/Arm/link"])
    joint.CreateAxisAttr("Y")
    joint.CreateLocalPos0Attr(Gf.Vec3f(0, 0, 0.1))
    joint.CreateLocalPos1Attr(Gf.Vec3f(0, 0, -0.2))
    drive = UsdPhysics.DriveAPI.Apply(joint.GetPrim(), "angular")
    drive.CreateStiffnessAttr(3.0)
    drive.CreateDampingAttr(0.1)
    drive.CreateMaxForceAttr(50.0)
    stage.Save()


def test_usd_drive_gains_become_joint_drives_per_radian(tmp_path):
    file = tmp_path / "arm.usda"
    _author_arm_usd(file)
    world = World()
    add_reference_to_stage(usd_path=str(file), prim_path="/World/Arm")
    arm = world.scene.add(Robot(prim_path="/World/Arm"))
    world.reset()
    kps, kds = arm.get_articulation_controller().get_gains()
    # UsdPhysics angular drive gains are per degree
    assert kps[0] == pytest.approx(3.0 * 180 / np.pi) and kds[0] == pytest.approx(0.1 * 180 / np.pi)
    act = world.model.actuator("/World/Arm/shoulder")
    assert world.model.actuator_forcerange[act.id][1] == pytest.approx(50.0)


def test_usd_joint_to_a_static_collider_warns_that_it_was_dropped(tmp_path):
    file = tmp_path / "arm.usda"
    _author_arm_usd(file, body0="/Arm/base")
    World()
    with pytest.warns(UserWarning, match="leave body0 empty"):
        add_reference_to_stage(usd_path=str(file), prim_path="/World/Arm")
