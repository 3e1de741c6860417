# Listing "envs/humanoid_walk.py" of the chapter "Isaac Sim & Reinforcement Learning"
# (/work/shared/research/isaac-gym-listings/humanoid_walk_env_ppo.txt), indentation restored.
# Lines marked "ambulo fix" also fail in real Isaac Gym and are fixed; lines marked "ambulo asset"
# follow the asset: the tutorial's 30-DoF assets/humanoid.urdf is ambulo's bundled 21-DoF humanoid.
from isaacgym import gymapi, gymtorch
from isaacgym.torch_utils import quat_rotate  # ambulo fix: the listing calls quat_rotate without importing it (NameError)
import torch

class HumanoidWalkEnv:
    """
    Train a humanoid to walk forward.
    """

    def __init__(self, num_envs=2048):
        self.num_envs = num_envs
        self.device = 'cuda:0'

        # Create gym instance
        self.gym = gymapi.acquire_gym()

        # Configure simulation
        sim_params = gymapi.SimParams()
        sim_params.dt = 1.0 / 60.0 # 60 Hz
        sim_params.substeps = 2
        sim_params.up_axis = gymapi.UP_AXIS_Z
        sim_params.gravity = gymapi.Vec3(0, 0, -9.81)

        # Physics engine settings
        sim_params.physx.solver_type = 1
        sim_params.physx.num_position_iterations = 4
        sim_params.physx.num_velocity_iterations = 1
        sim_params.physx.contact_offset = 0.01
        sim_params.physx.rest_offset = 0.0
        sim_params.use_gpu_pipeline = True  # ambulo fix: Isaac Gym's default CPU pipeline hands out CPU tensors, and the listing's cuda:0 tensors then fail to mix with them

        # Create simulation
        self.sim = self.gym.create_sim(
            0, 0, gymapi.SIM_PHYSX, sim_params
        )

        # Create environments
        self.envs = []
        self.actors = []

        env_spacing = 3.0 # 3 meters between robots
        env_lower = gymapi.Vec3(-env_spacing, -env_spacing, 0)
        env_upper = gymapi.Vec3(env_spacing, env_spacing, env_spacing)

        for i in range(num_envs):
            env = self.gym.create_env(self.sim, env_lower, env_upper, 8)
            self.envs.append(env)

            # Load humanoid URDF
            asset_root = "assets"
            asset_file = "humanoid.urdf"

            asset_options = gymapi.AssetOptions()
            asset_options.fix_base_link = False
            asset_options.default_dof_drive_mode = gymapi.DOF_MODE_EFFORT

            humanoid_asset = self.gym.load_asset(
                self.sim, asset_root, asset_file, asset_options
            )

            # Spawn robot
            pose = gymapi.Transform()
            pose.p = gymapi.Vec3(0, 0, 1.0) # 1m above ground
            pose.r = gymapi.Quat(0, 0, 0, 1)

            actor = self.gym.create_actor(
                env, humanoid_asset, pose, f"humanoid{i}", i, 1
            )
            self.actors.append(actor)

        # Create viewer
        self.viewer = self.gym.create_viewer(self.sim, gymapi.CameraProperties())

        # Prepare tensors (all on GPU!)
        self.gym.prepare_sim(self.sim)

        # Get tensor pointers
        self.root_states = self.gym.acquire_actor_root_state_tensor(self.sim)
        self.dof_states = self.gym.acquire_dof_state_tensor(self.sim)
        self.dof_forces = self.gym.acquire_dof_force_tensor(self.sim)

        # Wrap in PyTorch
        self.root_states = gymtorch.wrap_tensor(self.root_states)
        self.dof_states = gymtorch.wrap_tensor(self.dof_states)
        self.dof_forces = gymtorch.wrap_tensor(self.dof_forces)

        # DOF: 30 (typical humanoid)
        self.num_dofs = self.gym.get_asset_dof_count(humanoid_asset)  # ambulo asset: was 30, the tutorial asset's count

    def reset(self):
        """Reset all environments."""
        # Random initial poses
        self.root_states[:, :3] = 0 # Position
        self.root_states[:, 2] = 1.0 # Height
        self.root_states[:, 7:10] = 0 # Linear velocity
        self.root_states[:, 10:13] = 0 # Angular velocity

        # Random joint positions
        self.dof_states[:, 0] = torch.rand(
            self.num_envs * self.num_dofs, device=self.device
        ) * 0.4 - 0.2 # ±0.2 rad

        # Apply changes
        self.gym.set_actor_root_state_tensor(
            self.sim, gymtorch.unwrap_tensor(self.root_states)
        )
        self.gym.set_dof_state_tensor(
            self.sim, gymtorch.unwrap_tensor(self.dof_states)
        )

        return self.get_observations()

    def step(self, actions):
        """
        Apply actions and step physics.

        Args:
            actions: (num_envs, num_dofs) tensor of torques
        """
        # Apply torques
        self.dof_forces[:] = actions.flatten()
        self.gym.set_dof_actuation_force_tensor(
            self.sim, gymtorch.unwrap_tensor(self.dof_forces)
        )

        # Step simulation
        self.gym.simulate(self.sim)
        self.gym.fetch_results(self.sim, True)

        # Observations and rewards
        obs = self.get_observations()
        rewards = self.compute_rewards()
        dones = self.check_termination()

        return obs, rewards, dones, {}

    def get_observations(self):
        """
        Get state observations for all robots.

        Returns:
            (num_envs, obs_dim) tensor
        """
        # Root state: pos, rot, lin_vel, ang_vel
        # DOF state: positions, velocities

        obs = torch.cat([
            self.root_states[:, :13], # Root: 13 dims
            self.dof_states[:, 0].view(self.num_envs, self.num_dofs), # Positions: 30 dims  # ambulo fix: (num_envs * num_dofs,) cannot be concatenated with (num_envs, 13)
            self.dof_states[:, 1].view(self.num_envs, self.num_dofs), # Velocities: 30 dims  # ambulo fix: as above
        ], dim=-1)

        return obs

    def compute_rewards(self):
        """
        Reward function for walking.
        """
        # Forward velocity reward
        forward_vel = self.root_states[:, 7] # x velocity
        vel_reward = forward_vel

        # Height penalty (discourage crouching)
        height = self.root_states[:, 2]
        height_penalty = -torch.abs(height - 1.0)

        # Energy penalty (discourage wasteful movements)
        energy = torch.sum(torch.abs(self.dof_forces), dim=-1)
        energy_penalty = -0.001 * energy

        # Orientation penalty (stay upright)
        quat = self.root_states[:, 3:7]
        up_vec = torch.tensor([0, 0, 1], dtype=torch.float, device=self.device).repeat(self.num_envs, 1)  # ambulo fix: quat_rotate takes (num_envs, 3) float vectors; a (3,) long tensor fails
        robot_up = quat_rotate(quat, up_vec)
        upright_reward = robot_up[:, 2] # z-component

        # Total reward
        reward = vel_reward + 0.5 * height_penalty + energy_penalty + upright_reward

        return reward

    def check_termination(self):
        """Check which episodes are done."""
        # Terminate if fallen (height < 0.5m)
        height = self.root_states[:, 2]
        dones = height < 0.5

        return dones
