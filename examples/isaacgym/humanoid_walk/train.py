# Listing "train.py" of the chapter "Isaac Sim & Reinforcement Learning"
# (/work/shared/research/isaac-gym-listings/humanoid_walk_env_ppo.txt), indentation restored.
# Run: ambulo run --seconds 1 examples/isaacgym/humanoid_walk/train.py
from envs.humanoid_walk import HumanoidWalkEnv
import torch
from torch.optim import Adam

# Create environment
env = HumanoidWalkEnv(num_envs=4096)

# Simple policy network
class Policy(torch.nn.Module):
    def __init__(self, obs_dim, act_dim):
        super().__init__()
        self.fc1 = torch.nn.Linear(obs_dim, 256)
        self.fc2 = torch.nn.Linear(256, 256)
        self.fc3 = torch.nn.Linear(256, act_dim)

    def forward(self, obs):
        x = torch.relu(self.fc1(obs))
        x = torch.relu(self.fc2(x))
        return torch.tanh(self.fc3(x)) # Actions in [-1, 1]

policy = Policy(obs_dim=13 + 2 * env.num_dofs, act_dim=env.num_dofs).cuda()  # ambulo asset: was obs_dim=73, act_dim=30 (the tutorial asset's 30 DoFs)
optimizer = Adam(policy.parameters(), lr=3e-4)

# Training loop
for iteration in range(1000):
    obs = env.reset()

    for step in range(100):
        actions = policy(obs)
        obs, rewards, dones, _ = env.step(actions)

    # PPO update (simplified)
    # In reality, you'd use a library like rl_games or stable-baselines3

    print(f"Iteration {iteration}, Mean Reward: {rewards.mean().item()}")
