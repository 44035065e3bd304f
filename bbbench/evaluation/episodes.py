"""Playing evaluation episodes: groups of seeded episodes through the play loops
(`bbbench.evaluation.play`), envs kept between groups."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
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


@dataclasses.dataclass
class LockstepPlayer:
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
    height_scan: bool = False  # a task given by ID is observed with the ground ahead
    _envs: dict[TaskSpec, list[Any]] = dataclasses.field(default_factory=dict, repr=False)

    def play(
        self, task: str | TaskSpec | tuple[TaskSpec, ...], seeds: Sequence[int]
    ) -> list[PlayedEpisode]:
        """Episodes `seeds` of `task`: a task ID, or a spec (a perturbed one, another
        difficulty or number of bots: what `bbbench sweep` plays), or one single-bot spec
        per seed, of one task ID, side by side (`play_pairs`: a spot-check's draws)."""
        if isinstance(task, tuple):
            return self._play_side_by_side(task, seeds)
        if isinstance(task, str):
            task = spec(task).with_height_scan(self.height_scan)
        if task not in self._envs:
            self.close()
        envs = self._envs.setdefault(task, [])
        lanes = 1 if task.multi_agent else len(seeds)
        while len(envs) < lanes:
            envs.append(self._make(task))
        rngs = [action_generator(seed) for seed in seeds] if self.sampled else None
        actor = self.actors[task.id]
        if task.multi_agent:
            return [
                MultiEpisode(envs[0], actor, seed, None if rngs is None else rngs[i]).play()
                for i, seed in enumerate(seeds)
            ]
        return Lockstep(envs[:lanes], actor, seeds, task.max_episode_steps, rngs).play()

    def _play_side_by_side(
        self, tasks: tuple[TaskSpec, ...], seeds: Sequence[int]
    ) -> list[PlayedEpisode]:
        """Lane i plays `seeds[i]` of `tasks[i]`, in an env of its own made for it: one actor
        for every lane (the specs share a task ID), each lane's episode its seed's alone."""
        self.close()
        envs = [self._make(task) for task in tasks]
        try:
            rngs = [action_generator(seed) for seed in seeds] if self.sampled else None
            limit = tasks[0].max_episode_steps
            return Lockstep(envs, self.actors[tasks[0].id], seeds, limit, rngs).play()
        finally:
            for env in envs:
                env.close()

    def worlds(self) -> dict[str, int]:
        """How many envs the runner keeps open, by task (those of one task at a time)."""
        return {task.id: len(envs) for task, envs in self._envs.items()}

    def _make(self, task: TaskSpec) -> Any:
        if task.multi_agent:
            return MultiBalanceEnv(task, action_mode=self.action_mode)
        # The env itself, without gymnasium's wrappers: the loop keeps the time limit.
        return BalanceEnv(task, action_mode=self.action_mode)

    def close(self) -> None:
        for envs in self._envs.values():
            for env in envs:
                env.close()
        self._envs.clear()

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_envs": {}}
