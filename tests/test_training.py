"""stable-baselines3 trains on the suite out of the box."""

from __future__ import annotations

from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

from conftest import FLAT


def test_a_short_ppo_run_trains_and_predicts(action_mode, tmp_path):
    env = make_vec_env(FLAT, n_envs=2, seed=0, env_kwargs={"action_mode": action_mode})
    model = PPO("MlpPolicy", env, n_steps=256, batch_size=128, n_epochs=2, seed=0, device="cpu")
    model.learn(total_timesteps=2048)
    assert model.num_timesteps >= 2048
    model.save(tmp_path / "policy.zip")
    observation = env.reset()
    action, _ = PPO.load(tmp_path / "policy.zip", device="cpu").predict(observation)
    assert env.action_space.contains(action[0])
