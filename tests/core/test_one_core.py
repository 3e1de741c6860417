"""One core under every app: the World and a registered task compile the same robot alike."""

import mujoco
import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo import assets
from ambulo.core import GroundCfg, PhysicsCfg, Simulation, add_ground, compile_scene, new_scene
from ambulo.engine import Engine
from ambulo.sim import World, add_reference_to_stage

_OPTION_FIELDS = ("timestep", "gravity", "integrator", "solver", "iterations", "ls_iterations", "cone",
                  "impratio", "tolerance", "noslip_iterations", "o_margin", "o_solref", "o_solimp",
                  "density", "viscosity", "wind", "magnetic", "disableflags", "enableflags", "jacobian")
_GEOM_CONTACT = ("geom_friction", "geom_solref", "geom_solimp", "geom_solmix", "geom_condim", "geom_contype",
                 "geom_conaffinity", "geom_margin", "geom_gap", "geom_priority")
_JOINT = ("jnt_range", "jnt_limited", "dof_damping", "dof_armature", "dof_frictionloss", "jnt_actfrcrange")
_ACTUATOR = ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange", "actuator_forcelimited",
             "actuator_gear")


def _by_name(model, kind, count, field, prefix):
    """Values of ``field`` keyed by element name relative to ``prefix`` (the robot's prim path)."""
    values = getattr(model, field)
    return {getattr(model, kind)(i).name.removeprefix(prefix): np.asarray(values[i]) for i in range(count)}


def test_a_urdf_robot_compiles_identically_through_world_and_a_registered_task():
    cfg = envs.make_cfg("cartpole")
    env = envs.make("cartpole", num_envs=2, num_threads=1)
    # the Isaac-style path: a World with the task's physics, the same ground, the same URDF
    world = World(physics=cfg.physics, num_threads=1)
    g = cfg.ground
    world.scene.add_default_ground_plane(static_friction=g.static_friction, dynamic_friction=g.dynamic_friction,
                                         restitution=g.restitution, prim_path=g.prim_path)
    add_reference_to_stage(assets.path("cartpole"), "/World/cartpole", fixed_base=True,
                           drive_stiffness=cfg.robot.drives.stiffness, drive_damping=cfg.robot.drives.damping)
    world.reset()
    a, b = world.model, env.model
    for name in _OPTION_FIELDS:
        np.testing.assert_array_equal(np.asarray(getattr(a.opt, name)), np.asarray(getattr(b.opt, name)),
                                      err_msg=f"opt.{name}")
    groups = [("geom", a.ngeom, _GEOM_CONTACT, "/World/cartpole/"), ("joint", a.njnt, _JOINT, "/World/cartpole/"),
              ("actuator", a.nu, _ACTUATOR, "/World/cartpole/")]
    for kind, count, fields, prefix in groups:
        assert count == {"geom": b.ngeom, "joint": b.njnt, "actuator": b.nu}[kind]
        for field in fields:
            left = _by_name(a, kind, count, field, prefix)
            right = _by_name(b, kind, count, field, prefix)
            assert left.keys() == right.keys()
            for key in left:
                np.testing.assert_array_equal(left[key], right[key], err_msg=f"{field} of {key}")
    # and the task drives that robot through the same Entity the World's Articulation wraps
    assert env.robot.joint_names == ["slider", "hinge"]
    assert isinstance(env.engine, Engine) and isinstance(world.engine, Engine)


def test_physics_cfg_is_the_only_source_of_solver_options():
    spec = new_scene()
    add_ground(spec, GroundCfg())
    spec.option.iterations = 7  # an edit outside PhysicsCfg does not survive compilation
    model = compile_scene(spec, PhysicsCfg(solver_iterations=33, cone="elliptic", impratio=2.0))
    assert (model.opt.iterations, model.opt.cone, model.opt.impratio) == (
        33, mujoco.mjtCone.mjCONE_ELLIPTIC, 2.0)
    with pytest.raises(ValueError, match="integrator is 'rk5': unknown integrator; use one of"):
        PhysicsCfg(integrator="rk5")


class Recorder:
    """A component that records the lifecycle calls it receives."""

    def __init__(self):
        self.name, self.calls = "recorder", []

    def build(self, spec):
        spec.worldbody.add_site(name="recorder_site")
        self.calls.append("build")

    def initialize(self, engine):
        assert engine.model.site("recorder_site").id >= 0  # built into the compiled model
        self.calls.append(("initialize", engine.num_worlds))

    def update(self, dt_s):
        self.calls.append(("update", round(dt_s, 6)))

    def reset(self, world_ids=None):
        self.calls.append(("reset", None if world_ids is None else world_ids.tolist()))


def test_simulation_drives_components_through_build_initialize_update_reset():
    sim = Simulation(new_scene(), PhysicsCfg(timestep_s=0.002), num_worlds=3, num_threads=1)
    recorder = sim.add(Recorder())
    assert sim.add(recorder) is recorder  # adding the same object twice builds it once
    with pytest.raises(ValueError, match="already exists"):
        sim.add(Recorder())
    sim.start()
    sim.step(5)
    sim.reset(torch.tensor([False, True, False]))
    assert recorder.calls == ["build", ("initialize", 3), ("update", 0.01), ("reset", [False, True, False])]
