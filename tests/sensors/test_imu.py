"""IMU: gravity at rest, frame rotation, free fall, and Kalibr noise recovered by Allan deviation."""

import allantools
import mujoco
import numpy as np
import pytest
import torch

from ambulo.engine import CpuEngine
from ambulo.sensors import Imu, ImuCfg, euroc_adis16448
from ambulo.sim import DynamicCuboid, World

RATE_HZ = 200.0


def box_with_imu(imu_cfg: ImuCfg, num_worlds=1, height=0.1):
    """A free 0.2 m box resting on a plane, an IMU on its body."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1])
    body = spec.worldbody.add_body(name="/World/box", pos=[0, 0, height])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1])
    imu = Imu(imu_cfg)
    imu.build(spec)
    engine = CpuEngine(spec.compile(), num_worlds, num_threads=1)
    imu.initialize(engine)
    return engine, imu


def test_at_rest_reads_plus_g_on_the_up_axis():
    engine, imu = box_with_imu(ImuCfg(prim_path="/World/box/imu"))
    for _ in range(200):
        engine.step()
    data = imu.get_current_frame()
    assert np.allclose(data.lin_acc_b[0].numpy(), [0, 0, 9.81], atol=0.01)
    assert np.allclose(data.ang_vel_b[0].numpy(), 0, atol=1e-6)
    assert np.allclose(data.quat_w[0].numpy(), [1, 0, 0, 0], atol=1e-6)


def test_rotated_imu_sees_gravity_along_its_own_axes():
    # IMU rolled +90 deg about x: its y axis R e_y = (0, 0, 1) is world up
    roll = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0)
    engine, imu = box_with_imu(ImuCfg(prim_path="/World/box/imu", offset_quat=roll))
    for _ in range(100):
        engine.step()
    assert np.allclose(imu.get_current_frame().lin_acc_b[0].numpy(), [0, 9.81, 0], atol=0.01)
    engine_ng, imu_ng = box_with_imu(ImuCfg(prim_path="/World/box/imu", include_gravity=False))
    for _ in range(100):
        engine_ng.step()
    assert np.allclose(imu_ng.get_current_frame().lin_acc_b[0].numpy(), 0, atol=0.01)


def test_free_fall_reads_zero_specific_force():
    engine, imu = box_with_imu(ImuCfg(prim_path="/World/box/imu"), height=5.0)
    for _ in range(20):
        engine.step()
    assert np.allclose(imu.get_current_frame().lin_acc_b[0].numpy(), 0, atol=1e-6)


def test_rate_holds_samples_between_updates_and_noise_is_seeded():
    cfg = ImuCfg(prim_path="/World/box/imu", rate_hz=50.0, noise=euroc_adis16448(), seed=7)
    engine, imu = box_with_imu(cfg, num_worlds=2)
    readings = []
    for _ in range(8):  # 8 steps of 2 ms = 16 ms: samples at 0 ms (first read) and after 20 ms only
        engine.step()
        readings.append(imu.get_current_frame().lin_acc_b.clone())
    assert all(torch.equal(r, readings[0]) for r in readings)
    assert not torch.equal(readings[0][0], readings[0][1])  # worlds draw independent noise
    engine2, imu2 = box_with_imu(cfg, num_worlds=2)
    engine2.step()
    assert torch.equal(imu2.get_current_frame().lin_acc_b, readings[0])


def test_rate_samples_exactly_at_multiples_of_the_period():
    # 50 Hz on 2 ms physics steps: a sample period is 10 steps. Reading after every step
    # over 4 periods must give the samples taken at t = 0, 20, 40, 60, 80 ms and nothing else.
    rate_hz, dt, periods = 50.0, 0.002, 4
    steps_per_period = 10
    world = World(physics_dt=dt)
    world.scene.add_default_ground_plane()
    world.scene.add(DynamicCuboid(prim_path="/World/box", position=[0, 0, 0.1], size=0.2))
    imu = world.scene.add(Imu(ImuCfg(prim_path="/World/box/imu", rate_hz=rate_hz,
                                     noise=euroc_adis16448(), seed=7)))
    world.reset()

    def read():
        frame = imu.get_current_frame()
        return (float(frame.time_s[0]), frame.lin_acc_b[0].clone(), frame.ang_vel_b[0].clone())

    samples = [read()]  # step 0, t = 0: the first read samples
    for step in range(1, periods * steps_per_period + 1):
        world.step()
        assert world.current_time == pytest.approx(step * dt, abs=1e-12)
        samples.append(read())
        again = read()  # a second read at the same time returns the same sample
        assert again[0] == samples[-1][0]
        assert torch.equal(again[1], samples[-1][1]) and torch.equal(again[2], samples[-1][2])

    for step, (time_s, acc, gyro) in enumerate(samples):
        # the sample is the one taken at the last multiple of 1/R at or before now
        assert time_s == pytest.approx((step // steps_per_period) / rate_hz, abs=1e-12), step
        previous_time, previous_acc, previous_gyro = samples[max(step - 1, 0)]
        if step % steps_per_period:  # inside a period: the very same sample
            assert time_s == previous_time
            assert torch.equal(acc, previous_acc) and torch.equal(gyro, previous_gyro)
        elif step:  # a period elapsed: a new sample, with new noise
            assert time_s > previous_time
            assert not torch.equal(acc, previous_acc) and not torch.equal(gyro, previous_gyro)
    assert len({time_s for time_s, _, _ in samples}) == periods + 1


def allan_fit(signal: np.ndarray, rate_hz: float) -> tuple[float, float]:
    """Noise density N and random walk K from sigma^2(tau) = N^2/tau + K^2 tau/3, axes pooled.

    Least squares in relative terms (each tau weighs the same) over octave taus.
    """
    taus, variances = None, []
    for axis in range(signal.shape[1]):
        taus, adev, _, _ = allantools.oadev(signal[:, axis], rate=rate_hz, data_type="freq", taus="octave")[:4]
        variances.append(adev ** 2)
    var = np.mean(variances, 0)
    keep = taus <= len(signal) / rate_hz / 8  # at least 8 clusters per tau
    taus, var = taus[keep], var[keep]
    design = np.stack([1 / taus, taus / 3], 1) / var[:, None]
    (n2, k2), *_ = np.linalg.lstsq(design, np.ones_like(var), rcond=None)
    return float(np.sqrt(n2)), float(np.sqrt(k2))


@pytest.mark.parametrize("kind", ["accel", "gyro"])
def test_one_static_hour_at_200hz_recovers_kalibr_parameters(kind):
    noise = euroc_adis16448()
    engine, imu = box_with_imu(ImuCfg(prim_path="/World/box/imu", noise=noise, seed=3))
    for _ in range(100):
        engine.step()
    acc, gyro, _ = imu.clean_reading()
    clean, model = (acc, imu.accel_noise) if kind == "accel" else (gyro, imu.gyro_noise)
    steps = int(3600 * RATE_HZ)
    samples = model.sample(clean[None].expand(steps, 1, 3), 1.0 / RATE_HZ)[:, 0].numpy()
    density, walk = allan_fit(samples, RATE_HZ)
    want_density = getattr(noise, f"{kind}_noise_density")
    want_walk = getattr(noise, f"{kind}_random_walk")
    assert density == pytest.approx(want_density, rel=0.10)
    assert walk == pytest.approx(want_walk, rel=0.25)
    # at rest the mean is the true value plus the turn-on bias (0.5 deg/s, 20 mg scale)
    assert np.abs(samples.mean(0) - clean[0].numpy()).max() < 5 * getattr(noise, f"{kind}_turn_on_bias_std") + 0.1
