"""``omni.kit.commands`` under ``ambulo run``: Kit's commands author the stage as Kit's do, their
effects reach the simulation, and an unknown command fails in one line."""

import warnings
from pathlib import Path

import pytest

pytest.importorskip("pxr")

from ambulo import assets
from ambulo.cli import main
from ambulo.isaac import isaac_names, run_script
from ambulo.sim.usd_stage import forget_stages

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"
SUBSTEP_S = 1.0 / 240.0
"""The World's MuJoCo step at Isaac's 1/60 s physics step (4 substeps)."""


def _value(out: str, before: str, after: str = " ") -> str:
    return out.split(before, 1)[1].split(after, 1)[0]


def _fallen_m(g: float, seconds: float) -> float:
    """Distance fallen from rest under ``g`` after ``seconds``, as the semi-implicit Euler steps take it."""
    n = round(seconds / SUBSTEP_S)
    return g * SUBSTEP_S ** 2 * n * (n + 1) / 2


def _bodies(world) -> set[str]:
    return {world.model.body(i).name for i in range(world.model.nbody)}


def test_kit_commands_tutorial_builds_a_scene_whose_edits_reach_the_simulation(capsys):
    run_script(ISAAC_EXAMPLES / "kit_commands.py", seconds=10.0)
    out = capsys.readouterr().out
    from ambulo.sim import World

    assert "made /World/Cube and /World/Cube_01 (active False)" in out
    # the cube falls freely under the scene's gravity, then under the gravity ChangeProperty set
    assert float(_value(out, "under 9.81 m/s^2: cube at z = ")) == pytest.approx(2.0 - _fallen_m(9.81, 0.5), abs=1e-3)
    assert float(_value(out, "under 1.62 m/s^2: cube at z = ")) == pytest.approx(2.0 - _fallen_m(1.62, 0.5), abs=1e-3)
    # and lands on the static table (top at 0.5 m): its centre half its 0.2 m edge above
    assert float(_value(out, "cube at rest at z = ")) == pytest.approx(0.6, abs=3e-3)
    # MovePrim under a group at y = 1 kept the ball's world position: its local translate changed
    position = [float(v) for v in _value(out, "moved ball at [", "]").split(",")]
    assert position == pytest.approx([2.0, 0.0, 0.1], abs=2e-3)
    assert "local translate (2, -1, 0.1)" in out
    bodies = _bodies(World.instance())
    assert {"/World/Cube", "/World/Balls/Ball_copy"} <= bodies
    assert "/World/Ball" not in bodies and "/World/Cube_01" not in bodies  # deleted; deactivated
    assert "/World/Ball after DeletePrims: valid False" in out
    # the script's own command ran through execute, and undo restored what it changed
    assert "SetGravity: True, was 1.62, now 3.71" in out and "after undo: gravity 1.62" in out


def test_an_unknown_command_fails_in_one_line_listing_the_commands(tmp_path, capsys):
    script = tmp_path / "unknown.py"
    script.write_text("import omni.kit.commands\nomni.kit.commands.execute('CreateHydraPrim', prim_path='/World/x')\n")
    assert main(["run", str(script)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "no Kit command 'CreateHydraPrim'" in err and "CreatePrim" in err and "URDFParseAndImportFile" in err


def test_commands_return_kits_results_and_author_isaacs_default_ops():
    forget_stages()
    with isaac_names():
        import omni.kit.commands
        import omni.usd
        from isaacsim.core.api import World

        World()
        stage = omni.usd.get_context().get_stage()
        assert omni.kit.commands.execute("CreatePrim", prim_type="Cylinder") == (True, None)
        assert omni.kit.commands.execute("CreatePrimCommand", prim_type="Cylinder") == (True, None)  # Kit's suffix
        first, second = stage.GetPrimAtPath("/World/Cylinder"), stage.GetPrimAtPath("/World/Cylinder_01")
        assert first.IsValid() and second.IsValid()
        assert list(first.GetAttribute("xformOpOrder").Get()) == ["xformOp:translate", "xformOp:orient", "xformOp:scale"]
        assert first.GetAttribute("axis").Get() == "Z"  # the stage's up axis, as Kit sets it
        assert omni.kit.commands.execute("CreateMeshPrimWithDefaultXform", prim_type="Sphere") == (True, "/World/Sphere")
        extent = stage.GetPrimAtPath("/World/Sphere").GetAttribute("extent").Get()
        assert [tuple(v) for v in extent] == [pytest.approx((-0.5,) * 3), pytest.approx((0.5,) * 3)]  # 50 cm
        with pytest.raises(TypeError, match="'DeletePrims'.*it takes paths"):
            omni.kit.commands.execute("DeletePrims", path=["/World/Sphere"])
        with pytest.warns(UserWarning, match="DeletePrims: no prim at /World/Nothing"):
            omni.kit.commands.execute("DeletePrims", paths=["/World/Nothing", "/World/Sphere"])
        assert not stage.GetPrimAtPath("/World/Sphere").IsValid()
        with pytest.raises(ValueError, match="has no property 'radiuss'"):
            omni.kit.commands.execute("ChangeProperty", prop_path="/World/Cylinder.radiuss", value=1.0, prev=None)
        with pytest.raises(TypeError, match="not a subclass of omni.kit.commands.Command"):
            omni.kit.commands.register(dict)


def test_delete_and_transform_commands_act_on_an_imported_robots_model():
    forget_stages()
    with isaac_names():
        import omni.kit.commands
        from isaacsim.core.api import World
        from isaacsim.core.prims import SingleArticulation
        from pxr import Gf

        world = World()
        _, config = omni.kit.commands.execute("URDFCreateImportConfig")
        _, path = omni.kit.commands.execute("URDFParseAndImportFile", urdf_path=assets.path("cartpole"),
                                            import_config=config)
        robot = world.scene.add(SingleArticulation(prim_path=path, name="cartpole"))
        omni.kit.commands.execute("TransformPrimSRT", path=path, new_translation=Gf.Vec3d(1.0, 2.0, 0.5))
        world.reset()
        assert robot.get_world_pose()[0].tolist() == pytest.approx([1.0, 2.0, 0.5])  # the rail, welded there
        with pytest.raises(ValueError, match="made through the ambulo API"):
            omni.kit.commands.execute("ToggleActivePrims", prim_paths=[path])
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            omni.kit.commands.execute("DeletePrims", paths=[path])
        world.reset()
        assert not any(name.startswith(path) for name in _bodies(world)) and world.model.nu == 0
        assert not world.scene.object_exists("cartpole")  # its wrapper left with it
        assert not world.stage.GetPrimAtPath(path).IsValid()
