"""An Isaac Gym sim on ambulo's core: N ``create_env`` calls become ONE model stepped in N worlds.

Isaac Gym scripts build envs one by one (``create_env`` then ``create_actor`` in a loop); every env
holds the same actors in the same order, so ambulo compiles env 0's actors once (``core.scene``)
and steps that model in ``num_envs`` worlds of one engine (``engine.make_engine``); each actor is a
``core.Entity`` over all worlds. Per-env differences Isaac allows and a batched model keeps per
world are applied after compiling: start poses, DOF properties (drive gains, armature, friction).
Envs with different actors fail with a one-line error: they cannot share one model.

Frames: Isaac Gym reports poses in the sim frame, where env ``i`` sits at its grid origin
(``get_env_origin``); each ambulo world holds one env at its own origin, so reads add the origin
and writes subtract it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import torch

from ambulo.core import Entity, GroundCfg, PhysicsCfg, add_ground, compile_scene, new_scene
from ambulo.engine import make_engine
from ambulo.sensors.contact import ContactSensor, ContactSensorCfg

from . import terrain as terrains
from .assets import Asset, collision_geoms, drive_gains
from .types import DOF_MODE_EFFORT, UP_AXIS_Z, PlaneParams, SimParams, Transform, Vec3

log = logging.getLogger(__name__)


@dataclass
class Actor:
    """One ``create_actor`` call: the handle a script gets is its index in the env."""

    asset: Asset
    pose: Transform
    name: str
    group: int
    filter: int
    dof_props: np.ndarray
    """This actor's DOF properties (a copy of the asset's until the script sets them)."""
    shape_props: list = field(default_factory=list)
    """This actor's ``RigidShapeProperties`` (the asset's at ``create_actor``)."""
    body_props: list = field(default_factory=list)
    """This actor's ``RigidBodyProperties`` (the asset's at ``create_actor``)."""


@dataclass
class Env:
    """One ``create_env`` call."""

    index: int
    origin: np.ndarray
    """(3,) the env's origin in the sim frame, m."""
    sim: Sim
    actors: list[Actor] = field(default_factory=list)


def physics_of(params: SimParams) -> PhysicsCfg:
    """The MuJoCo physics of Isaac ``SimParams``: one MuJoCo step per PhysX substep.

    PhysX's iteration counts and solver type have no MuJoCo counterpart (MuJoCo's Newton solver
    converges in a few iterations to the constraint solution PhysX approaches), so they are not
    mapped; nor are ``contact_offset``/``rest_offset`` (see ``Sim.prepare``)."""
    if params.up_axis != UP_AXIS_Z:
        raise ValueError("isaacgym: ambulo's worlds are z-up; set sim_params.up_axis = gymapi.UP_AXIS_Z and "
                         "sim_params.gravity = gymapi.Vec3(0.0, 0.0, -9.81)")
    if params.substeps < 1:
        raise ValueError(f"isaacgym: sim_params.substeps is {params.substeps}; pass 1 or more")
    g = params.gravity
    # MuJoCo's default pyramidal cones let a loaded contact creep where PhysX's friction sticks (an
    # ANYmal on legged_gym's actuator network sinks 0.1 m in 2 s as its feet splay). Elliptic cones
    # with impratio 10-100 hold it, but legged_gym's anymal_c_flat then trained worse on the CPU
    # (episode length fell back after ~15 iterations in two runs), so the default stays until that
    # is understood
    return PhysicsCfg(timestep_s=params.dt / params.substeps, gravity_m_s2=(g.x, g.y, g.z))


