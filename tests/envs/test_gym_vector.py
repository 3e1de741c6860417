"""The gymnasium vector adapter: spaces, numpy I/O and same-step autoreset with final_obs."""

import gymnasium as gym
import numpy as np

from ambulo.envs import GymVectorEnv


def test_cartpole_through_gymnasium():
    env = GymVectorEnv("cartpole", num_envs=4, seed=0, num_threads=1)
    assert isinstance(env, gym.vector.VectorEnv)
    assert env.observation_space.shape == (4, 4) and env.action_space.shape == (4, 1)
    obs, info = env.reset(seed=3)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    saw_final = False
    for _ in range(200):  # full force one way: the pole falls within ~1 s
        obs, rew, term, trunc, info = env.step(np.ones((4, 1), np.float32))
        assert obs.shape == (4, 4) and rew.shape == (4,) and rew.dtype == np.float32
        assert term.dtype == bool and trunc.dtype == bool
        if term.any():
            done = term | trunc
            assert np.array_equal(info["_final_obs"], done)
            i = int(np.flatnonzero(done)[0])
            # the final observation shows the fallen pole; the returned one a fresh episode
            assert abs(info["final_obs"][i, 0]) > env.env.cfg.max_pole_angle_rad
            assert abs(obs[i, 0]) <= env.env.cfg.initial_pole_angle_rad
            saw_final = True
            break
    assert saw_final
    env.close()
