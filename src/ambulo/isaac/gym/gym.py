"""``gymapi.acquire_gym()``: Isaac Gym's ``Gym`` interface on ambulo's engines.

Every method takes Isaac's handles (sim, env, actor index, asset) and delegates to ``Sim``
(building, stepping), ``SimTensors`` (the tensor API) and ``Asset``. Viewer calls run headless.
A method Isaac Gym has and ambulo does not fails with one line naming the alternative
(``ISAAC_UNSUPPORTED``); docs/isaac-gym-coverage.md lists which is which.
"""

from __future__ import annotations

import copy
import os
import time

import mujoco
import numpy as np
import torch

from . import session
from . import terrain as terrains
from .assets import Asset, load_asset
from .gym_notes import ISAAC_APPROXIMATED, ISAAC_UNSUPPORTED
from .sim import Actor, Env, Sim
from .tensors import GymTensor, SimTensors
from .types import (
    DOF_ROTATION,
    DOF_STATE_DTYPE,
    DOF_TRANSLATION,
    SIM_PHYSX,
    AssetOptions,
    HeightFieldParams,
    PlaneParams,
    SimParams,
    Transform,
    TriangleMeshParams,
    Vec3,
)
from .viewer import HeadlessViewer, Viewer

DOMAIN_ACTOR, DOMAIN_ENV, DOMAIN_SIM = 0, 1, 2
ENV_SPACE, LOCAL_SPACE, GLOBAL_SPACE = 0, 1, 2
STATE_NONE, STATE_POS, STATE_VEL, STATE_ALL = 0, 1, 2, 3


class GymNotSupported(AttributeError):
    """An Isaac Gym method ambulo does not provide; the message names the alternative."""


