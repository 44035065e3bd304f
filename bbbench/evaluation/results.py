"""The results document: per-episode records and aggregates, in a versioned schema.

`docs/results-schema.json` is its JSON Schema. The document holds no
timestamps, host names or timings: the same policy file on the same seeds with
the same code gives the same bytes (`dumps`), on every machine but for its
`platform` block, which names the Python, numpy and pybullet build it ran on.

In memory a task's `episodes` are a list of records (`PlayedEpisode.record`); as text
they are a table, one row per episode under one list of columns (`dumps`, `loads`):
about a third of the bytes, and a changed episode is one changed line in a diff.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import bbbench
from bbbench.evaluation import machine, stats
from bbbench.evaluation.episodes import PlayedEpisode
from bbbench.portable import total
from bbbench.tasks.spec import TaskSpec

# 2: the overall is the mean normalized score (every episode counts), where 1 took the
# IQM of the episodes' scores (a run's worst quarter, its falls, never counted). 3: the
# text holds each task's episodes as a table (`dumps`), where 2 wrote one object per
# episode. The episode records are the same: a document of any is read for its episodes.
SCHEMA = "bbbench-results/3"
EPISODES_OF = ("bbbench-results/1", "bbbench-results/2", SCHEMA)
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


def dumps(document: dict[str, Any]) -> str:
    """A document as text (a results document, a profile, the board's): two-space
    indents, a list of plain values (seeds, an interval) on one line, and each list of
    episode records (a task's, a profile point's) as a table, `{"columns": [...], "rows":
    [...]}`, one row per line. The same document, the same bytes."""
    return _text(_tabled(document), "") + "\n"


def loads(text: str | bytes) -> dict[str, Any]:
    """A document `dumps` wrote, its episode tables read back as records; a document
    written before the tables (results 1 and 2, profile 1), as it is. `ValueError` for
    text that is not JSON, or a table whose rows do not fit its columns."""
    return _untabled(json.loads(text), "")


def read(path: Path) -> dict[str, Any]:
    """The document in the file at `path` (`loads`)."""
    return loads(path.read_bytes())


def _text(value: Any, indent: str) -> str:
    inner = indent + "  "
    if isinstance(value, dict) and value:
        items = (f"{inner}{json.dumps(key)}: {_text(item, inner)}" for key, item in value.items())
        return "{\n" + ",\n".join(items) + f"\n{indent}}}"
    if isinstance(value, list) and any(isinstance(item, dict | list) for item in value):
        return "[\n" + ",\n".join(inner + _text(item, inner) for item in value) + f"\n{indent}]"
    return json.dumps(value, allow_nan=False, separators=(",", ":"))


def _tabled(value: Any) -> Any:
    """`value` with each non-empty list of episode records under an "episodes" key laid
    out as a table: the columns in the order the records give them (a key only some
    records have, `cause`, is null in the others' rows)."""
    if isinstance(value, list):
        return [_tabled(item) for item in value]
    if not isinstance(value, dict):
        return value
    tabled = {key: _tabled(item) for key, item in value.items()}
    episodes = value.get("episodes")
    if isinstance(episodes, list) and episodes and all(isinstance(e, dict) for e in episodes):
        columns = list(dict.fromkeys(key for record in episodes for key in record))
        rows = [[record.get(column) for column in columns] for record in episodes]
        tabled["episodes"] = {"columns": columns, "rows": rows}
    return tabled


def _untabled(value: Any, where: str) -> Any:
    """`_tabled`'s inverse: a table's rows as records again, but for a null `cause`,
    which a record leaves out (`PlayedEpisode.record`)."""
    if isinstance(value, list):
        return [_untabled(item, f"{where}[{i}]") for i, item in enumerate(value)]
    if not isinstance(value, dict):
        return value
    plain = {
        key: _untabled(item, f"{where}.{key}" if where else key) for key, item in value.items()
    }
    table = value.get("episodes")
    if isinstance(table, dict):
        columns, rows = table.get("columns"), table.get("rows")
        if set(table) != {"columns", "rows"} or not isinstance(columns, list):
            raise ValueError(f"{where}.episodes: expected a table of columns and rows")
        if not isinstance(rows, list) or any(
            not isinstance(row, list) or len(row) != len(columns) for row in rows
        ):
            raise ValueError(
                f"{where}.episodes: expected rows of {len(columns)} values, one per column"
            )
        plain["episodes"] = [
            {
                column: item
                for column, item in zip(columns, row, strict=True)
                if not (column == "cause" and item is None)
            }
            for row in rows
        ]
    return plain