class Sim:
    """The state behind a ``Sim`` handle: envs while building, then the engine and entities."""

    def __init__(self, params: SimParams, device: str):
        self.params = params
        self.physics = physics_of(params)
        self.device = torch.device(device)
        self.ground: PlaneParams | None = None
        self.terrains: list[terrains.HeightField] = []
        """``add_heightfield`` / ``add_triangle_mesh`` terrain, as height fields."""
        self.envs: list[Env] = []
        self.asset_cache: dict[tuple[str, str], Asset] = {}
        """(file, options) -> the asset ``load_asset`` returned for them."""
        self.tensors = None
        """The ``SimTensors`` of the tensor API, from ``prepare_sim`` on."""
        self.engine = None
        self.entities: list[Entity] = []
        self.contacts: ContactSensor | None = None
        self.sim_time_s = 0.0
        self.frame_count = 0
        self.effort_mode: list[torch.Tensor] = []
        """Per actor, (N, J) bool: DOFs in ``DOF_MODE_EFFORT``, where actuation forces apply."""
        self._expanded: set[str] = set()
        """Model fields written per world so far (``_write_model_rows``)."""

    # -- building ----------------------------------------------------------------------------
    def add_env(self, lower: Vec3, upper: Vec3, per_row: int) -> Env:
        """Isaac's env grid: env ``i`` at column ``i % per_row``, row ``i // per_row``, spaced by
        the env's extent ``upper - lower``."""
        if self.engine is not None:
            raise RuntimeError("isaacgym: create_env after prepare_sim; create every env before prepare_sim")
        i = len(self.envs)
        per_row = max(int(per_row), 1)
        extent = upper - lower
        origin = np.array([(i % per_row) * extent.x, (i // per_row) * extent.y, 0.0])
        env = Env(i, origin, self)
        self.envs.append(env)
        return env

    @property
    def actors_per_env(self) -> list[Actor]:
        return self.envs[0].actors if self.envs else []

    def prepare(self) -> None:
        """Compile env 0's actors once and start ``num_envs`` worlds of it (``prepare_sim``)."""
        if self.engine is not None:
            return
        if not self.envs or not self.envs[0].actors:
            raise RuntimeError("isaacgym: prepare_sim with no actors; create_env and create_actor first")
        template = [a.asset for a in self.envs[0].actors]
        for env in self.envs:
            if [a.asset for a in env.actors] != template:
                raise ValueError(
                    f"isaacgym: env {env.index} holds other actors than env 0 ({len(env.actors)} vs {len(template)}); "
                    "ambulo steps all envs as worlds of one model, so every env must create the same assets in "
                    "the same order (vary poses and DOF properties instead)")
        spec = new_scene("isaacgym")
        if self.ground is not None:
            add_ground(spec, ground_cfg(self.ground))
        for k, terrain in enumerate(self.terrains):
            terrains.add_to_spec(spec, terrain, f"/World/terrain{k}")
        paths = [f"/World/actor{k}" for k in range(len(template))]
        for asset, path in zip(template, paths, strict=True):
            asset.attach(spec, path)
        physx = self.params.physx
        for geom in _actor_geoms(spec):  # by body: a URDF's geoms have no names
            # PhysX averages two shapes' frictions, MuJoCo takes the larger: the actors' geoms
            # outrank the ground and carry the average with it (``_contact_friction``).
            # contact_offset / rest_offset are not mapped to margin / gap: MuJoCo's contacts act
            # across the whole margin, so a margin would hold shapes contact_offset apart
            geom.priority = 1
        self.contacts = ContactSensor(ContactSensorCfg(prim_paths=tuple(
            f"{path}/{name}" for asset, path in zip(template, paths, strict=True) for name in asset.body_names),
            name="isaacgym_contacts"))
        self.contacts.build(spec)
        model = compile_scene(spec, self.physics)
        extra = {"num_threads": physx.num_threads} if self.device.type == "cpu" else {}
        self.engine = make_engine(model, num_worlds=len(self.envs), device=str(self.device), **extra)
        self.entities = [Entity(self.engine, path) for path in paths]
        self.contacts.initialize(self.engine)
        self._write_start_state()
        self.apply_dof_properties()
        self.apply_body_and_shape_properties()

    def _write_start_state(self) -> None:
        f = dict(dtype=self.engine.dtype, device=self.engine.device)
        for k, entity in enumerate(self.entities):
            poses = [env.actors[k].pose for env in self.envs]
            pos = torch.tensor(np.array([p.p.as_array() for p in poses]), **f)
            quat = torch.tensor(np.array([p.r.as_wxyz() for p in poses]), **f)
            if entity.is_floating or entity._root_static:
                entity.write_root_pose(pos_w=pos, quat_w=quat)
            elif poses[0].p.length() or poses[0].r != Transform().r:
                log.warning("isaacgym: actor %d's root is jointed; its start pose is ignored", k)
        self.engine.forward()
        self.engine.capture_initial_state()

    def apply_dof_properties(self, env_ids: list[int] | None = None) -> None:
        """Write the actors' DOF properties into the worlds: drive gains by drive mode, armature,
        friction and limits per world (each a per-world model field)."""
        envs = self.envs if env_ids is None else [self.envs[i] for i in env_ids]
        rows = torch.tensor([e.index for e in envs], device=self.engine.device)
        f = dict(dtype=self.engine.dtype, device=self.engine.device)
        for k, entity in enumerate(self.entities):
            if len(self.effort_mode) <= k:
                self.effort_mode.append(torch.zeros(len(self.envs), entity.num_joints, dtype=torch.bool,
                                                    device=self.engine.device))
            if not entity.num_joints:
                continue
            props = np.stack([e.actors[k].dof_props for e in envs])
            self.effort_mode[k][rows] = torch.as_tensor(props["driveMode"] == DOF_MODE_EFFORT, device=self.engine.device)
            gains = [drive_gains(p) for p in props]
            entity.write_gains(kp=torch.tensor(np.stack([g[0] for g in gains]), **f),
                               kd=torch.tensor(np.stack([g[1] for g in gains]), **f), env_ids=rows)
            self._write_model_rows("dof_armature", entity.dof_idx, props["armature"], rows)
            self._write_model_rows("dof_frictionloss", entity.dof_idx, props["friction"], rows)
            limited = props["hasLimits"]
            if limited.any():
                lim = np.stack([props["lower"], props["upper"]], -1)
                model_range = self.engine.model.jnt_range[entity._joint_ids]
                if not np.allclose(np.where(limited[..., None], lim, model_range), model_range, atol=1e-6):
                    self._write_model_rows("jnt_range", torch.as_tensor(entity._joint_ids),
                                           np.where(limited[..., None], lim, model_range), rows)

    def apply_body_and_shape_properties(self, env_ids: list[int] | None = None) -> None:
        """Write the actors' shape frictions and body masses into the worlds (per-world model fields;
        masses then recompute the model's derived constants)."""
        envs = self.envs if env_ids is None else [self.envs[i] for i in env_ids]
        rows = torch.tensor([e.index for e in envs], device=self.engine.device)
        masses_changed = False
        for k, entity in enumerate(self.entities):
            geoms = collision_geoms(self.engine.model, entity._body_ids_np)
            friction = np.array([[[self._contact_friction(p.friction), p.torsion_friction, p.rolling_friction]
                                  for p in e.actors[k].shape_props] for e in envs]).reshape(len(envs), len(geoms), 3)
            self._write_model_rows("geom_friction", geoms, friction, rows)
            masses = np.array([[p.mass for p in e.actors[k].body_props] for e in envs]).reshape(len(envs), -1)
            masses_changed |= self._write_model_rows("body_mass", entity._body_ids_np, masses, rows)
        if masses_changed:
            self.engine.set_const(rows)

    def _contact_friction(self, shape_friction: float) -> float:
        """The sliding friction MuJoCo should use for an actor shape: PhysX's average of the shape's
        and the ground's (the plane's or else the first terrain's dynamic friction); the shape's own
        without a ground."""
        surfaces = ([self.ground.dynamic_friction] if self.ground is not None else []) + \
            [t.dynamic_friction for t in self.terrains]
        return 0.5 * (shape_friction + surfaces[0]) if surfaces else shape_friction

    def _write_model_rows(self, name: str, cols, values: np.ndarray, rows: torch.Tensor) -> bool:
        """Write per-world ``values`` (R, C, ...) of model field ``name`` at columns ``cols`` of worlds
        ``rows``; a field every world leaves at the model's value is not expanded per world."""
        cols = torch.as_tensor(np.arange(cols.start, cols.stop) if isinstance(cols, slice) else cols,
                               device=self.engine.device)
        model_values = getattr(self.engine.model, name)[cols.cpu().numpy()]
        if name not in self._expanded and np.allclose(values, model_values, atol=1e-7):
            return False
        self._expanded.add(name)
        field_ = self.engine.model_field(name)
        # a field of a DOF-properties record is a strided view: copy it before torch wraps it
        values = np.ascontiguousarray(values)
        field_[rows[:, None], cols[None, :]] = torch.as_tensor(values, dtype=field_.dtype, device=field_.device)
        return True

    # -- stepping ----------------------------------------------------------------------------
    def step(self) -> None:
        """One ``simulate``: ``substeps`` MuJoCo steps; poses current afterwards."""
        self.engine.step(self.params.substeps, refresh=True)
        self.sim_time_s += self.params.dt
        self.frame_count += 1

    @property
    def origins(self) -> torch.Tensor:
        """(N, 3) env origins in the sim frame, engine dtype, m."""
        if not hasattr(self, "_origins"):
            self._origins = torch.tensor(np.array([e.origin for e in self.envs]), dtype=self.engine.dtype,
                                         device=self.engine.device)
        return self._origins


def _actor_geoms(spec):
    """The geoms of every actor attached to ``spec`` (bodies under ``/World/actor``)."""
    for body in spec.bodies:
        if (body.name or "").startswith("/World/actor"):
            yield from body.geoms


def ground_cfg(plane: PlaneParams) -> GroundCfg:
    n = plane.normal
    if abs(n.x) > 1e-6 or abs(n.y) > 1e-6 or n.z <= 0:
        raise ValueError(f"isaacgym: a ground plane with normal {n!r} is not supported; use the up axis "
                         "gymapi.Vec3(0, 0, 1) (tilted terrain: load it as an asset)")
    return GroundCfg(z_m=-plane.distance, static_friction=plane.static_friction,
                     dynamic_friction=plane.dynamic_friction, restitution=plane.restitution, sky=False, sun=True)


__all__ = ["Actor", "Env", "Sim", "ground_cfg", "physics_of"]
