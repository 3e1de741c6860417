"""``engine.forward(kinematics_only=True)``: a reset's cheap pass, on both engines.

It must recompute what a full forward computes for poses, com and com velocities
(``KINEMATIC_FIELDS``), skip the collision, actuation and constraint stages (their fields keep
the values they had, and ``acc_stale`` says so), leave other worlds alone, and make the contact
sensor read "no contact" for the worlds whose contacts were not computed. The GPU engine runs on
Warp's CPU device here (``AMBULO_TEST_DEVICE=cuda`` runs it on a GPU).
"""

import importlib.util
import math
import os

import pytest
import torch

import ambulo.envs as envs
from ambulo.utils.math import quat_from_yaw

DEVICE = os.environ.get("AMBULO_TEST_DEVICE", "cpu")
ENGINES = ["mujoco", pytest.param("warp", marks=pytest.mark.skipif(
    importlib.util.find_spec("mujoco_warp") is None, reason="needs mujoco_warp"))]

# float32 kernels (MuJoCo Warp) of one state: fwd_kinematics and forward run the same ones
TOL = {"mujoco": 0.0, "warp": 1e-6}
# after a step, on a GPU: MuJoCo Warp's constraint solver sums with atomics there, so two identical
# envs stepped once already differ (qacc, a solver output, by more than 1e-6 on an H200, session 12);
# the comparison then bounds that nondeterminism, not the kinematics pass
STEP_TOL = {"mujoco": (0.0, 0.0), "warp": (1e-6, 0.0) if DEVICE == "cpu" else (1e-3, 1e-3)}


def _standing_env(engine: str):
    """humanoid-walk's 4 worlds after a few steps standing: feet on the ground, qacc and contact
    forces nonzero. Two envs made this way hold the same state (same seed, same steps)."""
    env = envs.make("humanoid-walk", num_envs=4, seed=5, device="cpu" if engine == "mujoco" else DEVICE,
                    engine=engine, push_interval_s=None, reset_forward="full")  # the env's own resets: full
    for _ in range(3):
        env.step(torch.zeros(env.num_envs, env.num_actions, device=env.device))
    return env


def _new_state(env, rows):
    """Reset ``rows`` (an (N,) mask) without a forward, then give them a yaw and a spin: a state
    whose kinematics differ from the last step's."""
    eng = env.engine
    eng.reset(rows, forward=False)
    yaw = torch.full((env.num_envs,), math.radians(40.0), dtype=eng.dtype, device=env.device)
    env.robot.write_root_pose(quat_w=quat_from_yaw(yaw), env_ids=rows)
    spin = torch.tensor([0.3, -0.2, 0.1, 0.5, -0.4, 1.5], dtype=eng.dtype, device=env.device)
    eng.qvel[:, :6] = torch.where(rows[:, None], spin, eng.qvel[:, :6])


KIN = ("xpos", "xquat", "subtree_com", "cvel", "site_xpos")
ACC = ("qacc", "qfrc_actuator", "sensordata")


@pytest.mark.parametrize("engine", ENGINES)
def test_kinematics_forward_computes_the_poses_and_velocities_and_skips_the_rest(engine):
    kin_env, full_env = _standing_env(engine), _standing_env(engine)
    kin, full = kin_env.engine, full_env.engine
    for name in KIN + ACC:  # bound in both: the fields a forward refreshes
        kin.field(name), full.field(name)
    rows = torch.tensor([False, True, False, True], device=kin_env.device)
    before = {n: kin.field(n).clone() for n in KIN + ACC}
    assert kin.acc_stale is None  # nothing stale before the first kinematics-only forward

    for env in (kin_env, full_env):
        _new_state(env, rows)
    kin.forward(rows, kinematics_only=True)
    full.forward(rows)

    for name in KIN:
        # the reset worlds' poses and velocities are those of a full forward of the new state
        assert not torch.equal(full.field(name)[rows], before[name][rows]), name
        torch.testing.assert_close(kin.field(name)[rows], full.field(name)[rows], atol=TOL[engine], rtol=0,
                                   msg=name)
    for name in KIN + ACC:  # the other worlds keep every bound field (they lag one substep)
        torch.testing.assert_close(kin.field(name)[~rows], before[name][~rows], atol=0, rtol=0, msg=name)
    for name in ACC:
        # no actuation, constraint solve or contact sensors ran: the reset worlds keep the values
        # of before (a full forward changes them), and acc_stale marks those worlds
        assert not torch.equal(full.field(name)[rows], before[name][rows]), name
        torch.testing.assert_close(kin.field(name)[rows], before[name][rows], atol=0, rtol=0, msg=name)
    assert torch.equal(kin.acc_stale, rows)

    # the contact sensor: a full forward finds the feet on the ground; the stale worlds read no
    # contact and zero force (their sensordata still holds the pre-reset contacts)
    kin_frame, full_frame = kin_env.feet.get_current_frame(), full_env.feet.get_current_frame()
    assert bool(full_frame.in_contact[rows].any())
    assert not bool(kin_frame.in_contact[rows].any())
    assert not bool(kin_frame.net_force_w[rows].any()) and not bool(kin_frame.num_contacts[rows].any())
    assert torch.equal(kin_frame.in_contact[~rows], full_frame.in_contact[~rows])

    # a step computes everything: nothing is stale, both engines hold the same state again
    kin.step(1)
    full.step(1)
    assert not bool(kin.acc_stale.any())
    for name in KIN + ACC:
        atol, rtol = STEP_TOL[engine]
        torch.testing.assert_close(kin.field(name), full.field(name), atol=atol, rtol=rtol, msg=name)
    assert torch.equal(kin_env.feet.get_current_frame().in_contact, full_env.feet.get_current_frame().in_contact)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_full_forward_clears_the_stale_mark_of_its_worlds(engine):
    env = _standing_env(engine)
    eng = env.engine
    everyone = torch.ones(env.num_envs, dtype=torch.bool, device=env.device)
    eng.forward(everyone, kinematics_only=True)
    eng.forward(torch.tensor([True, False, False, True], device=env.device))
    assert eng.acc_stale.tolist() == [False, True, True, False]
    eng.reset([1])  # a reset's own (full) forward
    assert eng.acc_stale.tolist() == [False, False, True, False]
