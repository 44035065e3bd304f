"""`sweep`: policies' evaluation episodes at each value of one axis, through the harness.

An axis is a perturbation (`bbbench.tasks.perturbations`: `payload_mass`, `push`, ...),
`difficulty` on terrain tasks or `n_bots` on multi-bot tasks. Each (value, task) pair is
the task's spec with that value, played on the same evaluation seeds by the harness's
own player (`play_tasks`: workers, Ray, lockstep, safe loading), all pairs of a policy on
one pool of workers. Per pair the document holds the aggregate block of the results
document; per (policy, task) the robustness score, the mean normalized score over the
values, and the worst case, their minimum (RRLS's two figures), which are the profile's
when the values are the axis's standard grid.

from bbbench.evaluation.sweep import sweep
from bbbench.policies import load_policy

document = sweep([load_policy("pd")], "push", task_ids=["bbbench/VelocityTracking-v1"])
document["policies"][0]["tasks"][0]["robustness"]
"""

from __future__ import annotations

import difflib
import operator
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

import bbbench
from bbbench.evaluation import stats
from bbbench.evaluation.harness import play_tasks
from bbbench.evaluation.play import PlayedEpisode
from bbbench.evaluation.results import HARNESS_VERSION, aggregate
from bbbench.policies.policy import Policy
from bbbench.tasks.group import MAX_BOTS, MIN_BOTS
from bbbench.tasks.perturbations import PERTURBATIONS, refusal
from bbbench.tasks.perturbations import unit as perturbation_unit
from bbbench.tasks.spec import TaskSpec
from bbbench.tasks.suite import list_tasks, spec

SCHEMA = "bbbench-sweep/1"
# The standard grids of the two axes that are not perturbations.
DIFFICULTY_GRID = (0.0, 0.25, 0.5, 0.75, 1.0)
N_BOTS_GRID = (2, 4, 8, 16)
AXES = (*PERTURBATIONS, "difficulty", "n_bots")


def check_axis(axis: str) -> str:
    """`axis`, or a ValueError that names the closest axis and lists them all."""
    if axis in AXES:
        return axis
    closest = difflib.get_close_matches(axis, AXES, n=1, cutoff=0.5)
    hint = f"did you mean {closest[0]!r}? " if closest else ""
    raise ValueError(f"unknown axis {axis!r}: {hint}the axes are {', '.join(AXES)}")


def standard_grid(axis: str, task_ids: Sequence[str] = ()) -> tuple[float, ...]:
    """The values the robustness profile plays on `axis`; on `n_bots`, those every one of
    `task_ids` takes (a team takes 2 to 4 bots, Swap-v0 2 to 8)."""
    if axis == "difficulty":
        return DIFFICULTY_GRID
    if axis == "n_bots":
        most = min((most_bots(spec(task_id)) for task_id in task_ids), default=MAX_BOTS)
        return tuple(value for value in N_BOTS_GRID if value <= most)
    return PERTURBATIONS[check_axis(axis)].grid


def most_bots(task: TaskSpec) -> int:
    """The most bots a multi-bot task's world takes: its scenario's limit, or the suite's."""
    return task.scenario_class.most_bots or MAX_BOTS


def unit(axis: str, task_ids: Sequence[str] = ()) -> str:
    """The unit of `axis`'s values on the tasks `task_ids` (both, where they differ)."""
    if axis == "difficulty":
        return "terrain difficulty, 0 to 1"
    if axis == "n_bots":
        return "bots in the world"
    units = [perturbation_unit(axis, spec(task_id)) for task_id in task_ids]
    return " or ".join(dict.fromkeys(units)) or PERTURBATIONS[axis].unit


def whole(axis: str) -> bool:
    """Whether the axis counts (steps, bots): its values are whole numbers."""
    return axis == "n_bots" or (PERTURBATIONS.get(axis) is not None and PERTURBATIONS[axis].whole)


def parse_values(axis: str, text: str) -> list[float]:
    """'0,0.5,1' as the axis's values, or a ValueError that says what is expected."""
    values = []
    for item in text.split(","):
        try:
            if "_" in item:  # float() reads '1_0' as 10: a typo, not a number
                raise ValueError(item)
            value = float(item)
        except ValueError:
            raise ValueError(
                f"--values {text!r}: {item.strip()!r} is not a number; give numbers separated "
                f"by commas, e.g. {','.join(f'{v:g}' for v in standard_grid(axis))}"
            ) from None
        if whole(axis):
            if value != int(value):
                raise ValueError(f"{axis} is a whole number ({unit(axis)}), got {item.strip()}")
            value = int(value)
        values.append(value)
    if len(set(values)) != len(values):
        raise ValueError(f"--values {text!r}: a value is given twice")
    return sorted(values)


