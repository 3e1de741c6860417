"""humanoid-walk: the 21-DoF humanoid tracks a commanded planar velocity and yaw rate.

Observations (72, in order): projected gravity in the base frame (3), command (vx, vy, yaw
rate) scaled (3), joint positions relative to the default pose (21), scaled joint velocities
(21), scaled base angular velocity in the base frame (3), last action (21); the actor's copy
carries uniform noise, the critic's is clean and adds base linear velocity, base height and
foot contacts. Actions (21): joint position targets ``default + action_scale * a`` tracked by
each joint's implicit PD drive. Commands are resampled within episodes (heading control,
standing envs). Falls (base below ``min_base_height_m`` or tilted past ``max_tilt_rad``) end
the episode. Friction and base mass are randomized per env at start; each env is pushed at
its own random interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import torch

from ambulo.core import GroundCfg, PhysicsCfg, RobotCfg, randomize
from ambulo.core.rows import put_rows, select_rows, take_rows
from ambulo.policies.velocity_obs import velocity_policy_terms
from ambulo.robots import humanoid
from ambulo.sensors import ContactSensor, ContactSensorCfg
from ambulo.utils.validate import rule

from ..utils.math import quat_from_yaw
from . import observations as obs_terms
from . import rewards
from .base import EnvCfg, RLEnv
from .commands import VelocityCommand, VelocityCommandCfg
from .ppo import PpoCfg
from .registry import Criterion, TaskSpec, register
from .transfer import PLAY_KEEPS, TransferCfg, TransferRandomization


@dataclass(kw_only=True)
class HumanoidWalkCfg(EnvCfg):
    """humanoid-walk settings."""

    base_body: str = humanoid.BASE_BODY
    feet_bodies: tuple[str, ...] = humanoid.FOOT_BODIES
    action_scale: float = 0.25
    """Joint target offset for an action of 1, rad. legged_gym's 0.25: with 0.5, PPO's initial
    exploration noise toppled the stiff-jointed humanoid within 0.8 s and a 300-iteration CPU
    run reached 2.9 s episodes; with 0.25 the same run reached 17.5 s (docs/images)."""
    commands: VelocityCommandCfg = field(default_factory=VelocityCommandCfg)
    min_base_height_m: float = 0.5
    max_tilt_rad: float = math.radians(60.0)
    tracking_std: float = field(default=0.5, metadata=rule(minimum=0.0, strict=True))
    """Width of the velocity tracking kernels, m/s and rad/s."""
    air_time_threshold_s: float = field(default=0.4, metadata=rule(minimum=0.0))
    air_time_reward: Literal["touchdown", "single_stance"] = "touchdown"
    """The ``feet_air_time`` term: "touchdown" (legged_gym's, ``rewards.feet_air_time``: each touchdown
    adds its flight time minus ``air_time_threshold_s``, negative for quick steps) or "single_stance"
    (Isaac Lab's biped term, ``rewards.feet_air_time_single_stance``: time on one foot, capped at the
    threshold, never negative). The shipped walkers stand still under 0.25 m/s commands; the touchdown
    term's penalty on a slow walk's short steps is the suspect this option tests."""
    friction_range: tuple[float, float] | None = (0.4, 1.2)
    """Per-env friction of every geom, drawn at start; None keeps the model's."""
    added_base_mass_kg: tuple[float, float] | None = field(default=(-2.0, 3.0), metadata=rule(pair=True))
    """Per-env mass added to the base at start; None adds none."""
    push_interval_s: tuple[float, float] | None = field(default=(5.0, 10.0), metadata=rule(pair=True))
    """Each env is pushed after a time uniform in this range, then again; None: no pushes."""
    push_velocity_m_s: float = 0.5
    """Pushes add a planar base velocity uniform in +-this, m/s."""
    diverged_speed_bound: float | None = 100.0
    """``EnvCfg.diverged_speed_bound`` for a humanoid, rad/s or m/s: twice the fastest joint
    (a light foot or hand, ~45 rad/s) under PPO's noisiest exploration on the CPU engine, while
    worlds running away on MuJoCo Warp reach 280 rad/s base spins in one step (humanoid-rough)."""
    initial_joint_noise_rad: float = 0.05
    obs_scale_joint_vel: float = 0.05
    obs_scale_ang_vel: float = 0.25
    obs_scale_command: tuple[float, float, float] = (2.0, 2.0, 0.25)
    deviation_joints: tuple[str, ...] = (".*_hip_yaw", ".*_hip_roll", "torso_.*", ".*_shoulder_.*",
                                          ".*_elbow")
    """Joints whose distance from the default pose ``joint_deviation`` penalizes (name patterns):
    the ones walking does not need to move far, so the gait stays human-like."""
    curriculum_start_scale: float | None = None
    """Command curriculum: training starts drawing commands from this share of every range and
    widens it while the policy tracks well (None: full ranges from the start). Evaluation
    always uses the full ranges."""
    curriculum_threshold: float = 0.7
    """The range widens while the running mean of the linear tracking kernel is above this."""
    curriculum_rate_per_s: float = 0.02
    """How fast the range share grows while tracking is good, per second of simulated time."""
    transfer: TransferCfg = field(default_factory=TransferCfg, metadata={PLAY_KEEPS: True})
    """Transfer randomization (gains, strength, joint friction, armature, CoM, action latency,
    observation delay; ``envs.transfer``); off by default, ``transfer_cfg_wide()`` for the
    issue's robustness ranges (the humanoid-walk-robust task, ``envs.humanoid_walk_robust``).
    Training-only: a run's ``--env-cfg transfer.*`` does not reach its play/eval env (``rl.runs.play_overrides``)."""
    transfer_blocks: tuple[TransferCfg, ...] = field(default=(), metadata={PLAY_KEEPS: True})
    """Evaluation layouts: the worlds split into this many contiguous equal blocks, block b under
    ``transfer_blocks[b]`` in place of ``transfer`` (the robustness table's rows in one env,
    ``benchmarks/robustness.py``; humanoid-walk-robust's evaluation blocks); empty: every world under ``transfer``."""