class Gym(HeadlessViewer):
    """Isaac Gym's interface object (``gymapi.acquire_gym()``)."""

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        hint = ISAAC_UNSUPPORTED.get(name, "see docs/isaac-gym-coverage.md for what ambulo provides")
        raise GymNotSupported(f"ambulo does not provide Gym.{name} of Isaac Gym; {hint}")

    # -- sim ---------------------------------------------------------------------------------------
    def create_sim(self, compute_device: int = 0, graphics_device: int = 0, type: int = SIM_PHYSX,
                   params: SimParams | None = None) -> Sim:
        if type != SIM_PHYSX:
            raise ValueError("isaacgym: only gymapi.SIM_PHYSX is provided (ambulo runs it on MuJoCo); Flex is not")
        params = params or SimParams()
        gpu = params.use_gpu_pipeline and torch.cuda.is_available()
        return Sim(params, f"cuda:{compute_device}" if gpu else "cpu")

    def destroy_sim(self, sim: Sim) -> None:
        sim.engine = None

    def add_ground(self, sim: Sim, params: PlaneParams) -> None:
        sim.ground = params

    def add_heightfield(self, sim: Sim, heightSamples: np.ndarray, params: HeightFieldParams) -> None:
        """Terrain from height samples (int16 units of ``params.vertical_scale``), as a MuJoCo hfield."""
        self._require_building(sim)
        sim.terrains.append(terrains.from_samples(heightSamples, params))

    def add_triangle_mesh(self, sim: Sim, vertices: np.ndarray, triangles: np.ndarray,
                          params: TriangleMeshParams) -> None:
        """Terrain from a triangle mesh, sampled into a MuJoCo hfield (``terrain``'s docstring)."""
        self._require_building(sim)
        sim.terrains.append(terrains.from_mesh(vertices, triangles, params))

    @staticmethod
    def _require_building(sim: Sim) -> None:
        if sim.engine is not None:
            raise RuntimeError("isaacgym: terrain added after prepare_sim; add ground and terrain before prepare_sim")

    def prepare_sim(self, sim: Sim) -> bool:
        sim.prepare()
        sim.tensors = SimTensors(sim)
        return True

    def simulate(self, sim: Sim) -> None:
        self._require_prepared(sim)
        session.charge(sim.params.dt)
        sim.tensors.apply_controls(sim.effort_mode)
        sim.step()
        sim.tensors.clear_body_forces()

    def fetch_results(self, sim: Sim, wait: bool = True) -> None:
        """Results are ready when ``simulate`` returns (the engines step synchronously)."""

    def get_sim_time(self, sim: Sim) -> float:
        return sim.sim_time_s

    def get_frame_count(self, sim: Sim) -> int:
        return sim.frame_count

    def get_elapsed_time(self, sim: Sim) -> float:
        return time.perf_counter()

    def get_sim_params(self, sim: Sim) -> SimParams:
        return sim.params

    # -- assets ------------------------------------------------------------------------------------
    def load_asset(self, sim: Sim, root: str, filename: str, options: AssetOptions | None = None) -> Asset:
        """The asset of ``root/filename``; a script that loads the same file with the same options
        in every env's loop gets the one asset (compiled once), as the batched model needs."""
        options = options or AssetOptions()
        key = (os.path.abspath(os.path.join(root, filename)), repr(options))
        if key not in sim.asset_cache:
            sim.asset_cache[key] = load_asset(root, filename, options)
        return sim.asset_cache[key]

    load_asset_urdf = load_asset
    load_asset_mjcf = load_asset

    def get_asset_dof_count(self, asset: Asset) -> int:
        return asset.num_dofs

    def get_asset_joint_count(self, asset: Asset) -> int:
        return asset.num_dofs

    def get_asset_rigid_body_count(self, asset: Asset) -> int:
        return asset.num_bodies

    def get_asset_rigid_shape_count(self, asset: Asset) -> int:
        return asset.num_shapes

    def get_asset_dof_names(self, asset: Asset) -> list[str]:
        return list(asset.dof_names)

    def get_asset_rigid_body_names(self, asset: Asset) -> list[str]:
        return list(asset.body_names)

    def get_asset_dof_dict(self, asset: Asset) -> dict[str, int]:
        return {n: i for i, n in enumerate(asset.dof_names)}

    def get_asset_rigid_body_dict(self, asset: Asset) -> dict[str, int]:
        return {n: i for i, n in enumerate(asset.body_names)}

    def find_asset_dof_index(self, asset: Asset, name: str) -> int:
        return _index_or_invalid(asset.dof_names, name)

    def find_asset_rigid_body_index(self, asset: Asset, name: str) -> int:
        return _index_or_invalid(asset.body_names, name)

    def get_asset_dof_properties(self, asset: Asset) -> np.ndarray:
        return asset.dof_props.copy()

    def get_asset_rigid_shape_properties(self, asset: Asset) -> list:
        return copy.deepcopy(asset.shape_props)

    def set_asset_rigid_shape_properties(self, asset: Asset, props: list) -> bool:
        """Actors created from now on take ``props`` (legged_gym randomizes friction this way, per env)."""
        if len(props) != asset.num_shapes:
            raise ValueError(f"isaacgym: {len(props)} shape properties for an asset with {asset.num_shapes} shapes")
        asset.shape_props = copy.deepcopy(list(props))
        return True

    def get_asset_dof_type(self, asset: Asset, index: int) -> int:
        joint = int(asset.names.joint_ids[index])
        return DOF_TRANSLATION if asset.model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_SLIDE else DOF_ROTATION

    def apply_rigid_body_force_tensors(self, sim: Sim, forceTensor: GymTensor | None = None,
                                       torqueTensor: GymTensor | None = None, space: int = ENV_SPACE) -> bool:
        """Forces and torques ``(num_bodies, 3)`` at the bodies' centres of mass for the next simulate."""
        self._tensors(sim).apply_body_forces(None if forceTensor is None else _torch(forceTensor),
                                             None if torqueTensor is None else _torch(torqueTensor),
                                             local=space == LOCAL_SPACE)
        return True

    # -- envs and actors ---------------------------------------------------------------------------
    def create_env(self, sim: Sim, lower: Vec3, upper: Vec3, num_per_row: int) -> Env:
        return sim.add_env(lower, upper, num_per_row)

    def get_env_count(self, sim: Sim) -> int:
        return len(sim.envs)

    def get_env(self, sim: Sim, index: int) -> Env:
        return sim.envs[index]

    def get_env_origin(self, env: Env) -> Vec3:
        return Vec3(*env.origin)

    def create_actor(self, env: Env, asset: Asset, pose: Transform, name: str | None = None, group: int = -1,
                     filter: int = -1, segmentation_id: int = 0) -> int:
        if env.sim.engine is not None:
            raise RuntimeError("isaacgym: create_actor after prepare_sim; create every actor before prepare_sim")
        pose = Transform(Vec3(pose.p.x, pose.p.y, pose.p.z), pose.r.normalize())
        env.actors.append(Actor(asset, pose, name or f"actor{len(env.actors)}", group, filter, asset.dof_props.copy(),
                                copy.deepcopy(asset.shape_props), asset.body_properties()))
        return len(env.actors) - 1

    def get_actor_count(self, env: Env) -> int:
        return len(env.actors)

    def get_sim_actor_count(self, sim: Sim) -> int:
        return sum(len(e.actors) for e in sim.envs)

    def get_sim_dof_count(self, sim: Sim) -> int:
        return sum(a.asset.num_dofs for e in sim.envs for a in e.actors)

    def get_sim_rigid_body_count(self, sim: Sim) -> int:
        return sum(a.asset.num_bodies for e in sim.envs for a in e.actors)

    def get_env_dof_count(self, env: Env) -> int:
        return sum(a.asset.num_dofs for a in env.actors)

    def get_env_rigid_body_count(self, env: Env) -> int:
        return sum(a.asset.num_bodies for a in env.actors)

    def get_actor_name(self, env: Env, actor: int) -> str:
        return env.actors[actor].name

    def get_actor_handle(self, env: Env, index: int) -> int:
        return index

    def find_actor_handle(self, env: Env, name: str) -> int:
        return _index_or_invalid([a.name for a in env.actors], name)

    def get_actor_index(self, env: Env, actor: int, domain: int = DOMAIN_SIM) -> int:
        return actor if domain != DOMAIN_SIM else env.index * len(env.actors) + actor

    def get_actor_dof_count(self, env: Env, actor: int) -> int:
        return env.actors[actor].asset.num_dofs

    def get_actor_rigid_body_count(self, env: Env, actor: int) -> int:
        return env.actors[actor].asset.num_bodies

    def get_actor_dof_names(self, env: Env, actor: int) -> list[str]:
        return list(env.actors[actor].asset.dof_names)

    def get_actor_rigid_body_names(self, env: Env, actor: int) -> list[str]:
        return list(env.actors[actor].asset.body_names)

    def get_actor_dof_dict(self, env: Env, actor: int) -> dict[str, int]:
        return self.get_asset_dof_dict(env.actors[actor].asset)

    def get_actor_rigid_body_dict(self, env: Env, actor: int) -> dict[str, int]:
        return self.get_asset_rigid_body_dict(env.actors[actor].asset)

    def find_actor_dof_handle(self, env: Env, actor: int, name: str) -> int:
        """The DOF's index in its env (Isaac's DOF handles are env-local)."""
        return self.find_actor_dof_index(env, actor, name, DOMAIN_ENV)

    def find_actor_rigid_body_handle(self, env: Env, actor: int, name: str) -> int:
        """The body's index in its env (Isaac's rigid body handles are env-local)."""
        return self.find_actor_rigid_body_index(env, actor, name, DOMAIN_ENV)

    def find_actor_dof_index(self, env: Env, actor: int, name: str, domain: int = DOMAIN_SIM) -> int:
        return self._domain_index(env, actor, _index_or_invalid(env.actors[actor].asset.dof_names, name),
                                  domain, lambda a: a.asset.num_dofs)

    def find_actor_rigid_body_index(self, env: Env, actor: int, name: str, domain: int = DOMAIN_SIM) -> int:
        return self._domain_index(env, actor, _index_or_invalid(env.actors[actor].asset.body_names, name),
                                  domain, lambda a: a.asset.num_bodies)

    def get_actor_dof_properties(self, env: Env, actor: int) -> np.ndarray:
        return env.actors[actor].dof_props.copy()

    def set_actor_dof_properties(self, env: Env, actor: int, props: np.ndarray) -> bool:
        target = env.actors[actor].dof_props
        if props.shape != target.shape:
            raise ValueError(f"isaacgym: {props.shape[0]} DOF properties for an actor with {target.shape[0]} DOFs")
        target[:] = props
        if env.sim.engine is not None:
            env.sim.apply_dof_properties([env.index])
        return True

    def get_actor_rigid_shape_properties(self, env: Env, actor: int) -> list:
        return copy.deepcopy(env.actors[actor].shape_props)

    def set_actor_rigid_shape_properties(self, env: Env, actor: int, props: list) -> bool:
        env.actors[actor].shape_props = copy.deepcopy(list(props))
        if env.sim.engine is not None:
            env.sim.apply_body_and_shape_properties([env.index])
        return True

    def get_actor_rigid_body_properties(self, env: Env, actor: int) -> list:
        return copy.deepcopy(env.actors[actor].body_props)

    def set_actor_rigid_body_properties(self, env: Env, actor: int, props: list, recomputeInertia: bool = False) -> bool:
        env.actors[actor].body_props = copy.deepcopy(list(props))
        if env.sim.engine is not None:
            env.sim.apply_body_and_shape_properties([env.index])
        return True

    def get_actor_dof_states(self, env: Env, actor: int, flags: int = STATE_ALL) -> np.ndarray:
        entity = self._entity(env, actor)
        out = np.zeros(entity.num_joints, DOF_STATE_DTYPE)
        out["pos"] = entity.data.joint_pos[env.index].cpu().numpy()
        out["vel"] = entity.data.joint_vel[env.index].cpu().numpy()
        return out

    def set_actor_dof_states(self, env: Env, actor: int, states: np.ndarray, flags: int = STATE_ALL) -> bool:
        entity = self._entity(env, actor)
        f = dict(dtype=entity.engine.dtype, device=entity.device)
        rows = torch.tensor([env.index], device=entity.device)
        pos = torch.as_tensor(np.asarray(states["pos"], np.float64), **f)[None] if flags & STATE_POS else None
        vel = torch.as_tensor(np.asarray(states["vel"], np.float64), **f)[None] if flags & STATE_VEL else None
        entity.write_joint_state(pos=pos, vel=vel, env_ids=rows)
        entity.engine.forward()
        return True

    def set_actor_dof_position_targets(self, env: Env, actor: int, targets: np.ndarray) -> bool:
        return self._set_actor_dof_row(env, actor, "pos_target", targets)

    def _set_actor_dof_row(self, env: Env, actor: int, buffer: str, values: np.ndarray) -> bool:
        tensors = self._tensors(env.sim)
        target = getattr(tensors, buffer)
        target[env.index, tensors._dof_cols[actor]] = torch.as_tensor(np.asarray(values, np.float64)).to(target)
        return True

    def set_actor_dof_velocity_targets(self, env: Env, actor: int, targets: np.ndarray) -> bool:
        return self._set_actor_dof_row(env, actor, "vel_target", targets)

    def apply_actor_dof_efforts(self, env: Env, actor: int, efforts: np.ndarray) -> bool:
        return self._set_actor_dof_row(env, actor, "effort", efforts)

    def begin_aggregate(self, env: Env, max_bodies: int, max_shapes: int, self_collisions: bool) -> bool:
        """A PhysX broad-phase hint; nothing to do on MuJoCo."""
        return True

    def end_aggregate(self, env: Env) -> bool:
        return True

    def set_rigid_body_color(self, env: Env, actor: int, body: int, mesh_type: int, color: Vec3) -> None:
        """Headless: colors are not drawn."""

    # -- the tensor API ----------------------------------------------------------------------------
    def acquire_actor_root_state_tensor(self, sim: Sim) -> GymTensor:
        return GymTensor(self._tensors(sim).root)

    def acquire_dof_state_tensor(self, sim: Sim) -> GymTensor:
        return GymTensor(self._tensors(sim).dof_state)

    def acquire_rigid_body_state_tensor(self, sim: Sim) -> GymTensor:
        return GymTensor(self._tensors(sim).body_state)

    def acquire_net_contact_force_tensor(self, sim: Sim) -> GymTensor:
        return GymTensor(self._tensors(sim).contact)

    def acquire_dof_force_tensor(self, sim: Sim) -> GymTensor:
        return GymTensor(self._tensors(sim).dof_force)

    def refresh_actor_root_state_tensor(self, sim: Sim) -> None:
        self._tensors(sim).refresh_root()

    def refresh_dof_state_tensor(self, sim: Sim) -> None:
        self._tensors(sim).refresh_dof_state()

    def refresh_rigid_body_state_tensor(self, sim: Sim) -> None:
        self._tensors(sim).refresh_body_state()

    def refresh_net_contact_force_tensor(self, sim: Sim) -> None:
        self._tensors(sim).refresh_contact()

    def refresh_dof_force_tensor(self, sim: Sim) -> None:
        self._tensors(sim).refresh_dof_force()

    def set_actor_root_state_tensor(self, sim: Sim, states: GymTensor) -> bool:
        self._tensors(sim).set_root(_torch(states))
        return True

    def set_actor_root_state_tensor_indexed(self, sim: Sim, states: GymTensor, indices: GymTensor, count: int) -> bool:
        self._tensors(sim).set_root(_torch(states), _torch(indices)[:count])
        return True

    def set_dof_state_tensor(self, sim: Sim, states: GymTensor) -> bool:
        self._tensors(sim).set_dof_state(_torch(states))
        return True

    def set_dof_state_tensor_indexed(self, sim: Sim, states: GymTensor, indices: GymTensor, count: int) -> bool:
        self._tensors(sim).set_dof_state(_torch(states), _torch(indices)[:count])
        return True

    def set_dof_position_target_tensor(self, sim: Sim, targets: GymTensor) -> bool:
        t = self._tensors(sim)
        t.set_dof_buffer(t.pos_target, _torch(targets))
        return True

    def set_dof_position_target_tensor_indexed(self, sim: Sim, targets: GymTensor, indices: GymTensor,
                                               count: int) -> bool:
        t = self._tensors(sim)
        t.set_dof_buffer(t.pos_target, _torch(targets), _torch(indices)[:count])
        return True

    def set_dof_velocity_target_tensor(self, sim: Sim, targets: GymTensor) -> bool:
        t = self._tensors(sim)
        t.set_dof_buffer(t.vel_target, _torch(targets))
        return True

    def set_dof_velocity_target_tensor_indexed(self, sim: Sim, targets: GymTensor, indices: GymTensor,
                                               count: int) -> bool:
        t = self._tensors(sim)
        t.set_dof_buffer(t.vel_target, _torch(targets), _torch(indices)[:count])
        return True

    def set_dof_actuation_force_tensor(self, sim: Sim, forces: GymTensor) -> bool:
        t = self._tensors(sim)
        t.set_dof_buffer(t.effort, _torch(forces))
        return True

    def set_dof_actuation_force_tensor_indexed(self, sim: Sim, forces: GymTensor, indices: GymTensor,
                                               count: int) -> bool:
        t = self._tensors(sim)
        t.set_dof_buffer(t.effort, _torch(forces), _torch(indices)[:count])
        return True

    # -- helpers -----------------------------------------------------------------------------------
    @staticmethod
    def _require_prepared(sim: Sim) -> None:
        if sim.engine is None:
            raise RuntimeError("isaacgym: call gym.prepare_sim(sim) after creating the envs and before "
                               "simulate or the tensor API")

    def _tensors(self, sim: Sim) -> SimTensors:
        self._require_prepared(sim)
        return sim.tensors

    def _entity(self, env: Env, actor: int):
        self._require_prepared(env.sim)
        return env.sim.entities[actor]

    @staticmethod
    def _domain_index(env: Env, actor: int, local: int, domain: int, count) -> int:
        if local < 0 or domain == DOMAIN_ACTOR:
            return local
        in_env = sum(count(a) for a in env.actors[:actor]) + local
        return in_env if domain == DOMAIN_ENV else env.index * sum(count(a) for a in env.actors) + in_env


def _index_or_invalid(names: list[str], name: str) -> int:
    """Isaac returns -1 for a name it does not know."""
    return names.index(name) if name in names else -1


def _torch(t: GymTensor | torch.Tensor) -> torch.Tensor:
    return t.tensor if isinstance(t, GymTensor) else torch.as_tensor(t)


def acquire_gym() -> Gym:
    """Isaac Gym's entry point: the ``Gym`` interface."""
    return Gym()


__all__ = ["DOMAIN_ACTOR", "DOMAIN_ENV", "DOMAIN_SIM", "Gym", "GymNotSupported", "ISAAC_APPROXIMATED", "ISAAC_UNSUPPORTED",
           "STATE_ALL", "STATE_NONE", "STATE_POS", "STATE_VEL", "Viewer", "acquire_gym"]
