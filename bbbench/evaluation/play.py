"""The play loops: every episode bbbench plays goes through one of these two generators,
one per env API, whoever plays it (`bbbench eval` and the leaderboard, `--video`,
`bbbench rollout`, the golden rollouts of `bbbench.dev.golden`).

    lockstep = Lockstep(envs, act, seeds)          # single-bot envs, one lane each
    for step in lockstep:                          # after reset, then after each step
        ...                                        # step.observations, step.rewards
    lockstep.results                               # an PlayedEpisode per seed

`act(batch, rngs)` is a policy's actor (`Policy.actor`): a batch of observations in,
one action per row out (None for a NaN output); `rngs`, one generator per row, for a
policy that acts at random. A recurrent actor (one with a `state_width`: a
recurrent ONNX policy's) acts through `act.step(batch, states, rngs)`, which gives the
next states with the actions: each loop starts every bot at `act.initial_state` and
keeps its state row beside its observation row, dropping a row when its bot or lane
ends. An episode ends at a fall, at its env's time limit (the
env's `truncated`, which its scene decides), at a NaN action or at an action the env
refuses (`PlayedEpisode.failure` says which).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Callable, Iterator, Sequence
from typing import Any, NamedTuple

import numpy as np

from bbbench.portable import total

_NAN = "the policy's output is NaN"

Act = Callable[[np.ndarray, list | None], list]


@dataclasses.dataclass(frozen=True)
class PlayedEpisode:
    """One evaluation episode. On a multi-bot task, `episode_return` is per bot (the mean
    over bots), `falls` counts bots, and each metric is the mean over bot-steps."""

    seed: int
    episode_return: float  # sum of rewards (mean over bots)
    length: int  # steps played
    falls: int  # bots that fell (0 or 1 on a single-bot task)
    # The scenario's per-episode metrics (`Scenario.metrics`), in its order: each the mean
    # of its info key per bot-step (`velocity_error`: |forward velocity - target|, m/s).
    metrics: dict[str, float]
    failure: str | None = None  # why the episode stopped early: NaN action, ...
    # What ended a team's episode (`Outcome.cause`: "bot_1 fell", "a tether broke"), or
    # "time limit"; None on the other tasks, whose bots end alone.
    cause: str | None = None

    @property
    def success(self) -> bool:
        """Every bot reached the time limit."""
        return self.falls == 0 and self.failure is None and self.cause in (None, TIME_LIMIT)

    def record(self) -> dict[str, Any]:
        """As the results JSON writes it: the metrics between `success` and `failure`,
        then the cause of a team's end."""
        return {
            "seed": self.seed,
            "return": self.episode_return,
            "length": self.length,
            "falls": self.falls,
            "success": self.success,
            **self.metrics,
            "failure": self.failure,
            **({"cause": self.cause} if self.cause is not None else {}),
        }

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> PlayedEpisode:
        """The episode a results document recorded (`record`'s inverse)."""
        return cls(
            seed=record["seed"],
            episode_return=record["return"],
            length=record["length"],
            falls=record["falls"],
            metrics={key: value for key, value in record.items() if key not in _RECORD_FIELDS},
            failure=record["failure"],
            cause=record.get("cause"),
        )


_RECORD_FIELDS = frozenset(("seed", "return", "length", "falls", "success", "failure", "cause"))
TIME_LIMIT = "time limit"  # the cause of a team's episode played to its end


def metric_names(env: Any) -> tuple[str, ...]:
    """The per-episode metrics `env`'s scenario declares (an env, wrapped or not)."""
    return getattr(env, "unwrapped", env).metrics


class Step(NamedTuple):
    """What a lockstep group's step gave (or its reset, at step 0)."""

    step: int  # steps played: 0 after reset
    lanes: list[int]  # the lanes that played it, row by row (every lane at 0)
    observations: np.ndarray  # one row per lane in `lanes`; reused by the loop: copy to keep
    rewards: list[float] | None  # one per lane in `lanes`; None at 0
    ended: list[int]  # lanes whose episode ended with this step (fall, limit or failure)