def humanoid_walk_cfg() -> HumanoidWalkCfg:
    """Default humanoid-walk: 200 Hz physics, decimation 4 (50 Hz policy), 20 s episodes.

    Weights follow Isaac Lab's humanoid velocity tasks (tracking 1.0 / 0.5, termination
    -200, action rate -0.01, joint limits -1), per second of simulated time. Observation
    noise follows mjlab's velocity task (angular velocity 0.2 rad/s, gravity 0.05, joint
    position 0.01 rad, joint velocity 1.5 rad/s), in scaled units.
    """
    return HumanoidWalkCfg(
        robot=RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH),
        robot_keyframe="home",
        ground=GroundCfg(static_friction=1.0, dynamic_friction=1.0, restitution=0.0),
        physics=PhysicsCfg(timestep_s=0.005, integrator="implicitfast", solver_iterations=50,
                           ls_iterations=50),
        decimation=4,
        episode_length_s=20.0,
        reward_weights=dict(
            track_lin_vel_xy_exp=1.0,
            track_ang_vel_z_exp=1.0,
            upright=0.5,
            flat_orientation_l2=-1.0,
            terminated=-200.0,
            ang_vel_xy_l2=-0.05,
            torques_l2=-1.0e-5,
            action_rate_l2=-0.01,
            joint_pos_limits=-1.0,
            feet_air_time=1.0,
            feet_slide=-0.25,
            joint_deviation=-0.1,
        ),
        curriculum_start_scale=0.4,
        observation_noise=dict(projected_gravity=0.05, joint_pos_rel=0.01, joint_vel=1.5 * 0.05,
                               base_ang_vel=0.2 * 0.25),
        # the policy's observations, rewards and dones equal "full"'s (tests/envs/test_reset_forward.py:
        # humanoid-walk, -footsteps, -rough and g1-walk); only the critic's feet_contact reads 0 on a
        # reset row. H200, 4096 worlds (session 12): env/raw 0.682 -> 0.807 eager, 0.708 -> 0.839 graph;
        # time to walk (1 GPU, seeds 0/1/2) 2.51/2.39/2.78 min against 2.77/2.81/2.43 with "full"
        reset_forward="kinematics",
    )


def as_play(cfg: HumanoidWalkCfg) -> HumanoidWalkCfg:
    """``cfg`` for play and evaluation (every walking task's play variant): no pushes, no
    observation noise, nominal friction and mass, the full command ranges, no time-out (falls
    still end an episode)."""
    cfg.push_interval_s = None
    cfg.observation_noise = {}
    cfg.friction_range = None
    cfg.added_base_mass_kg = None
    cfg.episode_length_s = 1.0e9
    cfg.curriculum_start_scale = None
    cfg.transfer = TransferCfg()
    return cfg


def humanoid_walk_play_cfg() -> HumanoidWalkCfg:
    return as_play(humanoid_walk_cfg())


