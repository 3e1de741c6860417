"""``isaacgym`` exists only inside ``ambulo run``, and says what to use for what it lacks."""

import importlib.util
import sys

import pytest
import torch

from ambulo.isaac import IsaacNameError, run_script


def test_isaacgym_is_answered_only_during_a_run(tmp_path, capsys):
    assert importlib.util.find_spec("isaacgym") is None
    script = tmp_path / "probe.py"
    script.write_text(
        "import torch\n"
        "from isaacgym import gymapi, gymtorch, gymutil\n"
        "from isaacgym.torch_utils import quat_rotate\n"
        "q = torch.tensor([[0.0, 0.0, 0.7071068, 0.7071068]])  # x, y, z, w: 90 degrees about z\n"
        "print('rotated', [round(v, 3) + 0.0 for v in quat_rotate(q, torch.tensor([[1.0, 0.0, 0.0]]))[0].tolist()])\n"
        "print('device', torch.zeros(1, device='cuda:0').device.type if not torch.cuda.is_available() else 'cpu')\n"
        "gym = gymapi.acquire_gym()\n"
        "try:\n"
        "    gym.create_asset_box\n"
        "except AttributeError as err:\n"
        "    print('missing:', err)\n")
    run_script(script)
    out = capsys.readouterr().out
    assert "rotated [0.0, 1.0, 0.0]" in out and "device cpu" in out
    assert "missing: ambulo does not provide Gym.create_asset_box" in out and "load a URDF/MJCF" in out
    assert not any(m.split(".")[0] == "isaacgym" for m in sys.modules)
    if not torch.cuda.is_available():  # CUDA tensors are CPU tensors for the run only
        with pytest.raises((RuntimeError, AssertionError)):
            torch.zeros(1, device="cuda:0")
    if "rl_games.common.vecenv" in sys.modules:  # registered for a run only
        assert "ISAACGYM" not in sys.modules["rl_games.common.vecenv"].vecenv_config


def test_an_isaac_gym_name_ambulo_lacks_fails_at_its_import_line(tmp_path):
    script = tmp_path / "flex.py"
    script.write_text("from isaacgym.gymapi import FlexSolverParams\n")
    with pytest.raises(IsaacNameError, match="FlexSolverParams.*isaacgym.gymapi"):
        run_script(script)


def test_a_y_up_sim_fails_in_one_line_naming_the_fix(tmp_path):
    script = tmp_path / "yup.py"
    script.write_text("from isaacgym import gymapi\ngym = gymapi.acquire_gym()\n"
                      "gym.create_sim(0, 0, gymapi.SIM_PHYSX, gymapi.SimParams())\n")
    with pytest.raises(ValueError, match="UP_AXIS_Z"):
        run_script(script)
