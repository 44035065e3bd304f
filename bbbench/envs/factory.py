"""A task's env by ID: `make` (Gymnasium, single bot), `make_parallel` (PettingZoo,
several bots) and `make_batched` (many worlds of several bots, as arrays), each with a
clear error for the other kind of task or an unknown ID."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium

from bbbench.envs.batched import BatchedEnv
from bbbench.envs.multi import MultiBalanceEnv
from bbbench.tasks.suite import list_tasks, multi_bot_hint, spec


def make(task_id: str, max_episode_steps: int | None = None, **kwargs: Any) -> gymnasium.Env:
    """`gymnasium.make` for a single-bot task, with a clear error for an unknown ID.

    `max_episode_steps` sets the env's own time limit (the scene decides truncation) and
    Gymnasium's `TimeLimit` at the same step; `gymnasium.make`'s keyword of that name
    reaches its wrapper only, and so can shorten episodes but not lengthen them."""
    if spec(task_id).multi_agent:
        raise ValueError(multi_bot_hint(task_id))
    if max_episode_steps is None:
        return gymnasium.make(task_id, **kwargs)
    registered = gymnasium.spec(task_id)
    limited = dataclasses.replace(
        registered,
        max_episode_steps=max_episode_steps,
        kwargs={**registered.kwargs, "max_episode_steps": max_episode_steps},
    )
    return gymnasium.make(limited, **kwargs)


def make_parallel(task_id: str, **kwargs: Any) -> MultiBalanceEnv:
    """A multi-bot task as a PettingZoo `ParallelEnv` (see `MultiBalanceEnv` for keywords)."""
    if not spec(task_id).multi_agent:
        raise ValueError(
            f"{task_id} is a single-bot task: make it with bbbench.make({task_id!r}) or "
            f"gymnasium.make; the multi-bot tasks are "
            f"{', '.join(list_tasks(multi_agent=True))}"
        )
    return MultiBalanceEnv(task_id, **kwargs)


def make_batched(task_id: str, worlds: int = 1, workers: int = 1, **kwargs: Any) -> BatchedEnv:
    """`worlds` worlds of a multi-bot or team task stepped together, in `workers`
    processes (see `BatchedEnv`; keywords as `make_parallel`'s)."""
    return BatchedEnv(task_id, worlds=worlds, workers=workers, **kwargs)
