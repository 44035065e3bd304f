"""The training seeds a policy is evaluated on while it trains (never an eval seed)."""

from __future__ import annotations

import numpy as np

from bbbench.tasks.spec import TRAINING_SEEDS
from bbbench.tasks.suite import spec

# Bot-episodes per task at each evaluation during training (a world of 4 bots counts 4).
# The best of the evaluations is kept, so too few pick a lucky policy: with 10, PPO on
# Slopes-v2 kept one that averaged 68.5 on them and 47.9 on 30 evaluation seeds (PD: 51.5
# and 50.7).
EVALUATION_EPISODES = 50


def evaluation_seeds(task_id: str, count: int | None = None) -> list[int]:
    """The training seeds a policy is evaluated on while it trains: fixed, drawn from the
    task's name, and never one of its evaluation seeds. `count` defaults to
    `EVALUATION_EPISODES` bot-episodes' worth of the task's episodes."""
    task = spec(task_id)
    if count is None:
        count = max(EVALUATION_EPISODES // (task.group.n_bots if task.group else 1), 1)
    rng = np.random.default_rng(list(task_id.encode()))
    seeds = [int(s) for s in rng.integers(TRAINING_SEEDS.stop, size=count)]
    if set(task.eval_seeds).intersection(seeds):
        raise AssertionError(f"{task_id}: a training evaluation seed is an eval seed")
    return seeds
