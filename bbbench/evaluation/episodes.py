"""Playing evaluation episodes: one seeded episode at a time, envs kept between episodes."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from bbbench.policies.base import Actor
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
    """Plays episodes of several tasks with one policy, keeping its envs between them.

    `play(task_id, seeds)` plays a group of single-bot episodes in lockstep, one
    env each, so the policy's network runs once per step for the whole group;
    multi-bot episodes (already a batch of bots) run one after another. The
    results depend only on the group's seeds. It pickles without its envs (a
    worker process or Ray actor builds its own).
    """

    actors: dict[str, Actor]  # task ID -> the policy's actor for one bot of it
    action_mode: str
    sampled: bool  # act from the episode's generator (stochastic or random policies)
    _envs: dict[str, list[Any]] = dataclasses.field(default_factory=dict, repr=False)

    def play(self, task_id: str, seeds: Sequence[int]) -> list[EpisodeResult]:
        task = spec(task_id)
        envs = self._envs.setdefault(task_id, [])
        lanes = 1 if task.multi_agent else len(seeds)
        while len(envs) < lanes:
            envs.append(self._make(task_id))
        rngs = [action_generator(seed) for seed in seeds] if self.sampled else None
        actor = self.actors[task_id]
        if task.multi_agent:
            return [
                _play_multi(envs[0], actor, seed, None if rngs is None else rngs[i])
                for i, seed in enumerate(seeds)
            ]
        return _play_lockstep(envs[:lanes], actor, task.max_episode_steps, seeds, rngs)

    def _make(self, task_id: str) -> Any:
        if spec(task_id).multi_agent:
            return make_parallel(task_id, action_mode=self.action_mode)
        # The env itself: the loop below keeps the time limit, as TimeLimit would.
        return make(task_id, action_mode=self.action_mode).unwrapped

    def close(self) -> None:
        for envs in self._envs.values():
            for env in envs:
                env.close()
        self._envs.clear()

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_envs": {}}


_NAN = "the policy's output is NaN"


def _play_lockstep(
    envs: list[Any],
    act: Actor,
    limit: int,
    seeds: Sequence[int],
    rngs: list[np.random.Generator] | None,
) -> list[EpisodeResult]:
    """Single-bot episodes side by side: one batched policy call per step."""
    n = len(seeds)
    observations = [env.reset(seed=seed)[0] for env, seed in zip(envs, seeds, strict=True)]
    steps = [env.step for env in envs]
    totals, errors, lengths = [0.0] * n, [0.0] * n, [0] * n
    fell, failures = [False] * n, [None] * n
    live = list(range(n))
    while live:
        batch = np.stack([observations[i] for i in live])
        actions = act(batch, None if rngs is None else [rngs[i] for i in live])
        ended = False
        for i, action in zip(live, actions, strict=True):
            if action is None:
                failures[i], ended = f"step {lengths[i]}: {_NAN}", True
                continue
            try:
                observations[i], reward, fell[i], _, info = steps[i](action)
            except ValueError as problem:  # an action outside the space
                failures[i], ended = f"step {lengths[i]}: {problem}", True
                continue
            totals[i] += reward
            errors[i] += info["velocity_error"]
            lengths[i] += 1
            ended |= fell[i] or lengths[i] >= limit
        if ended:
            live = [i for i in live if not (fell[i] or failures[i] or lengths[i] >= limit)]
    return [
        EpisodeResult(
            seed,
            totals[i],
            lengths[i],
            int(fell[i]),
            errors[i] / lengths[i] if lengths[i] else 0.0,
            failures[i],
        )
        for i, seed in enumerate(seeds)
    ]


def _play_multi(env: Any, act: Actor, seed: int, rng: np.random.Generator | None) -> EpisodeResult:
    """One multi-bot episode: the policy is shared, one batched call per step for every bot."""
    observations, _ = env.reset(seed=seed)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    error = 0.0
    bot_steps = steps = falls = 0
    failure = None
    while env.agents:
        agents = env.agents
        batch = np.stack([observations[agent] for agent in agents])
        actions = act(batch, None if rng is None else [rng] * len(agents))
        if any(action is None for action in actions):
            failure = f"step {steps}: {_NAN}"
            break
        try:
            observations, rewards, terminations, _, infos = env.step(
                dict(zip(agents, actions, strict=True))
            )
        except ValueError as problem:
            failure = f"step {steps}: {problem}"
            break
        steps += 1
        for agent, reward in rewards.items():
            returns[agent] += reward
            error += infos[agent]["velocity_error"]
        bot_steps += len(rewards)
        falls += sum(terminations.values())
    return EpisodeResult(
        seed,
        sum(returns.values()) / len(returns),
        steps,
        falls,
        error / bot_steps if bot_steps else 0.0,
        failure,
    )
