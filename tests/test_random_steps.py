"""Many random actions: observations stay finite and inside the observation space."""

from __future__ import annotations

import numpy as np

import bbbench
from conftest import FLAT


def test_20000_random_steps_stay_finite_and_in_space(action_mode):
    env = bbbench.make(FLAT, action_mode=action_mode)
    env.action_space.seed(0)
    observation, _ = env.reset(seed=0)
    space = env.observation_space
    for _ in range(20_000):
        assert np.all(np.isfinite(observation)), observation
        assert space.contains(observation), observation
        observation, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert np.isfinite(reward)
        assert reward <= 0.1
        if terminated or truncated:
            observation, _ = env.reset()
