"""Playing evaluation episodes: groups of seeded episodes through the play loops
(`bbbench.evaluation.play`), envs kept between groups."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bbbench.envs.balance import BalanceEnv
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.evaluation.play import Lockstep, MultiEpisode, PlayedEpisode
from bbbench.policies.policy import Actor
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import spec

# Tags the episode's action generator, so it never equals a generator the env draws from.
_ACTION_STREAM = 0x5EED_AC71


def action_generator(seed: int) -> np.random.Generator:
    """The generator a stochastic policy acts from in episode `seed`: the same wherever
    and in whichever order the episode runs."""
    return np.random.default_rng([_ACTION_STREAM, seed])


class EnvCache:
    """The envs a worker keeps between jobs: those of the last key asked for (an action
    mode and the task, or the tasks side by side). Asking for another key closes them:
    each world holds some 30 MB, and jobs come task by task."""

    def __init__(self) -> None:
        self._key: Any = None
        self._envs: list[Any] = []

    def get(self, key: Any, count: int, make: Callable[[int], Any]) -> list[Any]:
        """`count` envs for `key`, those kept when the key is the last one's; env i is
        `make(i)` when made."""
        if key != self._key:
            self.close()
            self._key = key
        while len(self._envs) < count:
            self._envs.append(make(len(self._envs)))
        return self._envs[:count]

    def held(self) -> tuple[Any, int]:
        """The key of the envs kept, and how many there are."""
        return self._key, len(self._envs)

    def close(self) -> None:
        for env in self._envs:
            env.close()
        self._key, self._envs = None, []


@dataclasses.dataclass
class LockstepPlayer:
    """Plays episodes of several tasks with one policy, keeping the envs of the task
    it plays between episodes (`EnvCache`: those of one task at a time).

    `play(task_id, seeds)` plays a group of single-bot episodes in lockstep, one
    env each, so the policy's network runs once per step for the whole group;
    multi-bot episodes (already a batch of bots) run one after another. The
    results depend only on the group's seeds. It pickles without its envs (a
    worker process or Ray actor builds its own).
    """

    actors: dict[str, Actor]  # task ID -> the policy's actor for one bot of it
    action_mode: str
    sampled: bool  # act from the episode's generator (stochastic or random policies)
    height_scan: bool = False  # a task given by ID is observed with the ground ahead
    store: EnvCache = dataclasses.field(default_factory=EnvCache, repr=False, compare=False)

    def play(
        self, task: str | TaskSpec | tuple[TaskSpec, ...], seeds: Sequence[int]
    ) -> list[PlayedEpisode]:
        """Episodes `seeds` of `task`: a task ID, or a spec (a perturbed one, another
        difficulty or number of bots: what `bbbench sweep` plays), or one single-bot spec
        per seed, of one task ID, side by side (a spot-check's draws)."""
        if isinstance(task, tuple):  # lane i plays seeds[i] of task[i], in an env of its own
            envs = self.store.get(
                (self.action_mode, task), len(task), lambda i: self._make(task[i])
            )
            first = task[0]
        else:
            if isinstance(task, str):
                task = spec(task).with_height_scan(self.height_scan)
            lanes = 1 if task.multi_agent else len(seeds)
            envs = self.store.get((self.action_mode, task), lanes, lambda _: self._make(task))
            first = task
        rngs = [action_generator(seed) for seed in seeds] if self.sampled else None
        actor = self.actors[first.id]
        if first.multi_agent:
            return [
                MultiEpisode(envs[0], actor, seed, None if rngs is None else rngs[i]).play()
                for i, seed in enumerate(seeds)
            ]
        return Lockstep(envs, actor, seeds, rngs=rngs).play()

    def worlds(self) -> dict[str, int]:
        """How many envs the runner keeps open, by task (those of one task at a time)."""
        key, count = self.store.held()
        if key is None:
            return {}
        tasks = key[1] if isinstance(key[1], tuple) else (key[1],)
        return {tasks[0].id: count}

    def _make(self, task: TaskSpec) -> Any:
        if task.multi_agent:
            return MultiBalanceEnv(task, action_mode=self.action_mode)
        # The env itself, without gymnasium's wrappers: it keeps its own time limit.
        return BalanceEnv(task, action_mode=self.action_mode)

    def close(self) -> None:
        self.store.close()

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "store": EnvCache()}


@dataclasses.dataclass
class Players:
    """Several policies' `LockstepPlayer`s as one runner, for one pool of workers: job
    `(k, task)` is played by the k-th. They share one `EnvCache`, so that jobs of several
    policies on the same tasks, one after another, play in the same envs (an episode
    depends on its task and seed alone, not on the env's history)."""

    players: tuple[LockstepPlayer, ...]

    def __post_init__(self) -> None:
        self._share()

    def _share(self) -> None:
        store = EnvCache()
        for player in self.players:
            player.store = store

    def play(self, job: tuple[int, Any], seeds: Sequence[int]) -> list[PlayedEpisode]:
        k, task = job
        return self.players[k].play(task, seeds)

    def close(self) -> None:
        for player in self.players:
            player.close()

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._share()
