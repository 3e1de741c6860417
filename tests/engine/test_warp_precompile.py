"""engine.warp_precompile: a dry run of a body of MuJoCo Warp launches finds every module its real
first run needs and executes nothing; GpuEngine's first step then loads no module itself.

On Warp's CPU device (``AMBULO_TEST_DEVICE=cuda`` for a GPU). Whether a module compiles or comes from
Warp's kernel cache does not matter here: what is checked is which (module, block size) variants are
loaded before and during the real run, through ``Module.load``, the one call a launch loads through."""

import os

import mujoco
import pytest
import torch

mjw = pytest.importorskip("mujoco_warp")
import warp as wp
from warp._src.context import Module

from ambulo.engine import make_engine, warp_precompile
from ambulo.engine.warp_precompile import compile_in_processes, precompile, recording_launches
from script_loader import ROOT, load_script

DEVICE = os.environ.get("AMBULO_TEST_DEVICE", "cpu")
XML = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="5 5 .1"/>
<body pos="0 0 .3"><freejoint/><geom type="box" size=".05 .05 .05" mass="1"/></body>
<body pos=".4 0 .3"><freejoint/><geom type="capsule" size=".04 .1" mass="1"/></body>
</worldbody></mujoco>"""


@pytest.fixture
def loads(monkeypatch):
    """The (module name, block size) pairs ``Module.load`` is asked for while the fixture lives."""
    seen = []
    original = Module.load

    def load(self, device, block_dim=None, *args, **kwargs):
        seen.append((self.name, block_dim))
        return original(self, device, block_dim, *args, **kwargs)

    monkeypatch.setattr(Module, "load", load)
    return seen


def _model_and_data():
    model = mujoco.MjModel.from_xml_string(XML)
    with wp.ScopedDevice(DEVICE):
        return mjw.put_model(model), mjw.put_data(model, mujoco.MjData(model), nworld=2)


def test_the_dry_run_records_the_steps_modules_and_runs_nothing(loads):
    m, d = _model_and_data()
    qpos, time_s = d.qpos.numpy().copy(), d.time.numpy().copy()
    variants, counter = {}, [0]
    with wp.ScopedDevice(DEVICE), recording_launches(variants, counter):
        mjw.step(m, d)
    assert counter[0] > 20  # a step is dozens of launches
    assert sum(len(mods) for mods in variants.values()) > 5
    # nothing ran: no kernel advanced the clock or moved a body, and no module was loaded
    assert (d.time.numpy() == time_s).all() and (d.qpos.numpy() == qpos).all()
    assert loads == []
    assert wp.launch.__module__.startswith("warp")  # the real launch is back


def test_after_precompile_the_real_step_loads_nothing_new(loads):
    m, d = _model_and_data()
    with wp.ScopedDevice(DEVICE):
        report = precompile(lambda: mjw.step(m, d), max_workers=2)
        before = set(loads)
        assert report.modules > 5 and report.launches > 20
        mjw.step(m, d)
    real = set(loads) - before
    # the real step only looks up variants the precompile already loaded
    assert real == set(), sorted(real)[:5]
    assert (d.time.numpy() > 0).all()  # and it did run



def test_the_precompile_loads_only_what_the_real_step_loads(loads):
    """The scene has no equality constraint, tendon or flex: MuJoCo Warp launches their kernels over a zero
    dimension, which ``wp.launch`` skips without loading the module, so the precompile must not compile them
    either (on humanoid-rough such modules were 16 of the precompile's compiles, ~10 s of a ~50 s cold start
    on Warp's CPU device)."""
    m, d = _model_and_data()
    with wp.ScopedDevice(DEVICE):
        precompile(lambda: mjw.step(m, d), max_workers=2)
        precompiled = set(loads)
        loads.clear()
        mjw.step(m, d)
    unused = precompiled - set(loads)
    assert unused == set(), sorted(unused)[:5]


def test_a_launch_of_no_threads_is_counted_not_recorded():
    @wp.kernel(module="unique")
    def never(a: wp.array(dtype=wp.float32)):
        a[wp.tid()] = 1.0

    @wp.kernel(module="unique")
    def once(a: wp.array(dtype=wp.float32)):
        a[wp.tid()] = 2.0

    values = wp.zeros(4, dtype=wp.float32, device=DEVICE)
    variants, counter = {}, [0]
    with recording_launches(variants, counter):
        wp.launch(never, dim=(4, 0), inputs=[values], device=DEVICE)
        wp.launch_tiled(never, dim=0, inputs=[values], block_dim=1, device=DEVICE)
        wp.launch(once, dim=4, inputs=[values], device=DEVICE)
    assert counter[0] == 3
    assert [list(mods) for mods in variants.values()] == [[once.module]]
    assert values.numpy().tolist() == [0.0] * 4


def test_the_engines_first_step_precompiles_and_steps_as_without_it():
    model = mujoco.MjModel.from_xml_string(XML)
    fast = make_engine(model, 2, device=DEVICE, engine="warp", compile_workers=2)
    serial = make_engine(model, 2, device=DEVICE, engine="warp", compile_workers=0)
    for _ in range(20):
        fast.step()
        serial.step()
    assert fast.precompile_reports and not serial.precompile_reports
    # the dry run's copies were undone: both engines stepped the same trajectory
    torch.testing.assert_close(fast.qpos, serial.qpos, rtol=0, atol=0)
    assert (fast.qpos[:, 2] < 0.3).all()  # the bodies fell


def test_a_failing_precompile_is_logged_and_the_engine_compiles_serially(monkeypatch, caplog):
    """The precompile is an optimization: a Warp whose internals it does not know must cost time, not the run."""
    import ambulo.engine.gpu as gpu

    def broken(body, max_workers=None, processes=0):
        raise AttributeError("no _resolve_launch_block_dim in this Warp")

    monkeypatch.setattr(gpu, "precompile", broken)
    model = mujoco.MjModel.from_xml_string(XML)
    engine = make_engine(model, 2, device=DEVICE, engine="warp", compile_workers=2)
    reference = make_engine(model, 2, device=DEVICE, engine="warp", compile_workers=0)
    with caplog.at_level("WARNING", logger="ambulo.engine.gpu"):
        for _ in range(5):
            engine.step()
            reference.step()
    assert "parallel kernel precompile of step failed (AttributeError" in caplog.text
    assert not engine.precompile_reports
    torch.testing.assert_close(engine.qpos, reference.qpos, rtol=0, atol=0)


def test_another_threads_launches_run_during_the_dry_run():
    """The dry run patches ``wp.launch`` on the warp module; a launch from another thread in that window (a viewer
    rendering) must still run."""
    import threading

    @wp.kernel
    def add_one(a: wp.array(dtype=wp.float32)):
        a[wp.tid()] += 1.0

    values = wp.zeros(4, dtype=wp.float32, device=DEVICE)
    variants, counter = {}, [0]
    with recording_launches(variants, counter):
        worker = threading.Thread(target=lambda: wp.launch(add_one, dim=4, inputs=[values], device=DEVICE))
        worker.start()
        worker.join()
        wp.launch(add_one, dim=4, inputs=[values], device=DEVICE)  # this thread's: recorded, not run
    assert values.numpy().tolist() == [1.0] * 4
    assert counter[0] == 1 and [len(m) for m in variants.values()] == [1]


def test_the_benchmarks_profile_sums_codegen_and_native_and_counts_their_overlap():
    """benchmarks/warp_compile.py --profile: two native compiles that overlap for 1 s of their 2 s + 3 s make
    5 s of compile in 4 s of wall time (1.25 on average at once); a third 1 s after a gap adds 1 s to each."""
    benchmark = load_script(ROOT / "benchmarks" / "warp_compile.py")
    spans = [("codegen", "a", 0.0, 0.5), ("native", "a", 0.5, 2.5), ("codegen", "b", 0.5, 1.5),
             ("native", "b", 1.5, 4.5), ("native", "c", 10.0, 11.0), ("load", "a", 0.0, 2.6)]
    summary = benchmark._profile_summary(spans)
    assert summary["codegen_s"] == 1.5 and summary["native_s"] == 6.0 and summary["modules_compiled"] == 3
    assert summary["native_overlap"] == round(6.0 / 5.0, 2)
    assert list(summary["largest_native_s"]) == ["b", "a", "c"]


def test_the_benchmarks_profile_names_the_compiles_outside_the_parallel_loads():
    """--profile's serial_native_s: a native compile in a precompile's dry run or after it (a module's first launch)
    ran alone on the critical path; one in the precompile's loads did not."""
    benchmark = load_script(ROOT / "benchmarks" / "warp_compile.py")
    spans = [("precompile", "", 0.0, 10.0), ("dry_run", "", 0.0, 3.0), ("native", "queried", 1.0, 2.5),
             ("native", "loaded", 4.0, 9.0), ("native", "missed", 12.0, 13.0), ("native", "missed", 14.0, 14.5)]
    assert benchmark._profile_summary(spans)["serial_native_s"] == {"queried": 1.5, "missed": 1.5}


@wp.kernel(module="unique")
def _add_one(values: wp.array(dtype=wp.float32)):
    i = wp.tid()
    values[i] = values[i] + 1.0


@wp.kernel(module="unique")
def _double(values: wp.array(dtype=wp.float32)):
    i = wp.tid()
    values[i] = values[i] * 2.0


def _two_module_body(values):
    def body():
        wp.launch(_add_one, dim=4, inputs=[values], device=DEVICE)
        wp.launch(_double, dim=4, inputs=[values], device=DEVICE)
    return body


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """An empty Warp kernel cache for the test; Warp's own is back afterwards (initialized first, so
    what is restored is its real folder, not the unset value Warp's first use would fill in)."""
    wp.init()
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    return tmp_path


def _in_cache(device, block_dim, module) -> bool:
    """Whether the module's binary is in Warp's kernel cache (its folder: Warp's first use appends its version)."""
    folder = os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier(block_dim))
    return os.path.exists(os.path.join(folder, module._get_compile_output_name(device, block_dim=block_dim)))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="forked compile processes need os.fork")
