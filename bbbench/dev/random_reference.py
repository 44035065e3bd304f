"""Measure the random policy's mean return on each task's eval seeds: the 0 of the
normalized score, stored in the suite as `TaskSpec.random_return`.

    bbbench dev random-reference

prints each task's measured value beside the stored one. tests/test_evaluation.py
checks they agree, so a stored reference cannot go stale.
"""

from __future__ import annotations

from bbbench.evaluation import evaluate
from bbbench.policies import load_policy
from bbbench.tasks.suite import list_tasks


def measure(task_ids: list[str] | None = None, workers: int | None = None) -> dict[str, float]:
    """The random policy's (discrete actions) mean return per bot over all eval seeds."""
    task_ids = task_ids or list_tasks()
    evaluation = evaluate(load_policy("random"), task_ids, workers=workers)
    return {task["task"]: task["aggregate"]["mean"] for task in evaluation.document["tasks"]}
