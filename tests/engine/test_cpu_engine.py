"""CpuEngine: zero-copy tensors, determinism, per-world reset and fields, divergence handling."""

import mujoco
import pytest
import torch

from ambulo import assets
from ambulo.engine import CpuEngine, make_engine


def _humanoid_scene_spec() -> mujoco.MjSpec:
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.005
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[10, 10, 0.1])
    spec.attach(mujoco.MjSpec.from_file(assets.path("humanoid")), prefix="h/",
                frame=spec.worldbody.add_frame())
    return spec


def _humanoid_scene_model():
    return _humanoid_scene_spec().compile()


def _rollout(num_worlds, seed, steps=150):
    model = _humanoid_scene_model()
    engine = CpuEngine(model, num_worlds)
    gen = torch.Generator().manual_seed(seed)
    trajectory = []
    for _ in range(steps):
        engine.ctrl[:] = 50.0 * torch.randn(num_worlds, model.nu, generator=gen, dtype=torch.float64)
        engine.step(2)
        trajectory.append(engine.qpos.clone())
    return torch.stack(trajectory)


@pytest.mark.parametrize("num_worlds", [1, 64])
def test_same_seed_and_actions_give_bit_identical_trajectories(num_worlds):
    a, b = _rollout(num_worlds, seed=3), _rollout(num_worlds, seed=3)
    assert torch.equal(a, b)
    assert not torch.equal(a, _rollout(num_worlds, seed=4))


def test_worlds_match_single_world_runs():
    # world i of a batch equals a lone run given world i's controls (no cross-talk)
    model = _humanoid_scene_model()
    batch, single = CpuEngine(model, 8), CpuEngine(model, 1)
    ctrl = 40.0 * torch.randn(30, 8, model.nu, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    for t in range(30):
        batch.ctrl[:] = ctrl[t]
        single.ctrl[:] = ctrl[t, 5]
        batch.step()
        single.step()
    assert torch.equal(batch.qpos[5], single.qpos[0])


def test_state_tensors_are_zero_copy_views_and_outputs_refresh():
    model = _humanoid_scene_model()
    engine = CpuEngine(model, 4)
    qpos = engine.qpos
    assert qpos.shape == (4, model.nq) and qpos.dtype == torch.float64
    assert engine.field("qpos").data_ptr() == qpos.data_ptr()
    qpos[2, 2] += 1.0  # lift world 2's pelvis by 1 m
    engine.forward()
    pelvis = model.body("h/pelvis").id
    assert engine.xpos[2, pelvis, 2] - engine.xpos[0, pelvis, 2] == pytest.approx(1.0)


def _humanoid_with_filtered_actuator_model():
    """The humanoid scene plus one first-order filter actuator, so that worlds carry ``act`` state."""
    spec = _humanoid_scene_spec()
    spec.add_actuator(name="filtered", target="h/torso_yaw", trntype=mujoco.mjtTrn.mjTRN_JOINT,
                      dyntype=mujoco.mjtDyn.mjDYN_FILTER, dynprm=[0.05] + [0.0] * 9,
                      gainprm=[20.0] + [0.0] * 9)
    return spec.compile()


def test_reset_restores_only_the_given_worlds():
    model = _humanoid_with_filtered_actuator_model()
    assert model.na == 1
    engine = CpuEngine(model, 4, num_threads=1)
    fields = ("time", "qpos", "qvel", "act")
    initial = {f: engine.field(f).clone() for f in fields}
    _ = engine.xpos  # bind the output now: from here on only the engine's own calls refresh it
    # what a fresh forward of the initial state computes, from plain MuJoCo
    fresh = mujoco.MjData(model)
    mujoco.mj_forward(model, fresh)
    assert torch.equal(initial["qpos"][1], torch.from_numpy(fresh.qpos))
    # drive every world somewhere else: different controls per world, so all four differ
    gen = torch.Generator().manual_seed(1)
    for _ in range(40):
        engine.ctrl[:] = 20.0 * torch.randn(4, model.nu, generator=gen, dtype=torch.float64)
        engine.step()
    before = {f: engine.field(f).clone() for f in fields}
    for world in range(4):
        for f in ("qpos", "qvel", "act"):
            assert not torch.equal(before[f][world], initial[f][world]), (f, world)
    assert not torch.equal(before["qpos"][1], before["qpos"][3])

    engine.reset([1, 3])

    for f in fields:
        after = engine.field(f)
        for world in (1, 3):  # reset: exactly the initial state, not only the clock
            assert torch.equal(after[world], initial[f][world]), (f, world)
        for world in (0, 2):  # untouched: exactly as before the reset
            assert torch.equal(after[world], before[f][world]), (f, world)
    # derived fields of the reset worlds describe the initial state, as a fresh mj_forward does
    for world in (1, 3):
        torch.testing.assert_close(engine.xpos[world], torch.from_numpy(fresh.xpos), rtol=0, atol=1e-12)
    assert not torch.allclose(engine.xpos[0], torch.from_numpy(fresh.xpos))


def test_per_world_friction_changes_only_that_world():
    spec = mujoco.MjSpec.from_string("""<mujoco><compiler angle="radian"/><option timestep="0.002"/><worldbody>
      <geom name="slope" type="plane" size="5 5 .1" euler="0 0.3 0"/>
      <body name="block" pos="0 0 0.2" euler="0 0.3 0"><freejoint/><geom type="box" size=".05 .05 .05"/></body>
      </worldbody></mujoco>""")
    model = spec.compile()
    engine = CpuEngine(model, 2)
    # tan(0.3 rad) = 0.31: friction 1.0 holds the block, 0.1 lets it slide
    engine.model_field("geom_friction")[0, :, 0] = 1.0
    engine.model_field("geom_friction")[1, :, 0] = 0.1
    engine.step(500)
    assert float(engine.qvel[0, :3].norm()) < 0.01  # held (soft contacts creep by mm/s)
    assert float(engine.qvel[1, :3].norm()) > 0.3


def test_diverged_world_is_detected_reported_and_reset_alone(caplog):
    model = _humanoid_scene_model()
    engine = CpuEngine(model, 3)
    engine.step(10)
    healthy = engine.qpos[0].clone()
    engine.qvel[1, 0] = float("nan")
    with caplog.at_level("WARNING"):
        diverged = engine.step()
    assert diverged.tolist() == [False, True, False]
    assert "diverged" in caplog.text
    assert torch.equal(engine.qpos[1], torch.from_numpy(engine.initial_state)[1, 1:1 + model.nq])
    assert not torch.equal(engine.qpos[0], healthy)  # world 0 kept stepping
    assert engine.num_diverged == 1


def test_bad_arguments_name_the_fix():
    model = _humanoid_scene_model()
    with pytest.raises(ValueError, match="num_worlds"):
        CpuEngine(model, 0)
    engine = make_engine(model, 2, "cpu")
    with pytest.raises(IndexError, match="out of range"):
        engine.reset([5])
    with pytest.raises(ValueError, match="xpoz|not an MjData"):
        engine.field("xpoz")
    with pytest.raises(ValueError, match="unknown device"):
        make_engine(model, 2, "tpu")
