"""``ambulo run``: Isaac Sim scripts from examples/isaac, unchanged, do what they say physically."""

from pathlib import Path

import numpy as np
import pytest

from ambulo.cli import main
from ambulo.isaac import run_script
from script_loader import printed_number

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"


def test_standalone_hello_world_drops_a_cube_to_rest_on_the_ground(capsys):
    result = run_script(ISAAC_EXAMPLES / "hello_world.py")
    out = capsys.readouterr().out
    assert result.ran_sample is None and result.physics_steps == 120
    rest = float(out.strip().splitlines()[-1].split("height ")[1].split(" m")[0])
    assert rest == pytest.approx(0.5015 / 2, abs=0.01)  # the cube's half size: resting on z = 0


def test_a_base_sample_is_loaded_then_played_as_the_gui_would(capsys):
    result = run_script(ISAAC_EXAMPLES / "hello_robot_sample.py", seconds=2.0)
    out = capsys.readouterr().out
    assert result.ran_sample == "HelloRobot"
    assert "before first reset: None" in out and "after first reset: 2" in out
    assert result.sim_time_s == pytest.approx(2.0, abs=1e-6)
    from ambulo.sim import World

    jetbot = World.instance().scene.get_object("fancy_robot")
    # 10 rad/s on both wheels of r = 0.03 m: about 0.3 m/s forward, straight ahead
    x, y = jetbot.get_world_pose()[0][:2]
    assert 0.3 < x < 0.65 and abs(y) < 0.05


def test_cli_run_reports_and_fails_in_one_line(capsys, tmp_path):
    assert main(["run", "--seconds", "1", str(ISAAC_EXAMPLES / "hello_robot_sample.py")]) == 0
    assert "HelloRobot loaded and played: 1.00 s simulated in 60 physics steps" in capsys.readouterr().out
    bad = tmp_path / "bad.py"
    bad.write_text("from isaacsim.core.api.objects import DynamicCone\n")
    assert main(["run", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "DynamicCone" in err and "cylinders" in err
    assert main(["run", str(tmp_path / "nope.py")]) == 2
    assert "no script" in capsys.readouterr().err


def test_script_argv_reaches_the_script(tmp_path, capsys):
    script = tmp_path / "args.py"
    script.write_text("import sys\nprint('argv', sys.argv[1:])\n")
    run_script(script, ["--headless", "7"])
    assert "argv ['--headless', '7']" in capsys.readouterr().out


def test_isaac_asset_paths_resolve_to_stand_ins():
    from ambulo.core.scene import resolve_file
    from ambulo.sim import get_assets_root_path
    from ambulo.sim.isaac_assets import resolve_asset

    root = get_assets_root_path()
    assert resolve_asset(root + "/Isaac/Robots/Jetbot/jetbot.usd").endswith("jetbot.xml")
    url = "https://omniverse-content-production.s3-us-west-2.amazonaws.com/Assets/Isaac/4.5"
    assert resolve_asset(url + "/Isaac/Environments/Simple_Warehouse/warehouse.usd").endswith("simple_warehouse.xml")
    with pytest.raises(FileNotFoundError, match="no stand-in.*Isaac/Robots/Carter.*jetbot"):
        resolve_asset(root + "/Isaac/Robots/Carter/carter_v1.usd")
    # paths and bundled names resolve as in the core, which knows nothing of Isaac's library
    assert resolve_asset("jetbot") == resolve_file("jetbot")
    assert resolve_file(root + "/Isaac/Robots/Jetbot/jetbot.usd") == root + "/Isaac/Robots/Jetbot/jetbot.usd"


def test_isaac_asset_paths_place_their_stand_ins():
    from ambulo.sim import World, add_reference_to_stage, get_assets_root_path

    world = World()
    add_reference_to_stage(usd_path=get_assets_root_path() + "/Isaac/Robots/Jetbot/jetbot.usd", prim_path="/World/Jetbot")
    world.reset()
    assert world.model.body("/World/Jetbot/chassis") is not None
    assert np.isfinite(1.0)


def test_adding_a_controller_turns_the_jetbot_a_quarter_circle(capsys):
    run_script(ISAAC_EXAMPLES / "adding_controller.py")
    out = capsys.readouterr().out
    # 0.2 m/s at pi/4 rad/s for 2 s: a quarter of a circle of radius 0.255 m, chord 0.255 * sqrt(2)
    assert printed_number(out, "turned ", " deg") == pytest.approx(90.0, abs=3.0)
    assert printed_number(out, "deg, ", " m from") == pytest.approx(0.2546 * 2 ** 0.5, abs=0.02)


def test_multiple_robots_through_one_view_drive_as_commanded(capsys):
    run_script(ISAAC_EXAMPLES / "multiple_robots.py")
    out = capsys.readouterr().out
    assert "3 Jetbots with joints ['left_wheel_joint', 'right_wheel_joint']" in out
    # forward, still, backward at 10 rad/s * 0.03 m = 0.3 m/s for 2 s
    finals = [printed_number(out, f"env_{k}/Jetbot: x +0.000 -> ", " m") for k in range(3)]
    assert finals[0] == pytest.approx(0.6, abs=0.05) and abs(finals[1]) < 1e-3
    assert finals[2] == pytest.approx(-0.6, abs=0.05)


def test_usd_authored_with_pxr_is_simulated_next_to_api_objects(capsys):
    run_script(ISAAC_EXAMPLES / "usd_authoring.py")
    out = capsys.readouterr().out
    assert "the stage holds /World/api_cube: True" in out and "pendulum degrees of freedom: 1" in out
    assert printed_number(out, "API cube at rest at height ", " m") == pytest.approx(0.1, abs=2e-3)
    # 2 kg link, centre 0.3 m below the hinge, kp = 10/deg = 573 N m/rad: sag m g l sin(30) / kp
    sag_deg = 2.0 * 9.81 * 0.3 * 0.5 / (10.0 * 180 / 3.141592653589793) * 180 / 3.141592653589793
    assert printed_number(out, "pendulum held at ", " degrees") == pytest.approx(30.0 - sag_deg, abs=0.2)
    slid = printed_number(out, "(slid ", " m along x)")
    assert 0.2 < slid < 0.5  # launched at 1 m/s: 0.3 m in flight, then friction 0.5 stops it within 0.1 m


def test_every_isaac_example_is_run_by_a_test():
    tests = Path(__file__).resolve().parent
    text = "".join(p.read_text() for p in tests.glob("test_*.py")) + (tests.parent / "sim" / "test_isaac_sensors.py").read_text()
    missing = [p.name for p in ISAAC_EXAMPLES.glob("*.py") if f'"{p.name}"' not in text and p.stem not in text]
    assert not missing, f"examples/isaac scripts no test runs: {missing}"