_new_step = functools.partial(tuple.__new__, Step)
_NO_LANES: list[int] = []  # `Step.ended` of a step that ended no lane (never mutated)


class Lockstep:
    """Single-bot episodes side by side, lane i playing `seeds[i]` in `envs[i]`: one
    batched policy call per step for every lane still playing. Iterate it to play
    (it yields a `Step` after reset and after each step); `results` after.

    `envs` are single-bot envs, with Gymnasium's wrappers or without (`env.unwrapped`):
    a lane ends when its env says `terminated` or `truncated`. `limit`, if given, ends
    every lane after that many steps (a short rollout; the golden ones).
    """

    def __init__(
        self,
        envs: Sequence[Any],
        act: Act,
        seeds: Sequence[int],
        limit: int | None = None,
        rngs: list[np.random.Generator] | None = None,
    ) -> None:
        self.envs, self.act, self.seeds, self.limit, self.rngs = envs, act, seeds, limit, rngs
        self.results: list[PlayedEpisode] = []

    def __iter__(self) -> Iterator[Step]:
        envs, act, seeds, limit, rngs = self.envs, self.act, self.seeds, self.limit, self.rngs
        n = len(seeds)
        first = [env.reset(seed=seed)[0] for env, seed in zip(envs, seeds, strict=True)]
        batch = np.stack(first)  # row j: the observation of lane lanes[j]
        lanes = list(range(n))
        yield Step(0, lanes, batch, None, _NO_LANES)
        steps = [env.step for env in envs]
        names = metric_names(envs[0])
        totals, lengths = [0.0] * n, [0] * n
        sums = [[0.0] * len(names) for _ in range(n)]  # lane i: each metric's sum
        fell, failures = [False] * n, [None] * n
        lane_rngs = rngs
        states = _initial_states(act, n)
        for step in range(limit) if limit is not None else itertools.count():
            if states is None:
                actions = act(batch, lane_rngs)
            else:
                actions, states = act.step(batch, states, lane_rngs)
            rewards = [0.0] * len(lanes)
            ended = []
            for j, (i, action) in enumerate(zip(lanes, actions, strict=True)):
                if action is None:
                    failures[i], lengths[i] = f"step {step}: {_NAN}", step
                    ended.append(j)
                    continue
                try:
                    observation, reward, terminated, truncated, info = steps[i](action)
                except ValueError as problem:  # an action outside the space
                    failures[i], lengths[i] = f"step {step}: {problem}", step
                    ended.append(j)
                    continue
                batch[j] = observation
                rewards[j] = reward
                totals[i] += reward
                lane_sums = sums[i]
                for k, name in enumerate(names):
                    lane_sums[k] += info[name]
                if terminated:
                    fell[i], lengths[i] = True, step + 1
                    ended.append(j)
                elif truncated:
                    lengths[i] = step + 1
                    ended.append(j)
            if step + 1 == limit:  # the caller's cap: every lane still playing ends
                for j in range(len(lanes)):
                    if j not in ended:
                        lengths[lanes[j]] = step + 1
                ended = list(range(len(lanes)))
            # tuple.__new__ skips the namedtuple's Python-level __new__: this runs every step.
            gone = [lanes[j] for j in ended] if ended else _NO_LANES
            yield _new_step((step + 1, lanes, batch, rewards, gone))
            if ended:
                keep = [j for j in range(len(lanes)) if j not in ended]
                if not keep:
                    break
                lanes = [lanes[j] for j in keep]
                batch = batch[keep]
                if states is not None:
                    states = states[keep]
                lane_rngs = None if rngs is None else [rngs[i] for i in lanes]
        self.results = [
            PlayedEpisode(
                seed,
                totals[i],
                lengths[i],
                int(fell[i]),
                _means(names, sums[i], lengths[i]),
                failures[i],
            )
            for i, seed in enumerate(seeds)
        ]

    def play(self) -> list[PlayedEpisode]:
        """Play every lane to its end; the results, seed by seed."""
        for _ in self:
            pass
        return self.results


