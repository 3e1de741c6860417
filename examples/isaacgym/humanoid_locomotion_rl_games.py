# Listing of the tutorial module "The AI-Robot Brain" (Isaac Gym humanoid locomotion + rl_games),
# /work/shared/research/isaac-gym-listings/humanoid_locomotion_rl_games.txt, indentation restored.
# Lines marked "ambulo fix" also fail in real Isaac Gym (or real rl_games) and are fixed; the asset
# assets/humanoid.urdf (the tutorial's 21-DoF humanoid) is ambulo's bundled 21-DoF humanoid.
# Run: ambulo run --seconds 0.1 examples/isaacgym/humanoid_locomotion_rl_games.py
from isaacgym import gymapi, gymtorch, gymutil
import torch
import numpy as np
class HumanoidLocomotionEnv:
    """
    Massively parallel humanoid walking environment.
    Trains 4096 humanoids simultaneously.
    """
    def __init__(self, num_envs: int = 4096, device: str = "cuda:0"):
        self.num_envs = num_envs
        self.device = device
        # Acquire gym interface
        self.gym = gymapi.acquire_gym()
        # Simulation parameters
        sim_params = gymapi.SimParams()
        sim_params.dt = 1.0 / 500.0 # 500 Hz physics
        sim_params.substeps = 2
        sim_params.up_axis = gymapi.UP_AXIS_Z
        sim_params.gravity = gymapi.Vec3(0.0, 0.0, -9.81)
        # PhysX parameters for stable humanoid sim
        sim_params.physx.solver_type = 1 # TGS (recommended for articulations)
        sim_params.physx.num_position_iterations = 4
        sim_params.physx.num_velocity_iterations = 1
        sim_params.physx.contact_offset = 0.02
        sim_params.physx.rest_offset = 0.0
        sim_params.physx.use_gpu = True
        sim_params.physx.num_threads = 4
        sim_params.use_gpu_pipeline = True  # ambulo fix: Isaac Gym's default CPU pipeline hands out CPU tensors, and the listing's cuda:0 tensors then fail to mix with them
        # Create simulation
        self.sim = self.gym.create_sim(0, 0, gymapi.SIM_PHYSX, sim_params)
        # Environment dimensions
        self.state_dim = 60 # Joint pos (21) + vel (21) + base ori (4) + base vel (6) + ...
        self.action_dim = 21 # Joint position targets
        self._create_ground()
        self._create_envs()
        self._init_tensors()
    def _create_ground(self):
        """Create ground plane with friction."""
        plane_params = gymapi.PlaneParams()
        plane_params.normal = gymapi.Vec3(0, 0, 1)
        plane_params.static_friction = 0.8
        plane_params.dynamic_friction = 0.6
        plane_params.restitution = 0.0
        self.gym.add_ground(self.sim, plane_params)
    def _create_envs(self):
        """Create parallel environments with humanoid robots."""
        # Load humanoid asset
        asset_options = gymapi.AssetOptions()
        asset_options.fix_base_link = False
        asset_options.angular_damping = 0.01
        asset_options.max_angular_velocity = 100.0
        asset_options.default_dof_drive_mode = gymapi.DOF_MODE_POS
        humanoid_asset = self.gym.load_asset(
            self.sim, "assets", "humanoid.urdf", asset_options
        )
        self.num_dof = self.gym.get_asset_dof_count(humanoid_asset)
        self.num_bodies = self.gym.get_asset_rigid_body_count(humanoid_asset)
        # Environment spacing
        spacing = 2.0
        envs_per_row = int(np.sqrt(self.num_envs))
        lower = gymapi.Vec3(-spacing, -spacing, 0.0)
        upper = gymapi.Vec3(spacing, spacing, spacing)
        self.envs = []
        self.actors = []
        for i in range(self.num_envs):
            env = self.gym.create_env(self.sim, lower, upper, envs_per_row)
            # Initial pose: standing
            start_pose = gymapi.Transform()
            start_pose.p = gymapi.Vec3(0.0, 0.0, 0.95) # Standing height
            start_pose.r = gymapi.Quat(0, 0, 0, 1)
            actor = self.gym.create_actor(
                env, humanoid_asset, start_pose, "humanoid", i, 1
            )
            # Configure joint properties
            dof_props = self.gym.get_actor_dof_properties(env, actor)
            dof_props['driveMode'].fill(gymapi.DOF_MODE_POS)
            dof_props['stiffness'].fill(100.0) # Position gain
            dof_props['damping'].fill(10.0) # Velocity gain
            self.gym.set_actor_dof_properties(env, actor, dof_props)
            self.envs.append(env)
            self.actors.append(actor)
    def _init_tensors(self):
        """Initialize GPU tensors for fast access."""
        self.gym.prepare_sim(self.sim)
        # Get GPU tensor handles
        actor_root_state = self.gym.acquire_actor_root_state_tensor(self.sim)
        dof_state = self.gym.acquire_dof_state_tensor(self.sim)
        rigid_body_state = self.gym.acquire_rigid_body_state_tensor(self.sim)
        contact_force = self.gym.acquire_net_contact_force_tensor(self.sim)
        # Wrap as PyTorch tensors (zero-copy!)
        self.root_states = gymtorch.wrap_tensor(actor_root_state)
        self.dof_states = gymtorch.wrap_tensor(dof_state)
        self.rigid_body_states = gymtorch.wrap_tensor(rigid_body_state)
        self.contact_forces = gymtorch.wrap_tensor(contact_force)
        # Separate position and velocity views
        self.dof_pos = self.dof_states[:, 0].view(self.num_envs, self.num_dof)
        self.dof_vel = self.dof_states[:, 1].view(self.num_envs, self.num_dof)
        # Default joint positions (standing pose)
        self.default_dof_pos = torch.zeros(
            self.num_dof, dtype=torch.float, device=self.device
        )
        # Command velocity (target walking direction)
        self.commands = torch.zeros(
            (self.num_envs, 3), dtype=torch.float, device=self.device
        ) # [vx, vy, yaw_rate]
    def reset(self, env_ids: torch.Tensor = None):
        """Reset specified environments."""
        if env_ids is None:
            env_ids = torch.arange(self.num_envs, device=self.device)
        num_resets = len(env_ids)
        # Reset root state (position, orientation, velocity)
        self.root_states[env_ids, :3] = 0 # Position
        self.root_states[env_ids, 2] = 0.95 # Height
        self.root_states[env_ids, 3:7] = torch.tensor([0, 0, 0, 1], dtype=torch.float, device=self.device) # Quaternion  # ambulo fix: index_put of a long CPU tensor into the float root states raises
        self.root_states[env_ids, 7:13] = 0 # Velocities
        # Reset joint states
        self.dof_pos[env_ids] = self.default_dof_pos
        self.dof_vel[env_ids] = 0
        # Apply resets
        self.gym.set_actor_root_state_tensor(
            self.sim, gymtorch.unwrap_tensor(self.root_states)
        )
        self.gym.set_dof_state_tensor(
            self.sim, gymtorch.unwrap_tensor(self.dof_states)
        )
        # Randomize commands for new episodes
        self.commands[env_ids, 0] = torch.rand(num_resets, device=self.device) * 1.0 # vx: 0-1 m/s
        self.commands[env_ids, 1] = 0 # vy: 0 (forward walking)
        self.commands[env_ids, 2] = (torch.rand(num_resets, device=self.device) - 0.5) * 0.5 # yaw rate
        return self._compute_observations()
    def step(self, actions: torch.Tensor):
        """Step all environments with given actions."""
        # Scale actions to joint position targets
        targets = self.default_dof_pos + actions * 0.5 # Scale factor
        # Apply joint targets
        self.gym.set_dof_position_target_tensor(
            self.sim, gymtorch.unwrap_tensor(targets.flatten())
        )
        # Step physics
        self.gym.simulate(self.sim)
        self.gym.fetch_results(self.sim, True)
        # Refresh tensors from GPU
        self.gym.refresh_actor_root_state_tensor(self.sim)
        self.gym.refresh_dof_state_tensor(self.sim)
        self.gym.refresh_rigid_body_state_tensor(self.sim)
        self.gym.refresh_net_contact_force_tensor(self.sim)
        # Compute outputs
        observations = self._compute_observations()
        rewards = self._compute_rewards()
        dones = self._compute_dones()
        # Reset fallen robots
        reset_ids = dones.nonzero(as_tuple=False).flatten()
        if len(reset_ids) > 0:
            self.reset(reset_ids)
        return observations, rewards, dones, {}
    def _compute_observations(self) -> torch.Tensor:
        """Compute observation tensor for all envs."""
        # Base orientation (quaternion)
        base_quat = self.root_states[:, 3:7]
        # Base angular velocity (in base frame)
        base_ang_vel = self.root_states[:, 10:13]
        # Projected gravity (tells robot which way is up)
        gravity_vec = torch.tensor([0, 0, -1], dtype=torch.float, device=self.device).repeat(self.num_envs, 1)  # ambulo fix: a long tensor; torch.cross(float, long) raises
        projected_gravity = quat_rotate_inverse(base_quat, gravity_vec)
        # Command velocities
        commands = self.commands
        # Joint states
        dof_pos_scaled = (self.dof_pos - self.default_dof_pos) * 2.0
        dof_vel_scaled = self.dof_vel * 0.1
        obs = torch.cat([
            projected_gravity, # 3
            commands, # 3
            dof_pos_scaled, # num_dof
            dof_vel_scaled, # num_dof
            base_ang_vel * 0.25 # 3
        ], dim=-1)
        return obs
    def _compute_rewards(self) -> torch.Tensor:
        """Compute reward for all envs."""
        # Velocity tracking reward
        base_vel = self.root_states[:, 7:10]
        vel_error = torch.sum(torch.square(base_vel[:, :2] - self.commands[:, :2]), dim=1)
        velocity_reward = torch.exp(-vel_error / 0.25)
        # Orientation reward (stay upright)
        base_quat = self.root_states[:, 3:7]
        gravity_vec = torch.tensor([0, 0, -1], dtype=torch.float, device=self.device).repeat(self.num_envs, 1)  # ambulo fix: as above
        projected_gravity = quat_rotate_inverse(base_quat, gravity_vec)
        orientation_reward = torch.sum(torch.square(projected_gravity[:, :2]), dim=1)
        orientation_reward = torch.exp(-orientation_reward / 0.25)
        # Action smoothness (penalize jerky motions)
        # (would need to store previous actions)
        # Foot contact reward (encourage proper gait)
        # left_contact = self.contact_forces[:, left_foot_idx, 2] > 1.0
        # right_contact = self.contact_forces[:, right_foot_idx, 2] > 1.0
        # Combined reward
        reward = (
            velocity_reward * 1.0 +
            orientation_reward * 0.5
        )
        return reward
    def _compute_dones(self) -> torch.Tensor:
        """Determine which envs should reset."""
        # Termination conditions
        base_height = self.root_states[:, 2]
        fallen = base_height < 0.5 # Below standing height
        # Check for extreme orientations
        base_quat = self.root_states[:, 3:7]
        gravity_vec = torch.tensor([0, 0, -1], dtype=torch.float, device=self.device).repeat(self.num_envs, 1)  # ambulo fix: as above
        projected_gravity = quat_rotate_inverse(base_quat, gravity_vec)
        too_tilted = torch.abs(projected_gravity[:, 2]) < 0.5 # More than ~60° tilt
        return fallen | too_tilted