def test_forked_processes_compile_each_module_into_the_kernel_cache(fresh_cache):
    values = wp.zeros(4, dtype=wp.float32, device=DEVICE)
    variants, counter = {}, [0]
    with recording_launches(variants, counter):
        _two_module_body(values)()
    jobs = [(wp.get_device(d), block_dim, m) for (d, block_dim), mods in variants.items() for m in mods]
    assert len(jobs) == 2 and not any(_in_cache(*job) for job in jobs)
    assert compile_in_processes(variants, processes=2) == (2, 0)
    assert all(_in_cache(*job) for job in jobs)  # the children compiled both, one each


@pytest.mark.skipif(not hasattr(os, "fork"), reason="forked compile processes need os.fork")
def test_failing_compile_processes_cost_time_not_correctness(fresh_cache, monkeypatch):

    def broken(module, device, block_dim):
        raise RuntimeError("NVRTC out of memory")

    monkeypatch.setattr(warp_precompile, "_compile_into_cache", broken)
    values = wp.zeros(4, dtype=wp.float32, device=DEVICE)
    report = precompile(_two_module_body(values), max_workers=1, processes=2)
    assert (report.processes, report.process_failures, report.modules) == (2, 2, 2)
    _two_module_body(values)()  # the loads compiled what the children did not: the kernels run
    assert values.numpy().tolist() == [2.0] * 4


def test_the_engine_takes_compile_processes_from_the_physics_config():
    model = mujoco.MjModel.from_xml_string(XML)
    engine = make_engine(model, 2, device=DEVICE, engine="warp", compile_workers=2, compile_processes=2)
    engine.step()
    (report,) = engine.precompile_reports.values()
    assert engine.compile_processes == 2 and report.processes == (2 if hasattr(os, "fork") else 0)
    assert report.process_failures == 0
