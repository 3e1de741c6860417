"""engine.warp_precompile's coverage: after GpuEngine's precompiles, what an env does first (a forward at
creation, a mass randomization's set_const, a reset's kinematics pass, steps) loads no module variant that
a precompile did not load. A variant loaded outside a precompile is compiled there, serially: on an H200
host the humanoid's set_const modules and its occupancy-queried CCD and broadphase modules were ~40-55 s
of a ~100 s cold start.

On Warp's CPU device (``AMBULO_TEST_DEVICE=cuda`` for a GPU). What is checked is which (module, block size)
variants ``Module.load`` is asked for inside and outside the precompiles (a launch asks it on every call),
so the result does not depend on Warp's kernel cache or on modules earlier tests loaded."""

import os
from contextlib import contextmanager

import mujoco
import pytest
import torch

mjw = pytest.importorskip("mujoco_warp")
import warp as wp
from warp._src.context import Module

import ambulo.engine.gpu as gpu
from ambulo.engine import make_engine, warp_precompile
from ambulo.engine.warp_precompile import precompile, recording_launches

DEVICE = os.environ.get("AMBULO_TEST_DEVICE", "cpu")
# the smallest scene on MuJoCo Warp's paths the humanoid's cold start compiled serially: a free body with a
# hinged child is one 7-dof tree (above 6 dofs its inertia is factored in Cholesky tiles, set_const's too),
# ellipsoids collide through the convex CCD kernels, and a few geoms use the all-pairs (nxn) broadphase
XML = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="5 5 .1"/>
<body pos="0 0 .4"><freejoint/><geom type="box" size=".08 .05 .05" mass="2"/>
  <body pos="0 0 -.1"><joint type="hinge" axis="0 1 0" range="-1 1"/>
    <geom type="ellipsoid" size=".03 .03 .08" pos="0 0 -.08" mass=".5"/></body></body>
<body pos=".3 0 .3"><freejoint/><geom type="ellipsoid" size=".05 .04 .03" mass="1"/></body>
</worldbody></mujoco>"""


@pytest.fixture
def module_loads(monkeypatch):
    """``{"precompile": set, "outside": set}`` of the (module name, block size) variants ``Module.load`` is
    asked for within GpuEngine's precompiles (its worker threads included) and outside them."""
    seen = {"precompile": set(), "outside": set()}
    inside = [0]  # a plain counter, not thread-local: the precompile loads from a thread pool
    original_load, original_precompile = Module.load, gpu.precompile

    def load(self, device, block_dim=None, *args, **kwargs):
        variant = (self.name, self.options["block_dim"] if block_dim is None else block_dim)
        seen["precompile" if inside[0] else "outside"].add(variant)
        return original_load(self, device, block_dim, *args, **kwargs)

    def counted_precompile(*args, **kwargs):
        inside[0] += 1
        try:
            return original_precompile(*args, **kwargs)
        finally:
            inside[0] -= 1

    monkeypatch.setattr(Module, "load", load)
    monkeypatch.setattr(gpu, "precompile", counted_precompile)
    return seen


def _an_envs_first_calls(engine) -> None:
    """What an env's make, first reset and first steps ask of its engine (envs.base, humanoid_walk)."""
    engine.forward()  # the sim's creation
    engine.model_field("body_mass")[:, 1] += 0.5  # a startup base-mass randomization ...
    engine.set_const()  # ... and the constants derived from it
    engine.reset(forward=False)  # a reset: the state restored, then one kinematics pass
    engine.forward(kinematics_only=True)
    for _ in range(3):
        engine.step()


def test_an_envs_first_reset_and_steps_load_nothing_the_precompiles_did_not(module_loads):
    engine = make_engine(mujoco.MjModel.from_xml_string(XML), 2, device=DEVICE, engine="warp", compile_workers=2)
    _an_envs_first_calls(engine)
    precompiled, outside = module_loads["precompile"], module_loads["outside"]
    names = " ".join(name for name, _ in precompiled | outside)
    # the scene does run the paths in question, so their absence from ``missed`` means something
    for path in ("mujoco_warp._src.set_const", "_tile_cholesky_factorize_block", "ccd_kernel", "_nxn_broadphase"):
        assert path in names, f"the scene no longer exercises {path}"
    missed = outside - precompiled
    assert missed == set(), f"compiled at their first launch, after the precompiles: {sorted(missed)}"
    assert {key[0] for key in engine.precompile_reports} == {"forward", "set_const", "forward_kinematics", "step"}
    assert torch.isfinite(engine.qpos).all() and (engine.field("time") > 0).all()  # and the calls ran


@wp.kernel(module="unique")
def _wide(values: wp.array(dtype=wp.float32)):
    values[wp.tid()] = 1.0


@wp.kernel(module="unique")
def _narrow(values: wp.array(dtype=wp.float32)):
    values[wp.tid()] = 2.0


@contextmanager
def _occupancy_queries_load_as_on_cuda(monkeypatch):
    """On the CPU, where ``wp.get_suggested_block_size`` loads nothing, its dry-run handling as on a CUDA device
    (a variant not loaded gets a stand-in answer), the CPU's block size (1) standing for CUDA's default and the
    stand-in a CUDA-like (64, 132) where the CPU's real answer is (1, 1)."""
    def variant(kernel, device):
        loaded = warp_precompile._is_loaded(kernel.module, device, 1)
        return None if loaded or kernel.is_generic else (kernel.module, 1)

    monkeypatch.setattr(warp_precompile, "_occupancy_variant", variant)
    monkeypatch.setattr(warp_precompile, "_stand_in_answer", lambda block_dim, device: (64, 132))
    yield


@pytest.mark.skipif(DEVICE != "cpu", reason="stands the CPU in for a CUDA device; a CUDA device runs the real thing")
def test_an_occupancy_query_is_answered_after_the_loads_and_what_its_answer_chooses_is_recorded(monkeypatch):
    """MuJoCo Warp queries a kernel's occupancy (loading its module, serially, in the dry run) and may choose the
    kernel it launches by the answer: the dry run records the queried module with a stand-in answer, loads it,
    and runs again with the real answer, recording the kernel that answer chooses."""
    values = wp.zeros(4, dtype=wp.float32, device=DEVICE)
    answers = []

    def body():
        answer = wp.get_suggested_block_size(_wide, DEVICE)
        answers.append(answer)
        # as MuJoCo Warp's deterministic sparse gradient: the answer chooses the kernel launched
        wp.launch(_narrow if answer == (1, 1) else _wide, dim=4, inputs=[values], device=DEVICE)

    with _occupancy_queries_load_as_on_cuda(monkeypatch):
        report = precompile(body, max_workers=1)
        real = warp_precompile._occupancy_variant(_narrow, wp.get_device(DEVICE))
    assert real is None, "the kernel the real answer chooses was not precompiled: the real run compiles it"
    assert report.passes == 2 and answers == [(64, 132), (1, 1)]
    assert values.numpy().tolist() == [0.0] * 4  # and nothing ran


def test_occupancy_queries_that_load_nothing_are_answered_as_ever():
    """Where Warp's answer costs no compile (Warp's CPU device: (1, 1)), the dry run passes the query on and
    records nothing for it: one pass."""
    variants, counter, stand_ins = {}, [0], []
    with recording_launches(variants, counter, stand_ins):
        answer = wp.get_suggested_block_size(_wide, "cpu")
    assert answer == (1, 1) and variants == {} and stand_ins == []
