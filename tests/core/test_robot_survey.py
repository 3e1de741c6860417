"""Every robot of the ``example-robot-data`` pip package loads with the DoF its URDF declares
and holds its pose for 1 s without diverging (skipped without the ``robots`` extra).

One case per file (69, ~45 s on 2 cores with a warm cache). Converted meshes go to the
user's cache, so only the first run pays for the conversions (~20 s more).
"""

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from script_loader import load_script

pytest.importorskip("trimesh")
_SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "robot_survey.py"
survey = load_script(_SCRIPT, "robot_survey", register=True)  # dataclasses look their module up

ROOT = survey.robots_dir()
pytestmark = pytest.mark.skipif(ROOT is None, reason="example-robot-data is not installed (pip install 'ambulo[robots]')")

NOT_ROBOTS = {
    "ur_description/urdf/ur3.urdf": "has no <link>",  # an empty xacro leftover: <robot/> and a comment
    # its meshes are absolute paths into a NAOqi SDK install, in Ogre's .mesh format
    "romeo_description/urdf/romeo_laas_small.urdf": "Torso.mesh' not found",
}
"""Files of the package that are not loadable robots, with the reason the error must give."""
FILES = [str(f.relative_to(ROOT)) for f in survey.robot_files(ROOT)] if ROOT else []


def _check(relative: str) -> None:
    file = ROOT / relative
    row = survey.survey(file, ROOT)
    if relative in NOT_ROBOTS:
        assert not row.loaded and NOT_ROBOTS[relative] in row.reason
        return
    assert row.loaded, row.reason
    assert row.dof == row.expected_dof, f"{row.dof} DoF loaded, the URDF declares {row.expected_dof}"
    assert row.mass_kg > 0
    assert row.fixed_stable and row.ground_stable


@pytest.mark.parametrize("relative", FILES)
def test_every_robot_file_loads_with_its_dof_and_holds_still_for_1s_or_is_listed_with_its_reason(relative):
    _check(relative)


def test_the_survey_covers_the_whole_package():
    assert len(FILES) >= 69 and set(NOT_ROBOTS) <= set(FILES)


def test_collada_robot_has_the_dof_and_mass_its_urdf_declares():
    file = ROOT / "panda_description/urdf/panda.urdf"
    row = survey.survey(file, ROOT)
    assert row.dof == 9  # 7 arm joints + 2 fingers (one mimics the other)
    assert "converted meshes" in row.notes
    urdf_mass_kg = sum(float(m.get("value")) for m in ET.parse(file).getroot().iter("mass"))
    assert row.mass_kg == pytest.approx(urdf_mass_kg, rel=1e-9)
