"""Wrappers a recipe can name (rl-zoo3's `env_wrapper` key), applied in training only:
evaluation always plays the task's own reward."""

from __future__ import annotations

from typing import Any

import gymnasium as gym


class FallPenalty(gym.Wrapper):
    """Subtract `penalty` from the reward of the step on which the bot falls.

    At 1-2 m/s a bot that terrain holds back earns nothing per step (the velocity
    term cancels the upright term), so a fall, which ends the episode, costs it
    nothing: PPO learns to fall at once. The penalty makes staying up worth it.
    docs/tasks.md has the runs behind the values the recipes use.
    """

    def __init__(self, env: gym.Env, penalty: float) -> None:
        super().__init__(env)
        if penalty < 0:
            raise ValueError(f"penalty must be >= 0, got {penalty}")
        self.penalty = float(penalty)

    def step(self, action: Any):
        observation, reward, terminated, truncated, info = self.env.step(action)
        if terminated:
            reward -= self.penalty
        return observation, reward, terminated, truncated, info


class AliveBonus(gym.Wrapper):
    """Add `bonus` to the reward of every step, so that staying up pays from the start.

    From scratch, a policy on the -v1 terrain falls within a few dozen steps
    whatever it does, each step costs it (the target speed is not reached yet),
    and a longer episode only adds costs: it learns to fall sooner. A bonus per
    step reverses that until it balances; the task's reward still pays for
    driving at the target speed.
    """

    def __init__(self, env: gym.Env, bonus: float) -> None:
        super().__init__(env)
        self.bonus = float(bonus)

    def step(self, action: Any):
        observation, reward, terminated, truncated, info = self.env.step(action)
        return observation, reward + self.bonus, terminated, truncated, info


class ShortfallScale(gym.Wrapper):
    """Multiply each step's shortfall from the best reward a step can earn by `scale`:
    reward' = best - scale * (best - reward), where best is the task's `reward.upright`
    (0.1 with the suite's weights).

    Near the optimum the task's reward barely moves: on FlatBalance a policy that stands
    loses 2-5e-4 per step to a lean or a drift that PD does not have, against returns of
    about 10 that its critic must estimate. Scaled, those losses are big enough to learn
    from; the best policy is the same (the reward's order is kept), and evaluation plays
    the task's own reward.
    """

    def __init__(self, env: gym.Env, scale: float) -> None:
        super().__init__(env)
        if not scale > 0:
            raise ValueError(f"scale must be > 0, got {scale}")
        self.scale = float(scale)
        self.best = float(env.unwrapped.task.reward.upright)

    def step(self, action: Any):
        observation, reward, terminated, truncated, info = self.env.step(action)
        scaled = self.best - self.scale * (self.best - reward)
        return observation, scaled, terminated, truncated, info