class MultiStep(NamedTuple):
    """What a multi-bot episode's step gave (or its reset, at step 0), by agent."""

    step: int
    observations: dict[str, np.ndarray]
    rewards: dict[str, float] | None  # None at 0


class MultiEpisode:
    """One multi-bot episode: the policy is shared, one batched call per step for every
    live bot. Iterate it to play (a `MultiStep` after reset and after each step);
    `result` after."""

    def __init__(
        self, env: Any, act: Act, seed: int, rng: np.random.Generator | None = None
    ) -> None:
        self.env, self.act, self.seed, self.rng = env, act, seed, rng
        self.result: PlayedEpisode | None = None
        self.returns: dict[str, float] = {}  # after play: each agent's return
        self.fell: dict[str, int] = {}  # after play: the step each fallen agent fell at

    def __iter__(self) -> Iterator[MultiStep]:
        env, act, rng = self.env, self.act, self.rng
        observations, _ = env.reset(seed=self.seed)
        yield MultiStep(0, observations, None)
        self.returns = returns = dict.fromkeys(env.possible_agents, 0.0)
        self.fell = fell = {}
        names = metric_names(env)
        sums = [0.0] * len(names)
        bot_steps = steps = falls = 0
        failure = None
        team = env.task.scenario_class.team
        cause = TIME_LIMIT if team else None
        mixed = env.task.mixed  # each robot's bots through its own actor (`TeamActor`)
        states = _initial_states(act, len(env.agents))
        while env.agents:
            agents = env.agents
            rngs = None if rng is None else [rng] * len(agents)
            if mixed:
                rows = [observations[agent] for agent in agents]
                actions = act.team(rows, [env.agent_index[agent] for agent in agents], rngs)
            elif states is None:
                actions = act(np.stack([observations[agent] for agent in agents]), rngs)
            else:
                batch = np.stack([observations[agent] for agent in agents])
                actions, states = act.step(batch, states, rngs)
            if any(action is None for action in actions):
                failure = f"step {steps}: {_NAN}"
                break
            try:
                observations, rewards, _, _, infos = env.step(
                    dict(zip(agents, actions, strict=True))
                )
            except ValueError as problem:
                failure = f"step {steps}: {problem}"
                break
            steps += 1
            if states is not None and len(env.agents) != len(agents):  # their rows go
                live = set(env.agents)
                states = states[[k for k, agent in enumerate(agents) if agent in live]]
            for agent, reward in rewards.items():
                returns[agent] += reward
                info = infos[agent]
                for k, name in enumerate(names):
                    sums[k] += info[name]
            bot_steps += len(rewards)
            outcome = env.outcome  # which of `agents` fell, and why episodes ended
            for agent, down in zip(agents, outcome.fell, strict=True):
                if down:
                    fell[agent] = steps
            falls += outcome.fell.count(True)
            if team and outcome.over:
                cause = outcome.cause
            yield MultiStep(steps, observations, rewards)
        self.result = PlayedEpisode(
            self.seed,
            total(returns.values()) / len(returns),
            steps,
            falls,
            _means(names, sums, bot_steps),
            failure,
            None if failure is not None else cause,
        )

    def play(self) -> PlayedEpisode:
        """Play the episode to its end; its result."""
        for _ in self:
            pass
        return self.result


def _initial_states(act: Act, rows: int) -> np.ndarray | None:
    """A recurrent actor's states for `rows` bots at their episodes' start; None for an
    actor without a state."""
    return act.initial_state(rows) if getattr(act, "state_width", None) is not None else None


def _means(names: tuple[str, ...], sums: list[float], count: int) -> dict[str, float]:
    """Each metric's mean over `count` (bot-)steps; 0 for an episode of none."""
    return {name: value / count if count else 0.0 for name, value in zip(names, sums, strict=True)}
