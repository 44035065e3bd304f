"""The suite: a table of task IDs to specs, registered with gymnasium from that table."""

from __future__ import annotations

import difflib
from typing import Any

import gymnasium

from bbbench.tasks.spec import TaskSpec

# Evaluation seeds are public and fixed per task version.
_EVAL_SEEDS = tuple(range(1_000_000, 1_000_100))

SUITE: dict[str, TaskSpec] = {
    spec.id: spec
    for spec in (
        TaskSpec(
            id="bbbench/FlatBalance-v0",
            summary="stay upright and in place on flat ground (the tutorial's task)",
            eval_seeds=_EVAL_SEEDS,
        ),
    )
}

_ENTRY_POINT = "bbbench.tasks.balance:BalanceEnv"


def register_suite() -> None:
    """Register every task of the suite with gymnasium (idempotent)."""
    for task in SUITE.values():
        if task.id in gymnasium.registry:
            continue
        gymnasium.register(
            id=task.id,
            entry_point=_ENTRY_POINT,
            kwargs={"task": task.id},
            max_episode_steps=task.max_episode_steps,
        )


def list_tasks() -> list[str]:
    """The IDs of every task in the suite, sorted."""
    return sorted(SUITE)


def spec(task_id: str) -> TaskSpec:
    """The frozen spec of a task; a clear error, naming the closest IDs, for an unknown one."""
    try:
        return SUITE[task_id]
    except (KeyError, TypeError):
        pass
    close = difflib.get_close_matches(str(task_id), list(SUITE), n=3, cutoff=0.5)
    if not close and isinstance(task_id, str):
        # "FlatBalance-v0" without the namespace, or any case.
        close = [known for known in SUITE if known.lower().endswith(task_id.lower())]
    hint = f" Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    raise ValueError(
        f"unknown task {task_id!r}.{hint} Known tasks: {', '.join(list_tasks())} "
        f"(see `bbbench list`)."
    )


def make(task_id: str, **kwargs: Any) -> gymnasium.Env:
    """`gymnasium.make` for a bbbench task, with a clear error for an unknown ID."""
    spec(task_id)
    return gymnasium.make(task_id, **kwargs)
