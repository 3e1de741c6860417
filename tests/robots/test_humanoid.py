"""robots/humanoid.py is the one home of the bundled humanoid's facts (issue 23): every fact agrees
with the humanoid's MJCF and the shipped policy's contract, and no other module under src/ambulo
restates the key ones."""

import json
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from ambulo import assets
from ambulo.robots import humanoid

SRC = Path(__file__).resolve().parents[2] / "src" / "ambulo"
HOME = SRC / "robots" / "humanoid.py"

GEOMETRY_TOL_M = 1e-6
"""The facts are the model's exact numbers (written in the MJCF); 1 um covers float rounding and the
``home`` keyframe's pelvis height, given to 8 decimals (soles at z = -2.3e-9 there)."""


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(assets.path(humanoid.ASSET))


def _at(model, qpos):
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data


def test_named_elements_exist_in_the_compiled_model(model):
    assert model.body(humanoid.BASE_BODY).id == model.body(model.joint("root").bodyid[0]).id  # the free joint's
    assert model.jnt_type[model.joint("root").id] == mujoco.mjtJoint.mjJNT_FREE
    for body in humanoid.FOOT_BODIES:
        model.body(body)
    for side in ("left", "right"):  # LEG_BODIES: each side's chain from the pelvis down to its foot
        thigh, shank, foot = (model.body(b).id for b in humanoid.LEG_BODIES if b.startswith(side))
        assert [model.body_parentid[b] for b in (thigh, shank, foot)] == [model.body(humanoid.BASE_BODY).id, thigh, shank]
        assert foot == model.body(f"{side}_foot").id
    for site, foot in zip(humanoid.SOLE_SITES, humanoid.FOOT_BODIES):
        assert model.site_bodyid[model.site(site).id] == model.body(foot).id
    for side in ("left", "right"):
        chain = [model.joint(f"{side}_{j}") for j in humanoid.LEG_JOINTS]
        assert all(model.jnt_type[j.id] == mujoco.mjtJoint.mjJNT_HINGE for j in chain)
        assert model.jnt_bodyid[chain[-1].id] == model.body(f"{side}_foot").id  # hip to ankle
    assert model.nu == 21
    assert model.site_bodyid[model.site(humanoid.IMU_SITE).id] == model.body(humanoid.BASE_BODY).id
    assert model.site_bodyid[model.site(humanoid.HEAD_CAMERA_SITE).id] == model.body("head").id
    assert humanoid.HEAD_CAMERA_PRIM == f"{humanoid.PRIM_PATH}/{humanoid.HEAD_CAMERA_SITE}/{humanoid.HEAD_CAMERA_LEAF}"
    assert humanoid.head_camera_prim("/World/X") == "/World/X/head_camera_mount/camera"


def test_the_head_camera_looks_forward_and_down_with_525_px_at_640():
    from ambulo.utils.rotations import quat_to_mat

    for width, height in ((640, 480), (160, 120)):
        cfg = humanoid.head_camera_cfg(width, height)
        k = cfg.intrinsics_matrix()
        assert k[0, 0] == k[1, 1] == pytest.approx(525.0 * width / 640)
        assert cfg.prim_path == humanoid.HEAD_CAMERA_PRIM
    # the optical axis (x of the 'world' convention) in the mount frame: ahead, 18 deg below the horizon
    axis = quat_to_mat(np.array(cfg.offset_quat)) @ np.array([1.0, 0.0, 0.0])
    pitch = np.radians(humanoid.HEAD_CAMERA_PITCH_DEG)
    np.testing.assert_allclose(axis, [np.cos(pitch), 0.0, -np.sin(pitch)], atol=1e-12)
    assert humanoid.head_camera_cfg(320, 240, pitch_deg=0.0).offset_quat == (1.0, 0.0, 0.0, 0.0)


