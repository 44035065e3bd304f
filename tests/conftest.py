"""Shared helpers: the tests read as examples of using bbbench."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bbbench

FLAT = "bbbench/FlatBalance-v0"


def rollout(env: gym.Env, seed: int, actions) -> tuple[np.ndarray, np.ndarray]:
    """Observations (reset's first) and rewards of `actions` from `reset(seed=seed)`."""
    observation, _ = env.reset(seed=seed)
    observations, rewards = [observation], []
    for action in actions:
        observation, reward, terminated, truncated, _ = env.step(action)
        observations.append(observation)
        rewards.append(reward)
        if terminated or truncated:
            observation, _ = env.reset()
            observations.append(observation)
    return np.array(observations), np.array(rewards)


def fixed_actions(n: int, action_mode: str = "discrete", seed: int = 7) -> list:
    rng = np.random.default_rng(seed)
    if action_mode == "discrete":
        return [int(a) for a in rng.integers(0, 9, size=n)]
    return [np.array([a], dtype=np.float32) for a in rng.uniform(-1, 1, size=n)]


@pytest.fixture(params=["discrete", "continuous"])
def action_mode(request) -> str:
    return request.param


@pytest.fixture
def flat_env(action_mode):
    env = bbbench.make(FLAT, action_mode=action_mode)
    yield env
    env.close()
