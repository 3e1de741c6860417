"""GpuEngine (MuJoCo Warp): CPU/GPU parity, zero-copy state, masked resets, per-world model
fields, divergence and overflow handling.

Runs on Warp's CPU device by default, so CI checks the GPU engine without a GPU; set
``AMBULO_TEST_DEVICE=cuda`` to run the same tests on a GPU (benchmarks/gpu_suite.sh does).
"""

import math
import os

import mujoco
import numpy as np
import pytest
import torch

pytest.importorskip("mujoco_warp")

import ambulo.envs as envs
from ambulo.engine import CpuEngine, make_engine
from ambulo.engine.gpu import EngineOverflowError, GpuEngine

DEVICE = os.environ.get("AMBULO_TEST_DEVICE", "cpu")

# Stated parity: from one settled state and one control sequence, float32 MuJoCo Warp and
# float64 MuJoCo agree in every qpos entry (m or rad) within this, over these horizons.
PARITY_TOL = 1e-4
JETBOT_HORIZON_S = 1.0  # driving at 5 rad/s wheel speed, steering +-1 rad/s
HUMANOID_HORIZON_S = 2.0  # standing under +-1 rad sinusoidal drive targets


def _gpu(model, n, **kw) -> GpuEngine:
    return make_engine(model, n, device=DEVICE, engine="warp", **kw)


def _task_model(task):
    env = envs.make(task, num_envs=1, seed=1)
    return env.model, env.engine.qpos[0].clone()


def _copy_state(src, dst):
    for name in ("qpos", "qvel", "act", "ctrl", "qacc_warmstart"):
        if src.field(name).numel():
            dst.field(name).copy_(src.field(name))


@pytest.mark.parametrize("task, horizon_s, drive", [
    ("jetbot-goal", JETBOT_HORIZON_S, 5.0),
    ("humanoid-walk", HUMANOID_HORIZON_S, 0.0),
])
def test_cpu_and_gpu_trajectories_agree_from_the_same_state_and_controls(task, horizon_s, drive):
    model, qpos0 = _task_model(task)
    cpu, gpu = CpuEngine(model, 2), _gpu(model, 2)
    cpu.qpos[:] = qpos0
    cpu.step(100)  # settle on the ground, then both engines start from this state
    _copy_state(cpu, gpu)
    ctrl0 = cpu.ctrl.clone()
    phase = torch.arange(model.nu, dtype=torch.float64)
    worst = 0.0
    steps = round(horizon_s / model.opt.timestep)
    for k in range(steps):
        u = ctrl0 + drive + 1.0 * torch.sin(2 * math.pi * k * model.opt.timestep + phase)
        cpu.ctrl[:] = u
        gpu.ctrl[:] = u.to(gpu.device)
        cpu.step()
        gpu.step()
        worst = max(worst, float((gpu.qpos.cpu().double() - cpu.qpos).abs().max()))
    moved = float((cpu.qpos[0, :2] - qpos0[:2]).norm())
    if task == "jetbot-goal":
        assert moved > 0.3, "the Jetbot must drive, or parity says little"
    assert worst < PARITY_TOL, f"{task}: max |qpos_gpu - qpos_cpu| = {worst:.2e} over {horizon_s} s"


def test_env_observations_and_rewards_match_the_cpu_engine():
    # same seed: same resets (drawn in float64 on both), same actions -> same observations
    a = envs.make("humanoid-walk", num_envs=3, seed=2, device=DEVICE, engine="warp")
    b = envs.make("humanoid-walk", num_envs=3, seed=2) if DEVICE == "cpu" else None
    if b is None:
        pytest.skip("torch's CUDA and CPU generators draw different resets")
    torch.testing.assert_close(a.get_observations(), b.get_observations(), atol=1e-5, rtol=0)
    for _ in range(10):
        actions = torch.zeros(3, a.num_actions)
        oa, ra, da, _ = a.step(actions)
        ob, rb, db, _ = b.step(actions)
    torch.testing.assert_close(oa, ob, atol=1e-3, rtol=0)
    torch.testing.assert_close(ra, rb, atol=1e-4, rtol=0)
    assert torch.equal(da, db)