def test_pelvis_height_and_sole_offsets_agree_with_the_model_geometry(model):
    base, (left, right) = model.body(humanoid.BASE_BODY).id, (model.site(s).id for s in humanoid.SOLE_SITES)
    # the initial state (all joints 0): standing straight-legged, soles on z = 0
    data = _at(model, model.qpos0)
    assert data.xpos[base][2] == pytest.approx(humanoid.PELVIS_HEIGHT_M, abs=GEOMETRY_TOL_M)
    for state in (model.qpos0, model.key("home").qpos):
        data = _at(model, state)
        soles = data.site_xpos[[left, right]]
        np.testing.assert_allclose(soles[:, 2], 0.0, atol=GEOMETRY_TOL_M)
        assert soles[0, 1] - soles[1, 1] == pytest.approx(humanoid.STANCE_WIDTH_M, abs=GEOMETRY_TOL_M)
        assert soles[:, 0].mean() - data.xpos[base][0] == pytest.approx(humanoid.SOLE_X_M, abs=GEOMETRY_TOL_M)
    # the sole box of each foot is SOLE_LENGTH_M x SOLE_WIDTH_M, centred on the sole site in x and y
    for site, foot in zip(humanoid.SOLE_SITES, humanoid.FOOT_BODIES):
        (geom,) = [g for g in range(model.ngeom) if model.geom_bodyid[g] == model.body(foot).id]
        assert model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_BOX
        np.testing.assert_allclose(2 * model.geom_size[geom][:2], (humanoid.SOLE_LENGTH_M, humanoid.SOLE_WIDTH_M),
                                   atol=GEOMETRY_TOL_M)
        np.testing.assert_allclose(model.geom_pos[geom][:2], model.site_pos[model.site(site).id][:2],
                                   atol=GEOMETRY_TOL_M)


def test_the_policy_dt_is_the_contracts():
    contract = json.loads((Path(assets.get_assets_root_path()) / "policies" / "humanoid_walk" / "contract.json")
                          .read_text())
    assert humanoid.POLICY_PHYSICS_DT_S == contract["physics_dt_s"]
    assert contract["robot_file"] == humanoid.ASSET
    from ambulo.policies.shipped import load_policy

    assert load_policy(humanoid.POLICY_TASK).contract["physics_dt_s"] == humanoid.POLICY_PHYSICS_DT_S


# Literal restatements of the key facts. Each pattern must match in robots/humanoid.py (so the test
# follows the facts) and nowhere else under src/ambulo (data files are not .py: the MJCF and the
# contract are the sources the facts are checked against above).
RESTATEMENTS = {
    "the prim path": r"""["']/World/robot["']""",
    "the Isaac-style stage prim path": r"""["']/World/Humanoid""",
    "a sole site name": r"""["'](left|right)_sole["']""",
    "a foot body name": r"""["'](left|right)_foot["']""",
    "the leg joints": r"""["']hip_roll["']""",
    "the head-camera mount": r"""["'][^"'\s]*head_camera_mount""",  # in a string, not a docstring's prose
    # a module constant or a World's step (the training task's own PhysicsCfg is where the step comes from)
    "the policy's physics dt": r"""(DT_S\s*=\s*0\.005\b|World\(physics_dt\s*=\s*0\.005\b)""",
    # in code (an assignment or a product), not a docstring's "525 px"
    "the head camera's focal length": r"""(=\s*525\b|\b525(\.0)?\s*\*)""",
    "the head lamp": r"""headlight\.diffuse\s*=""",
}
ALLOWED = {
    # RobotCfg's default prim path, for any robot (core/ cannot import robots/: robots/ builds on it)
    ("the prim path", "core/scene.py"),
    # the Unitree G1's prim path, not the bundled humanoid's
    ("the prim path", "envs/g1_walk.py"),
}


def restatements(root: Path = SRC) -> list[str]:
    found = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if path == HOME:
            continue
        for fact, pattern in RESTATEMENTS.items():
            if (fact, rel) in ALLOWED:
                continue
            for n, line in enumerate(path.read_text().splitlines(), 1):
                if re.search(pattern, line):
                    found.append(f"{rel}:{n}: {fact}: {line.strip()}")
    return found


def test_the_patterns_find_the_facts_at_home():
    text = HOME.read_text()
    for fact, pattern in RESTATEMENTS.items():
        if fact == "the policy's physics dt":  # read from contract.json, stated nowhere in src
            assert not re.search(pattern, text) and '["physics_dt_s"]' in text
        else:
            assert re.search(pattern, text), fact


def test_no_module_restates_the_humanoids_facts():
    found = restatements()
    assert not found, "import these from ambulo.robots.humanoid instead:\n" + "\n".join(found)
