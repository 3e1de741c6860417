"""USD ``physics:jointEnabled = false`` in an Isaac script: the bodies the joint held come apart."""

from pathlib import Path

import pytest

from ambulo.isaac import run_script
from script_loader import printed_number

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"


def test_joint_enabled_tutorial_drops_what_disabled_joints_held(capsys):
    run_script(ISAAC_EXAMPLES / "joint_enabled.py")
    out = capsys.readouterr().out
    assert printed_number(out, "held_box at height ", " m") == pytest.approx(1.0, abs=1e-3)  # its fixed joint holds
    assert printed_number(out, "dropped_box at height ", " m") == pytest.approx(0.1, abs=2e-3)  # on the ground
    # the chain fell off its post and stands on its lower sphere (radius 0.1), the links 0.4 m apart
    assert printed_number(out, "upper link at height ", " m") == pytest.approx(0.1 + 0.4, abs=5e-3)
    assert printed_number(out, "m, ", " m from its lower link") == pytest.approx(0.4, abs=1e-3)