def _box_model(n_boxes=1, gravity=True):
    bodies = "".join(f'<body name="b{i}" pos="{0.3 * i} 0 0.1"><freejoint/>'
                     f'<geom type="box" size=".05 .05 .05" mass="1"/></body>' for i in range(n_boxes))
    g = "" if gravity else ' gravity="0 0 0"'
    return mujoco.MjModel.from_xml_string(
        f'<mujoco><option timestep="0.002"{g}/><worldbody><geom type="plane" size="5 5 .1"/>'
        f'{bodies}</worldbody></mujoco>')


def test_state_tensors_are_zero_copy_and_writable():
    model = _box_model(gravity=False)
    engine = _gpu(model, 3)
    qvel = engine.qvel
    assert qvel.shape == (3, 6) and qvel.dtype == torch.float32 and qvel.device.type == torch.device(DEVICE).type
    ptr = qvel.data_ptr()
    qvel[1, 0] = 2.0  # world 1's box moves along x at 2 m/s
    engine.step(50)
    assert engine.qvel.data_ptr() == ptr
    x = engine.qpos[:, 0].cpu()
    assert float(x[1] - x[0]) == pytest.approx(2.0 * 50 * 0.002, rel=1e-4)
    assert float(x[2] - x[0]) == pytest.approx(0.0, abs=1e-7)


def test_per_world_mass_scales_the_acceleration_of_an_applied_force():
    model = _box_model(gravity=False)
    engine = _gpu(model, 3)
    mass = engine.model_field("body_mass")
    assert mass.shape == (3, model.nbody)
    mass[:, 1] = torch.tensor([1.0, 2.0, 4.0], device=engine.device)
    engine.xfrc_applied[:, 1, 0] = 3.0  # N along x
    engine.step(100)
    # v = F t / m, hand-computed for each world
    expected = torch.tensor([3.0, 1.5, 0.75]) * 100 * 0.002
    torch.testing.assert_close(engine.qvel[:, 0].cpu(), expected, rtol=1e-4, atol=0)
    # the per-world model is what get_model reports
    assert engine.get_model(2).body_mass[1] == pytest.approx(4.0)


def test_per_world_friction_changes_only_that_world():
    model = mujoco.MjModel.from_xml_string("""<mujoco><compiler angle="radian"/><option timestep="0.002"/><worldbody>
      <geom name="slope" type="plane" size="5 5 .1" euler="0 0.3 0"/>
      <body name="block" pos="0 0 0.2" euler="0 0.3 0"><freejoint/><geom type="box" size=".05 .05 .05"/></body>
      </worldbody></mujoco>""")
    engine = _gpu(model, 2)
    friction = engine.model_field("geom_friction")
    friction[0, :, 0] = 1.0  # tan(0.3) = 0.31: holds
    friction[1, :, 0] = 0.1  # slides
    engine.step(500)
    speed = engine.qvel[:, :3].norm(dim=1).cpu()
    assert float(speed[0]) < 0.01 and float(speed[1]) > 0.3


def test_masked_reset_restores_only_those_worlds_and_their_derived_fields():
    model = _box_model(n_boxes=2)
    engine = _gpu(model, 4)
    initial = engine.qpos.clone()
    _ = engine.xpos  # bound: forward on a subset must leave the other worlds' values alone
    engine.qvel[:, 0] = torch.tensor([1.0, 2.0, 3.0, 4.0], device=engine.device)
    engine.step(20)
    before_q, before_x = engine.qpos.clone(), engine.xpos.clone()
    mask = torch.tensor([False, True, False, True], device=engine.device)
    engine.reset(mask)
    torch.testing.assert_close(engine.qpos[mask], initial[mask], atol=0, rtol=0)
    torch.testing.assert_close(engine.qpos[~mask], before_q[~mask], atol=0, rtol=0)
    torch.testing.assert_close(engine.xpos[~mask], before_x[~mask], atol=0, rtol=0)
    fresh = mujoco.MjData(model)
    mujoco.mj_forward(model, fresh)
    torch.testing.assert_close(engine.xpos[1].cpu().double(), torch.from_numpy(fresh.xpos), atol=1e-6, rtol=0)
    # indices work like the mask
    engine.step(5)
    engine.reset([0])
    torch.testing.assert_close(engine.qpos[0], initial[0], atol=0, rtol=0)