def humanoid_walk_ppo() -> PpoCfg:
    """legged_gym / Isaac Lab humanoid settings: 24-step rollouts, entropy 0.008."""
    return PpoCfg(num_envs=4096, max_iterations=3000, num_steps_per_env=24, save_interval=50,
                  actor_hidden_dims=(256, 128, 128), critic_hidden_dims=(256, 128, 128),
                  entropy_coef=0.008)


class HumanoidWalkEnv(RLEnv):
    """Velocity-tracking locomotion; see the module docstring."""

    cfg: HumanoidWalkCfg

    def _design_scene(self, spec) -> None:
        cfg = self.cfg
        ground = None if cfg.ground is None else cfg.ground.prim_path + "/geom"
        feet = tuple(f"{cfg.robot.prim_path}/{foot}" for foot in cfg.feet_bodies)
        self.feet = self.sim.add(ContactSensor(ContactSensorCfg(
            name="feet_contact", prim_paths=feet, include_subtree=True, against=ground)))

    def _make_robot(self):
        robot = super()._make_robot()
        if robot.num_joints == 0 or not robot.is_floating:
            raise ValueError(f"humanoid-walk needs a floating-base robot with joints; "
                             f"{self.cfg.robot.file} has {robot.num_joints} joints")
        return robot

    def _setup(self) -> None:
        n, dev, cfg = self.num_envs, self.device, self.cfg
        self.commands = VelocityCommand(cfg.commands, n, self.generator, dev)
        self.command_scale = torch.tensor(cfg.obs_scale_command, dtype=torch.float32, device=dev)
        self._push_time_left_s = torch.zeros(n, dtype=torch.float32, device=dev)
        if cfg.push_interval_s is not None:
            self._push_time_left_s = self._uniform((n,), *cfg.push_interval_s)
        # set by _get_terminations each step and reused by the rewards
        self._gravity_b = torch.zeros(n, 3, dtype=self.engine.dtype, device=dev)
        self._fell = torch.zeros(n, dtype=torch.bool, device=dev)
        self.feet_body_ids = torch.tensor(self.robot.find_bodies(list(cfg.feet_bodies)), device=dev)
        self.deviation_joint_ids = torch.tensor(self.robot.find_joints(list(cfg.deviation_joints)), device=dev)
        # running mean of the linear tracking kernel over all envs: a device scalar, no sync
        self._tracking_mean = torch.zeros((), dtype=torch.float32, device=dev)
        if cfg.curriculum_start_scale is not None:
            self.commands.range_scale.fill_(cfg.curriculum_start_scale)
        self._randomize_physics()
        self._targets = self.robot.default_joint_pos.expand(n, -1).clone()
        """(N, J) joint targets of the last action, rad (the drives get them in ``_simulate``)."""
        self.transfer = TransferRandomization(cfg.transfer, self, blocks=cfg.transfer_blocks)

    def _randomize_physics(self) -> None:
        """Per-env friction and base mass, drawn once at start (Isaac Lab's "startup" events)
        through ``core.randomize``, the layer the replicator's randomizers use too. Drawn in
        float32 from the env's generator, friction first, so a seed gives the worlds it gave."""
        cfg = self.cfg
        if cfg.friction_range is not None:
            # MuJoCo takes the larger friction of two touching geoms, so every geom gets the
            # env's sample (else the feet's own value would mask a slippery floor).
            randomize.geom_friction(self.engine, randomize.uniform(*cfg.friction_range), self.generator,
                                    shared=True, dtype=torch.float32)
        if cfg.added_base_mass_kg is not None:
            randomize.body_mass(self.robot, randomize.uniform(*cfg.added_base_mass_kg), self.generator,
                                bodies=[cfg.base_body], operation="add", dtype=torch.float32)
            self.engine.set_const()

    graph_audited = True  # tests/envs/test_graph_step.py

    def _graph_unsafe_reason(self) -> str | None:
        if self.transfer.action_delay is not None or self.transfer.obs_delay_steps[1] > 0:
            return "an action latency or observation delay advances DelayBuffer's Python cursor every step"
        return super()._graph_unsafe_reason()

    # -- metrics -----------------------------------------------------------------------
    def velocity_tracking_error(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(N,) |v_cmd - v| of the planar base velocity, m/s, and (N,) |yaw rate error|, rad/s."""
        vel_yaw, yaw_rate_w = self._planar_velocity(self.robot.data.projected_gravity_b)
        cmd = self.commands.command
        lin_err = torch.linalg.vector_norm(cmd[:, :2] - vel_yaw, dim=-1)
        return lin_err, (cmd[:, 2] - yaw_rate_w).abs()

    def _planar_velocity(self, gravity_b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """What the commands are tracked against: the base velocity in its heading frame (N, 2)
        m/s and the yaw rate about world z (N,) rad/s, given the projected gravity (N, 3)."""
        data = self.robot.data
        vel_yaw = obs_terms.base_lin_vel_yaw(data.root_quat_w, data.root_lin_vel_w)
        # e_z . (R w_b) = (R^T e_z) . w_b = -(projected gravity) . w_b: no rotation needed
        return vel_yaw, -(gravity_b * data.root_ang_vel_b).sum(dim=-1)

    # -- RLEnv hooks ---------------------------------------------------------------------
    def action_bounds(self) -> torch.Tensor:
        """(A,) float32: each joint's farther limit from its default position over ``action_scale``
        (an action past it only presses the target into the limit). humanoid: hip pitch 7.6, knee
        8.0, ankle roll 1.6; a PPO walker on humanoid-rough's hardest stairs reaches 3.6 at the knee
        (99th percentile) where FastSAC's one bound of 2.0 stops at 0.5 rad."""
        limits, default = self.robot.joint_pos_limits, self.robot.default_joint_pos
        reach = torch.maximum(limits[:, 1] - default, default - limits[:, 0]) / self.cfg.action_scale
        unlimited = [self.robot.joint_names[j] for j in torch.nonzero(~torch.isfinite(reach)).flatten().tolist()]
        if unlimited:
            raise ValueError(f"{self.cfg.robot.file}: joints {unlimited} have no limits, so they bound no action; "
                             "give them limits or train with one action_bound for all")
        return reach.float()

    def _apply_action(self, actions: torch.Tensor) -> None:
        self._targets = self.robot.default_joint_pos + actions * self.cfg.action_scale

    def _simulate(self) -> torch.Tensor:
        # the drives get the targets here: delayed per world when an action latency is on
        return self.transfer.simulate(self._targets, self.cfg.decimation)

    def _compute_observations(self) -> torch.Tensor:
        obs = super()._compute_observations()
        return self.transfer.observe(obs, self.episode_length_buf == 0)  # the actor's, delayed if on

    def _pre_physics(self) -> None:
        self.commands.update(self.step_dt_s, self.robot.data.heading_w)
        if self.cfg.push_interval_s is None:
            return
        self._push_time_left_s -= self.step_dt_s
        rows = select_rows(self._push_time_left_s <= 0.0)
        if rows is None:
            return
        n, v = self._num_rows(rows), self.cfg.push_velocity_m_s
        kick = torch.zeros(n, 3, dtype=self.engine.dtype, device=self.device)
        kick[:, :2] = self._uniform((n, 2), -v, v, dtype=self.engine.dtype)
        velocity = take_rows(self.robot.data.root_lin_vel_w, rows) + kick
        self.robot.write_root_velocity(lin_vel_w=velocity, env_ids=rows)
        put_rows(self._push_time_left_s[:, None], slice(None), self._uniform((n, 1), *self.cfg.push_interval_s),
                 rows)

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        # shared with the shipped-policy runner (sim.HumanoidWalkingPolicy): one definition
        return velocity_policy_terms(self.robot.data, self.commands.command, self.actions,
                                     command_scale=self.command_scale, joint_vel_scale=self.cfg.obs_scale_joint_vel,
                                     ang_vel_scale=self.cfg.obs_scale_ang_vel)

    def _privileged_terms(self) -> dict[str, torch.Tensor]:
        data = self.robot.data
        return {
            "base_lin_vel": data.root_lin_vel_b,
            "base_height": data.root_pos_w[:, 2:3],
            "feet_contact": self.feet.get_current_frame().in_contact.float(),  # after resets too
        }

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        data = self.robot.data
        self._gravity_b = data.projected_gravity_b
        fell_height = data.root_pos_w[:, 2] < self.cfg.min_base_height_m
        fell_tilt = rewards.upright(self._gravity_b) < math.cos(self.cfg.max_tilt_rad)
        self._fell = fell_height | fell_tilt
        return {"base_height": fell_height, "tilt": fell_tilt}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        cfg, data, robot = self.cfg, self.robot.data, self.robot
        cmd = self.commands.command
        vel_yaw, yaw_rate_w = self._planar_velocity(self._gravity_b)
        ang_vel_b = data.root_ang_vel_b
        feet = self.feet.data  # read once per step by the sensor's update
        track_lin = rewards.track_lin_vel_xy_exp(cmd[:, :2], vel_yaw, cfg.tracking_std)
        if cfg.curriculum_start_scale is not None:
            self._advance_curriculum(track_lin)
        return {
            "track_lin_vel_xy_exp": track_lin,
            "track_ang_vel_z_exp": rewards.track_ang_vel_z_exp(cmd[:, 2], yaw_rate_w, cfg.tracking_std),
            "upright": rewards.upright(self._gravity_b),
            "terminated": self._fell.float(),
            "ang_vel_xy_l2": rewards.l2(ang_vel_b[:, :2]),
            "torques_l2": rewards.torques_l2(data.joint_effort),
            "action_rate_l2": rewards.action_rate_l2(self.actions, self.prev_actions),
            "joint_pos_limits": rewards.joint_pos_limits(
                data.joint_pos, robot.soft_joint_pos_limits[:, 0], robot.soft_joint_pos_limits[:, 1]),
            "feet_air_time": self._feet_air_time(feet, cmd[:, :2]),
            "feet_slide": rewards.feet_slide(data.body_lin_vel_w[:, self.feet_body_ids], feet.in_contact),
            "joint_deviation": rewards.joint_deviation_l1(data.joint_pos_rel[:, self.deviation_joint_ids]),
            "flat_orientation_l2": rewards.flat_orientation_l2(self._gravity_b),
        }

    def _feet_air_time(self, feet, command_xy: torch.Tensor) -> torch.Tensor:
        """(N,) the ``feet_air_time`` term the cfg's ``air_time_reward`` names."""
        cfg = self.cfg
        if cfg.air_time_reward == "single_stance":
            return rewards.feet_air_time_single_stance(feet.current_air_time_s, feet.current_contact_time_s,
                                                       feet.in_contact, cfg.air_time_threshold_s, command_xy)
        return rewards.feet_air_time(feet.last_air_time_s, feet.first_contact, cfg.air_time_threshold_s, command_xy)

    def _advance_curriculum(self, track_lin: torch.Tensor) -> None:
        """Widen the command ranges while the envs track well (a mean over all envs, kept on
        the device: the curriculum never reads a value back to the host)."""
        cfg = self.cfg
        alpha = min(1.0, self.step_dt_s / 2.0)  # a 2 s running mean
        self._tracking_mean.lerp_(track_lin.float().mean(), alpha)
        grow = (self._tracking_mean > cfg.curriculum_threshold).float() * cfg.curriculum_rate_per_s * self.step_dt_s
        self.commands.range_scale.add_(grow).clamp_(max=1.0)

    def _reset_idx(self, rows: torch.Tensor) -> None:
        cfg, n, robot = self.cfg, self._num_rows(rows), self.robot
        yaw = self._uniform((n,), -math.pi, math.pi, dtype=self.engine.dtype)
        robot.write_root_pose(quat_w=quat_from_yaw(yaw), env_ids=rows)
        noise = self._uniform((n, robot.num_joints), -1.0, 1.0, dtype=self.engine.dtype) * cfg.initial_joint_noise_rad
        pos = (robot.default_joint_pos + noise).clamp(robot.joint_pos_limits[:, 0], robot.joint_pos_limits[:, 1])
        robot.write_joint_state(pos=pos, env_ids=rows)
        self.commands.resample(rows)
        # at the first reset, after every setup (a subclass's gains included); draws nothing
        # unless a term is on, so the walk's seeds give what they gave
        self.transfer.startup()
        self.transfer.reset(rows)
        self.transfer.start_episode_targets(rows, robot.default_joint_pos.expand(self.num_envs, -1))


WALKS = Criterion("walks", max_values={"fall_rate": 0.05, "mean_abs_vel_error_m_s": 0.2})
"""What walking means for every velocity-tracking humanoid task (``ambulo eval``)."""


def humanoid_walk_metrics(env: HumanoidWalkEnv) -> dict[str, torch.Tensor]:
    lin_err, yaw_err = env.velocity_tracking_error()
    return {"abs_vel_error_m_s": lin_err, "abs_yaw_rate_error_rad_s": yaw_err}


register(TaskSpec(
    name="humanoid-walk",
    env_cls=HumanoidWalkEnv,
    cfg_fn=humanoid_walk_cfg,
    play_cfg_fn=humanoid_walk_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="21-DoF humanoid tracks commanded (vx, vy, yaw rate) through joint PD targets",
    step_metrics=humanoid_walk_metrics,
    criteria=(WALKS,),
))