def variant(task: TaskSpec, axis: str, value: float) -> TaskSpec:
    """`task` with `value` on `axis`, or a ValueError: the axis does not apply to it, or
    the value lies outside the parameter's physical range."""
    if axis == "difficulty":
        if task.difficulty is None:
            raise ValueError(
                f"difficulty does not apply to {task.id}: it is on flat ground (the terrain "
                f"tasks: {', '.join(applying_tasks(axis))})"
            )
        return task.with_difficulty(value)
    if axis == "n_bots":
        if not task.multi_agent:
            raise ValueError(
                f"n_bots does not apply to {task.id}: it has one bot (the multi-bot tasks: "
                f"{', '.join(applying_tasks(axis))})"
            )
        if not MIN_BOTS <= value <= MAX_BOTS:
            raise ValueError(f"n_bots must be from {MIN_BOTS} to {MAX_BOTS}, got {value}")
        return task.with_n_bots(operator.index(value))
    reason = refusal(check_axis(axis), task)
    if reason:
        raise ValueError(reason)
    return task.with_perturbation(PERTURBATIONS[axis](value))


def applying_tasks(axis: str) -> list[str]:
    """The latest tasks of the suite that `axis` applies to."""
    check_axis(axis)
    latest = [spec(task_id) for task_id in list_tasks(latest=True)]
    if axis == "difficulty":
        return [task.id for task in latest if task.difficulty is not None]
    if axis == "n_bots":  # every multi-bot task, each on the grid values it takes
        return [task.id for task in latest if task.multi_agent]
    return [task.id for task in latest if refusal(axis, task) is None]


def sweep_tasks(
    task_ids: Sequence[str], axis: str, values: Sequence[float], height_scan: bool = False
) -> list[TaskSpec]:
    """Every (value, task) pair's spec, value by value: checks every pair before any
    episode is played."""
    tasks = [spec(task_id).with_height_scan(height_scan) for task_id in task_ids]
    return [variant(task, axis, value) for value in values for task in tasks]


def sweep(
    policies: Sequence[Policy],
    axis: str,
    values: Sequence[float] | None = None,
    task_ids: Sequence[str] = ("bbbench/VelocityTracking-v1",),
    episodes: int | None = None,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    on_result: Callable[[int, list[PlayedEpisode] | None], None] | None = None,
) -> dict[str, Any]:
    """Each policy's first `episodes` eval seeds (default: all) of each task at each value
    of `axis` (default: its standard grid), as the sweep document (deterministic actions).
    `on_result(n, results)` is called as each group of n episodes ends."""
    axis = check_axis(axis)
    values = list(standard_grid(axis, task_ids) if values is None else values)
    entries = []
    for policy in policies:
        tasks = sweep_tasks(task_ids, axis, values, policy.height_scan)
        played = play_tasks(policy, tasks, episodes, workers, backend, address, False, on_result)
        by_pair = iter(zip(tasks, played.episodes, strict=True))
        points: dict[str, list[dict[str, Any]]] = {task_id: [] for task_id in task_ids}
        for value in values:
            for task_id in task_ids:
                task, results = next(by_pair)
                points[task_id].append(_point(task, value, results))
        entries.append(
            {
                "policy": policy.record(),
                "tasks": [
                    {"task": spec(task_id).id, "points": rows, "robustness": robustness(rows)}
                    for task_id, rows in points.items()
                ],
            }
        )
    return {
        "schema": SCHEMA,
        "bbbench_version": bbbench.__version__,
        "harness_version": HARNESS_VERSION,
        "axis": axis,
        "unit": unit(axis, task_ids),
        "values": values,
        "standard_grid": tuple(values) == tuple(standard_grid(axis, task_ids)),
        "deterministic": True,
        "statistics": stats.method(),
        "policies": entries,
    }


def _point(task: TaskSpec, value: float, results: list[PlayedEpisode | None]) -> dict[str, Any]:
    seeds = task.eval_seeds[: len(results)]
    return {
        "value": value,
        "fingerprint": task.fingerprint,
        "seeds": [seeds[0], seeds[-1]],  # the first and last: they run in a row
        "missing": [s for s, r in zip(seeds, results, strict=True) if r is None],
        "aggregate": aggregate(task, [r for r in results if r is not None]),
    }


def robustness(points: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """The mean normalized score over the points, and the worst point; None for a task
    without a random reference (no normalized score)."""
    scores = [point["aggregate"].get("normalized_score") for point in points]
    if any(score is None for score in scores):
        return None
    worst = int(np.argmin(scores))
    return {
        "score": float(np.mean(scores)),
        "worst_case": scores[worst],
        "worst_value": points[worst]["value"],
    }
