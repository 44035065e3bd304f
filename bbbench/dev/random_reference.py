"""Measure the random policy's mean return on each task's eval seeds: the 0 of the
normalized score, stored in the suite as `TaskSpec.random_return`.

    bbbench dev random-reference

prints each task's measured value beside the stored one. tests/test_evaluation.py
checks they agree, so a stored reference cannot go stale.
"""

from __future__ import annotations

from bbbench.evaluation import evaluate
from bbbench.policies import load_policy
from bbbench.tasks.suite import list_tasks, spec


def measure(task_ids: list[str] | None = None, workers: int | None = None) -> dict[str, float]:
    """The random policy's mean return per bot over all eval seeds, acting in each task's
    default action mode (discrete for the two-wheel bot, continuous for a mixed team)."""
    by_mode: dict[str, list[str]] = {}
    for task_id in task_ids or list_tasks():
        by_mode.setdefault(spec(task_id).default_action_mode, []).append(task_id)
    measured = {}
    for action_mode, tasks in by_mode.items():
        policy = load_policy("random", action_mode=action_mode)
        evaluation = evaluate(policy, tasks, workers=workers)
        measured.update(
            (task["task"], task["aggregate"]["mean"]) for task in evaluation.document["tasks"]
        )
    return measured
