"""The results document: per-episode records and aggregates, in a versioned schema.

`docs/results-schema.json` is its JSON Schema. The document holds no
timestamps, host names or timings: the same policy file on the same seeds with
the same code gives the same bytes (`dumps`), on every machine but for its
`platform` block, which names the Python, numpy and pybullet build it ran on.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

import bbbench
from bbbench.evaluation import machine, stats
from bbbench.evaluation.episodes import PlayedEpisode
from bbbench.portable import total
from bbbench.tasks.spec import TaskSpec

# 2: the overall is the mean normalized score (every episode counts), where 1 took the
# IQM of the episodes' scores (a run's worst quarter, its falls, never counted). The
# episode records are the same: a document of either is read for its episodes.
SCHEMA = "bbbench-results/2"
EPISODES_OF = ("bbbench-results/1", SCHEMA)
# The version of the code that plays episodes (seeding, lockstep groups, actors): bump it
# when the same policy on the same task spec and seeds would play differently. The
# leaderboard reuses a stored task result only when it matches (with the policy's hash,
# the task's fingerprint and the seeds). 2: networks computed with `bbbench.portable` (each
# layer's output the float32 nearest the exact value, on every CPU), where 1 used numpy's
# `@` and `tanh` (which round by CPU). 3: a multi-bot episode plays as in a fresh world
# whatever its env played before (`Scene.reset`); under 2, an episode after one in which
# a bot was taken out could differ (1 of 8 PD episodes of MultiBumps-v1 in a row).
HARNESS_VERSION = 3


def normalized(value: float, task: TaskSpec) -> float | None:
    """0 for the random policy's mean return, 1 for the task's maximum return; None for a
    task without a stored random reference."""
    if task.random_return is None:
        return None
    return (value - task.random_return) / (task.max_return - task.random_return)


def aggregate(task: TaskSpec, episodes: Sequence[PlayedEpisode]) -> dict[str, Any]:
    """A task's aggregates over its (played) episodes."""
    if not episodes:
        return {"episodes": 0}
    returns = np.array([e.episode_return for e in episodes])
    mean_ci = stats.stratified_bootstrap_ci([returns], stats.mean)
    mean = stats.mean(returns)
    return {
        "episodes": len(episodes),
        "mean": mean,
        "std": float(returns.std(ddof=1)) if len(returns) > 1 else 0.0,
        "mean_ci": list(mean_ci),
        "iqm": stats.iqm(returns),
        "iqm_ci": list(stats.stratified_bootstrap_ci([returns], stats.iqm)),
        "success_rate": total(e.success for e in episodes) / len(episodes),
        "failures": total(e.failure is not None for e in episodes),
        **{  # the scenario's metrics, each the mean over episodes
            name: stats.mean([e.metrics[name] for e in episodes]) for name in episodes[0].metrics
        },
        "normalized_score": normalized(mean, task),
        "normalized_ci": (
            None if task.random_return is None else [normalized(b, task) for b in mean_ci]
        ),
    }


def overall(tasks: Sequence[TaskSpec], episodes: Sequence[Sequence[PlayedEpisode]]) -> dict:
    """Across tasks: the mean normalized score, every task weighed alike (the mean of
    each task's mean over its episodes, falls included), with its stratified-bootstrap
    interval."""
    strata = [
        np.array([normalized(e.episode_return, task) for e in played])
        for task, played in zip(tasks, episodes, strict=True)
        if played and task.random_return is not None
    ]
    if not strata:
        return {"tasks": 0}
    return {
        "tasks": len(strata),
        "normalized_score": float(np.mean([stratum.mean() for stratum in strata])),
        "normalized_ci": list(stats.stratified_bootstrap_ci(strata, _mean_of_tasks(strata))),
    }


def _mean_of_tasks(strata: Sequence[np.ndarray]):
    """The statistic over resampled strata laid side by side: the mean of the tasks' means
    (the strata may differ in size: a task with missing episodes)."""
    bounds = np.cumsum([0] + [len(stratum) for stratum in strata])

    def statistic(pooled: np.ndarray, axis: int = -1) -> np.ndarray:
        means = [pooled[..., a:b].mean(axis=-1) for a, b in itertools.pairwise(bounds)]
        return np.mean(means, axis=0)

    return statistic


def document(
    policy: dict[str, Any],
    tasks: Sequence[TaskSpec],
    seeds: Sequence[Sequence[int]],
    results: Sequence[Sequence[PlayedEpisode | None]],
    deterministic: bool,
    split: str = "evaluation",
) -> dict[str, Any]:
    """The whole results document; `results[i][j]` is task i's episode on `seeds[i][j]`,
    None if it is missing (its worker died twice); `split` names the tasks' seeds played
    (the validation seeds' documents say so: no board takes them)."""
    played = [[r for r in task_results if r is not None] for task_results in results]
    return {
        "schema": SCHEMA,
        "bbbench_version": bbbench.__version__,
        "harness_version": HARNESS_VERSION,
        "policy": policy,
        "deterministic": deterministic,
        # Only on validation seeds: documents of the evaluation seeds keep their bytes.
        **({"split": split} if split != "evaluation" else {}),
        "statistics": stats.method(),
        # Where it was made: the same bytes on every build but for this block.
        "platform": machine.record(),
        "tasks": [
            {
                "task": task.id,
                "version": task.version,
                "fingerprint": task.fingerprint,
                "bots": task.group.n_bots if task.group else 1,
                "max_return": task.max_return,
                "random_return": task.random_return,
                "seeds": list(task_seeds),
                "missing": [s for s, r in zip(task_seeds, rs, strict=True) if r is None],
                "aggregate": aggregate(task, ok),
                "episodes": [r.record() for r in ok],
                # Only when on: documents of blind policies keep their bytes.
                **({"height_scan": True} if task.height_scan else {}),
            }
            for task, task_seeds, rs, ok in zip(tasks, seeds, results, played, strict=True)
        ],
        "overall": overall(tasks, played),
    }


def dumps(results: dict[str, Any]) -> str:
    """The document as text: the same document, the same bytes."""
    return json.dumps(results, indent=2, allow_nan=False) + "\n"
