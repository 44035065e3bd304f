"""The suite: a registry of task IDs to specs, registered with gymnasium from it.

Each row is written beside its scenario (`bbbench.tasks.scenarios.solo`, `crossing`,
`beam_carry`, `convoy`: their `TASKS`), where it states all it sets; no row is made from
another. This module holds the registry and what reads it: `spec`, `list_tasks`,
`latest_version`, `agent_spaces`, and the gymnasium registration."""

from __future__ import annotations

import difflib
from typing import Any

import gymnasium
from gymnasium import spaces

from bbbench.tasks.scenarios import TASKS
from bbbench.tasks.spec import TaskSpec

SUITE: dict[str, TaskSpec] = {}
for _task in TASKS:  # each scenario's rows, beside it (`bbbench.tasks.scenarios`)
    if _task.id in SUITE:
        raise ValueError(f"{_task.id} is listed twice")
    SUITE[_task.id] = _task


def entry_point(task_id: str) -> str:
    """What plays a task: `bbbench.envs.task_envs.entry_point` every single-bot task (as
    the class made from its row), `MultiBalanceEnv` every multi-bot task."""
    if SUITE[task_id].multi_agent:
        return "bbbench.envs.multi:MultiBalanceEnv"
    return "bbbench.envs.task_envs:entry_point"


def register_suite() -> None:
    """Register every task of the suite with gymnasium (idempotent).

    Multi-bot tasks are PettingZoo environments, which `gymnasium.make` cannot
    build: their IDs are registered so that `gymnasium.make` says to use
    `bbbench.make_parallel` (or `bbbench.make_vec`) instead of "no such env".
    """
    for task in SUITE.values():
        if task.id in gymnasium.registry:
            continue
        if task.multi_agent:
            gymnasium.register(
                id=task.id, entry_point=not_a_gymnasium_env, kwargs={"task": task.id}
            )
            continue
        kwargs = {"task": task.id}
        if task.difficulty is not None:  # recorded in env.spec, default or not
            kwargs["difficulty"] = task.difficulty
        gymnasium.register(
            id=task.id,
            entry_point=entry_point(task.id),
            kwargs=kwargs,
            max_episode_steps=task.max_episode_steps,
        )


def not_a_gymnasium_env(task: str, **kwargs: Any) -> gymnasium.Env:
    """What `gymnasium.make` of a multi-bot task calls: an error that says what to use."""
    raise ValueError(multi_bot_hint(task))


def multi_bot_hint(task_id: str) -> str:
    return (
        f"{task_id} is a multi-bot (PettingZoo) task: make it with "
        f"bbbench.make_parallel({task_id!r}), or bbbench.make_vec for stable-baselines3"
    )


def list_tasks(multi_agent: bool | None = None, latest: bool = False) -> list[str]:
    """The IDs of the suite's tasks, sorted: all, or only multi-bot (True) or single-bot
    (False); with `latest`, only the newest version of each task (what the leaderboard
    ranks and `bbbench eval` plays unless told otherwise)."""
    return sorted(
        task_id
        for task_id, task in SUITE.items()
        if (multi_agent is None or task.multi_agent == multi_agent)
        and (not latest or latest_version(task_id) == task_id)
    )


def latest_version(task_id: str) -> str:
    """The newest version of `task_id`'s task: 'bbbench/Bumps-v2' for 'bbbench/Bumps-v0'."""
    name = spec(task_id).name
    return max((task for task in SUITE.values() if task.name == name), key=_version).id


def scored_version(trained: str) -> tuple[str, str]:
    """The version of a task a run trained on that the board scores (its latest), and
    what a table says of it: "" when it is the version trained on, else
    " (trained on vN)"."""
    on = latest_version(trained)
    return on, "" if on == trained else f" (trained on v{spec(trained).version})"


def _version(task: TaskSpec) -> int:
    return task.version


def spec(task_id: str) -> TaskSpec:
    """The frozen spec of a task; a clear error, naming the closest IDs, for an unknown one."""
    try:
        return SUITE[task_id]
    except (KeyError, TypeError):
        pass
    if isinstance(task_id, TaskSpec):  # a spec made in code, not an ID of the suite
        raise ValueError(
            f"give a task ID, not a TaskSpec ({task_id.id!r}): an env of a spec is "
            f"bbbench.envs.MultiBalanceEnv(spec) or BalanceEnv(spec)"
        )
    close = difflib.get_close_matches(str(task_id), list(SUITE), n=3, cutoff=0.5)
    if not close and isinstance(task_id, str):
        # "FlatBalance-v0" without the namespace, or any case.
        close = [known for known in SUITE if known.lower().endswith(task_id.lower())]
    hint = f" Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    raise ValueError(
        f"unknown task {task_id!r}.{hint} Known tasks: {', '.join(list_tasks())} "
        f"(see `bbbench list`)."
    )


def agent_spaces(
    task_id: str, action_mode: str, height_scan: bool = False
) -> tuple[spaces.Box, spaces.Space]:
    """The observation and action space of one bot of a task (every bot's, on a multi-bot
    task), without building the task's world: its scenario's, with the height scan if
    asked where the scenario scans the ground (`height_scan` is ignored elsewhere)."""
    task = spec(task_id)
    scenario = _scenario(task, height_scan)
    return scenario.observation_space(), task.action_space(action_mode)


def group_spaces(task_id: str) -> dict[str, tuple[spaces.Box, spaces.Space]]:
    """Each robot group's observation and action space (in the task's action mode) on a
    task, by robot: one entry, but on a mixed team (`TaskSpec.robot_groups`)."""
    task = spec(task_id)
    scenario = task.scenario_class(task)
    mode = task.default_action_mode
    return {
        group: (scenario.bot_observation_space(bots[0]), task.action_space(mode, bots[0]))
        for group, bots in task.robot_groups.items()
    }


def agent_layout(task_id: str, height_scan: bool = False) -> tuple[str, ...]:
    """The names of one bot's observation values on a task, in order: what its
    observation means, where `agent_spaces` gives only its width."""
    return tuple(field.name for field in _scenario(spec(task_id), height_scan).layout)


def _scenario(task: TaskSpec, height_scan: bool) -> Any:
    """The task's scenario, not built into a world: what it observes."""
    if task.scenario_class.scans_ground:
        task = task.with_height_scan(height_scan)
    return task.scenario_class(task)
