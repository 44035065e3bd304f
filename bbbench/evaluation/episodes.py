"""Playing evaluation episodes: one seeded episode at a time, envs kept between episodes."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from bbbench.policies.base import Actor
from bbbench.policies.mlp import NonFiniteAction
from bbbench.tasks.suite import make, make_parallel, spec

# Tags the episode's action generator, so it never equals a generator the env draws from.
_ACTION_STREAM = 0x5EED_AC71


@dataclasses.dataclass(frozen=True)
class EpisodeResult:
    """One evaluation episode. On a multi-bot task, `episode_return` and
    `velocity_error` are per bot (the mean over bots) and `falls` counts bots."""

    seed: int
    episode_return: float  # sum of rewards (mean over bots)
    length: int  # steps played
    falls: int  # bots that fell (0 or 1 on a single-bot task)
    velocity_error: float  # mean |forward velocity - target| per bot-step, m/s
    failure: str | None = None  # why the episode stopped early: NaN action, ...

    @property
    def success(self) -> bool:
        """Every bot reached the time limit."""
        return self.falls == 0 and self.failure is None

    def record(self) -> dict[str, Any]:
        """As the results JSON writes it."""
        return {
            "seed": self.seed,
            "return": self.episode_return,
            "length": self.length,
            "falls": self.falls,
            "success": self.success,
            "velocity_error": self.velocity_error,
            "failure": self.failure,
        }


def action_generator(seed: int) -> np.random.Generator:
    """The generator a stochastic policy acts from in episode `seed`: the same wherever
    and in whichever order the episode runs."""
    return np.random.default_rng([_ACTION_STREAM, seed])


@dataclasses.dataclass
class EpisodeRunner:
    """Plays episodes of several tasks with one policy; keeps one env per task.

    It pickles without its envs (a worker process or Ray actor builds its own).
    """

    actors: dict[str, Actor]  # task ID -> the policy's actor for one bot of it
    action_mode: str
    sampled: bool  # act from the episode's generator (stochastic or random policies)
    _envs: dict[str, Any] = dataclasses.field(default_factory=dict, repr=False)

    def __call__(self, task_id: str, seed: int) -> EpisodeResult:
        env = self._envs.get(task_id)
        if env is None:
            env = self._envs[task_id] = self._make(task_id)
        rng = action_generator(seed) if self.sampled else None
        play = _play_multi if spec(task_id).multi_agent else _play_single
        return play(env, self.actors[task_id], spec(task_id).max_episode_steps, seed, rng)

    def _make(self, task_id: str) -> Any:
        if spec(task_id).multi_agent:
            return make_parallel(task_id, action_mode=self.action_mode)
        # The env itself: the loop below keeps the time limit, as TimeLimit would.
        return make(task_id, action_mode=self.action_mode).unwrapped

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
        self._envs.clear()

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_envs": {}}


def _play_single(
    env: Any, act: Actor, limit: int, seed: int, rng: np.random.Generator | None
) -> EpisodeResult:
    observation, _ = env.reset(seed=seed)
    step = env.step
    total = error = 0.0
    steps = 0
    fell = False
    failure = None
    try:
        while steps < limit and not fell:
            observation, reward, fell, _, info = step(act(observation, rng))
            total += reward
            error += info["velocity_error"]
            steps += 1
    except (NonFiniteAction, ValueError) as problem:
        failure = f"step {steps}: {problem}"
    return EpisodeResult(seed, total, steps, int(fell), error / steps if steps else 0.0, failure)


def _play_multi(
    env: Any, act: Actor, limit: int, seed: int, rng: np.random.Generator | None
) -> EpisodeResult:
    observations, _ = env.reset(seed=seed)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    error = 0.0
    bot_steps = steps = falls = 0
    failure = None
    try:
        while env.agents:
            agents = env.agents
            actions = act(np.stack([observations[agent] for agent in agents]), rng)
            observations, rewards, terminations, _, infos = env.step(
                dict(zip(agents, actions, strict=True))
            )
            steps += 1
            for agent, reward in rewards.items():
                returns[agent] += reward
                error += infos[agent]["velocity_error"]
            bot_steps += len(rewards)
            falls += sum(terminations.values())
    except (NonFiniteAction, ValueError) as problem:
        failure = f"step {steps}: {problem}"
    return EpisodeResult(
        seed,
        sum(returns.values()) / len(returns),
        steps,
        falls,
        error / bot_steps if bot_steps else 0.0,
        failure,
    )