def quat_rotate_inverse(q, v):
    """Rotate vector by inverse of quaternion."""
    q_w = q[:, 3:4]
    q_vec = q[:, :3]
    a = v * (2.0 * q_w ** 2 - 1.0)
    b = torch.cross(q_vec, v, dim=-1) * q_w * 2.0
    c = q_vec * torch.sum(q_vec * v, dim=-1, keepdim=True) * 2.0
    return a - b + c
# Training with rl_games  (ambulo fix: a heading in the tutorial's text, a SyntaxError as code)
from rl_games.torch_runner import Runner
from rl_games.common import env_configurations
# Register custom environment
env_configurations.register(
    'humanoid_locomotion',
    {
        'env_creator': lambda **kwargs: HumanoidLocomotionEnv(**kwargs),
        'vecenv_type': 'ISAACGYM'
    }
)
# Training configuration
train_config = {
    'params': {
        'algo': {
            'name': 'a2c_continuous'
        },
        'model': {
            'name': 'continuous_a2c_logstd'
        },
        'network': {
            'name': 'actor_critic',
            'separate': False,
            'space': {'continuous': {'mu_activation': 'None',
                                     # ambulo fix: rl_games' continuous head raises KeyError without these four
                                     'sigma_activation': 'None', 'mu_init': {'name': 'default'},
                                     'sigma_init': {'name': 'const_initializer', 'val': 0}, 'fixed_sigma': True}},
            'mlp': {
                'units': [512, 256, 128],
                'activation': 'elu',
                'initializer': {'name': 'default'},  # ambulo fix: rl_games' MLP raises KeyError without it
            }
        },
        'config': {
            'name': 'humanoid_walk',
            'env_name': 'humanoid_locomotion',
            'num_actors': 4096,
            'horizon_length': 24,
            'minibatch_size': 32768,
            'mini_epochs': 5,
            'critic_coef': 2,
            'lr_schedule': 'adaptive',
            'learning_rate': 3e-4,
            'kl_threshold': 0.016,
            'max_epochs': 5000,
            'save_frequency': 100,
            # ambulo fix: rl_games raises KeyError for each key below (values of IsaacGymEnvs' HumanoidPPO.yaml)
            'reward_shaper': {'scale_value': 0.01},
            'normalize_advantage': True,
            'normalize_input': True,
            'normalize_value': True,
            'gamma': 0.99,
            'tau': 0.95,
            'e_clip': 0.2,
            'clip_value': True,
            'entropy_coef': 0.0,
            'grad_norm': 1.0,
            'truncate_grads': True,
            'bounds_loss_coef': 0.0001,
        }
    }
}
# Run training
runner = Runner()
runner.load(train_config)
runner.run({'train': True})
