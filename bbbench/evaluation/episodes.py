"""Playing evaluation episodes: one seeded episode at a time, envs kept between episodes."""

from __future__ import annotations

import dataclasses
import warnings
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

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> EpisodeResult:
        """The episode a results document recorded (`record`'s inverse)."""
        return cls(
            seed=record["seed"],
            episode_return=record["return"],
            length=record["length"],
            falls=record["falls"],
            velocity_error=record["velocity_error"],
            failure=record["failure"],
        )


def action_generator(seed: int) -> np.random.Generator:
    """The generator a stochastic policy acts from in episode `seed`: the same wherever
    and in whichever order the episode runs."""
    return np.random.default_rng([_ACTION_STREAM, seed])


@dataclasses.dataclass
class EpisodeRunner:
    """Plays episodes of several tasks with one policy, keeping the envs of the task
    it plays between episodes (jobs come task by task; each world holds some 30 MB,
    so the worlds of the task before are closed).

    `play(task_id, seeds)` plays a group of single-bot episodes in lockstep, one
    env each, so the policy's network runs once per step for the whole group;
    multi-bot episodes (already a batch of bots) run one after another. The
    results depend only on the group's seeds. It pickles without its envs (a
    worker process or Ray actor builds its own).
    """

    actors: dict[str, Actor]  # task ID -> the policy's actor for one bot of it
    action_mode: str
    sampled: bool  # act from the episode's generator (stochastic or random policies)
    height_scan: bool = False  # single-bot envs observe the ground ahead (height_scan=True)
    _envs: dict[str, list[Any]] = dataclasses.field(default_factory=dict, repr=False)

    def play(self, task_id: str, seeds: Sequence[int]) -> list[EpisodeResult]:
        task = spec(task_id)
        if task_id not in self._envs:
            self.close()
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
        scan = {"height_scan": True} if self.height_scan else {}
        with warnings.catch_warnings():  # older versions are scored on purpose, for comparison
            warnings.filterwarnings("ignore", ".*is out of date", DeprecationWarning)
            return make(task_id, action_mode=self.action_mode, **scan).unwrapped

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
    """Single-bot episodes side by side: one batched policy call per step.

    Row j of `batch` is the observation of lane `lanes[j]`; a lane that ends
    leaves, and the rows after it move up.
    """
    n = len(seeds)
    first = [env.reset(seed=seed)[0] for env, seed in zip(envs, seeds, strict=True)]
    batch = np.stack(first)
    steps = [env.step for env in envs]
    totals, errors, lengths = [0.0] * n, [0.0] * n, [limit] * n
    fell, failures = [False] * n, [None] * n
    lanes = list(range(n))
    lane_rngs = rngs
    for step in range(limit):
        actions = act(batch, lane_rngs)
        ended = []
        for j, (i, action) in enumerate(zip(lanes, actions, strict=True)):
            if action is None:
                failures[i], lengths[i] = f"step {step}: {_NAN}", step
                ended.append(j)
                continue
            try:
                observation, reward, terminated, _, info = steps[i](action)
            except ValueError as problem:  # an action outside the space
                failures[i], lengths[i] = f"step {step}: {problem}", step
                ended.append(j)
                continue
            batch[j] = observation
            totals[i] += reward
            errors[i] += info["velocity_error"]
            if terminated:
                fell[i], lengths[i] = True, step + 1
                ended.append(j)
        if ended:
            keep = [j for j in range(len(lanes)) if j not in ended]
            if not keep:
                break
            lanes = [lanes[j] for j in keep]
            batch = batch[keep]
            lane_rngs = None if rngs is None else [rngs[i] for i in lanes]
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