def test_diverged_world_is_detected_and_reset_alone():
    model = _box_model(n_boxes=2)
    engine, reference = _gpu(model, 3), _gpu(model, 3)
    initial = engine.qpos.clone()
    engine.qvel[1, 0] = float("nan")
    diverged = engine.step(5)
    reference.step(5)
    assert diverged.tolist() == [False, True, False]
    assert engine.num_diverged == 1
    torch.testing.assert_close(engine.qpos[1], initial[1], atol=0, rtol=0)
    # the other worlds never saw it
    torch.testing.assert_close(engine.qpos[[0, 2]], reference.qpos[[0, 2]], atol=0, rtol=0)
    assert not engine.step(5).any()


def test_a_finite_runaway_counts_as_diverged_as_nan_and_inf_do():
    engine = _gpu(_box_model(n_boxes=2), 4)
    engine.qvel[1, 0] = 1e12  # finite, past the engine's 1e10 bound
    engine.qvel[2, 1] = float("inf")
    assert engine.step(1).tolist() == [False, True, True, False]


def test_contact_overflow_is_an_error_that_names_the_setting():
    model = _box_model(n_boxes=6)
    engine = _gpu(model, 2, max_contacts_per_world=2, overflow_check_steps=1)
    with pytest.raises(EngineOverflowError, match="max_contacts_per_world=2.*raise PhysicsCfg.max_contacts_per_world"):
        for _ in range(10):
            engine.step(20)  # the boxes land after 0.1 s


def test_default_buffers_hold_a_row_of_resting_boxes():
    model = _box_model(n_boxes=6)
    engine = _gpu(model, 2, overflow_check_steps=1)
    for _ in range(30):
        engine.step(5)  # 6 boxes resting: 24 contacts per world, no overflow
    assert float(engine.qpos[0, 2]) == pytest.approx(0.05, abs=2e-3)


def test_get_data_is_the_world_state_with_derived_fields():
    model = _box_model(n_boxes=2)
    engine = _gpu(model, 3)
    engine.qvel[2, 0] = 1.0
    engine.step(10)
    data = engine.get_data(2)
    np.testing.assert_allclose(data.qpos, engine.qpos[2].cpu().numpy(), atol=1e-7)
    np.testing.assert_allclose(data.xpos[1], data.qpos[:3], atol=1e-7)


def test_bad_device_and_engine_names_are_one_line_errors():
    from ambulo.utils.checks import InvalidValueError

    with pytest.raises(InvalidValueError, match="unknown engine"):
        make_engine(_box_model(), 1, engine="physx")
    with pytest.raises(InvalidValueError, match="runs on the CPU"):
        make_engine(_box_model(), 1, device="cuda", engine="mujoco")


@pytest.mark.parametrize("task", ["humanoid-walk", "jetbot-goal"])
def test_the_gpu_engine_runs_the_cpu_engines_options_but_a_float32_tolerance(task):
    """MuJoCo Warp may override options silently (put_model); the only override for our models is
    the solver tolerance, raised to 1e-6 for float32 (harmless: benchmarks/sim_to_sim.py)."""
    model, _ = _task_model(task)
    differ = make_engine(model, 1, device=DEVICE, engine="warp").option_differences()
    assert set(differ) == {"tolerance"}, differ
    assert differ["tolerance"][0] == model.opt.tolerance == 1e-8
    assert differ["tolerance"][1] == pytest.approx(1e-6)
