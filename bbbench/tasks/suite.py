"""The suite: a table of task IDs to specs, registered with gymnasium from that table."""

from __future__ import annotations

import difflib
from typing import Any

import gymnasium
from gymnasium import spaces
from pettingzoo import ParallelEnv

from bbbench.tasks.actions import action_space
from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.group import Group
from bbbench.tasks.observation import observation_space
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TaskSpec, parse_task_id
from bbbench.terrain import Bumps, HeightfieldTerrain, Obstacles

_VELOCITY_TARGETS = PiecewiseConstantVelocity(low=-1.0, high=1.0, hold=(2.0, 5.0))
# On terrain the bot must make progress across it: forward targets only.
_FORWARD_TARGETS = PiecewiseConstantVelocity(low=0.2, high=0.8, hold=(2.0, 5.0))

SUITE: dict[str, TaskSpec] = {
    spec.id: spec
    for spec in (
        TaskSpec(
            id="bbbench/FlatBalance-v0",
            summary="stay upright and in place on flat ground (the tutorial's task)",
            random_return=4.265516002827753,
        ),
        TaskSpec(
            id="bbbench/VelocityTracking-v0",
            summary="follow a target velocity in [-1, 1] m/s that changes every 2-5 s",
            random_return=1.2860367754813657,
            command=_VELOCITY_TARGETS,
        ),
        TaskSpec(
            id="bbbench/NoisySensors-v0",
            summary="velocity tracking with a biased, noisy IMU and encoders",
            random_return=1.2860367754813657,
            command=_VELOCITY_TARGETS,
            sensors=NoisySensors(),
        ),
        TaskSpec(
            id="bbbench/Bumps-v0",
            summary="drive forward at 0.2-0.8 m/s across smooth random hills",
            random_return=1.781347180609098,
            terrain=HeightfieldTerrain(generator=Bumps(), difficulty=0.3),
            command=_FORWARD_TARGETS,
        ),
        TaskSpec(
            id="bbbench/Obstacles-v0",
            summary="drive forward at 0.2-0.8 m/s over scattered boxes and steps",
            random_return=1.777879984692359,
            terrain=HeightfieldTerrain(generator=Obstacles(), difficulty=0.3),
            command=_FORWARD_TARGETS,
        ),
        TaskSpec(
            id="bbbench/MultiBalance-v0",
            summary="4 bots (2-16) whose paths cross on flat ground, each at 0.2-0.8 m/s",
            random_return=1.5245667657055884,
            command=_FORWARD_TARGETS,
            group=Group(),
        ),
        TaskSpec(
            id="bbbench/MultiBumps-v0",
            summary="4 bots (2-16) whose paths cross on smooth random hills",
            random_return=1.5233704486135895,
            terrain=HeightfieldTerrain(
                generator=Bumps(),
                difficulty=0.3,
                # A square around the spawn circle, level along it.
                size=(12.0, 12.0),
                start_margin=6.0,
                start_ring=Group().spawn_radius,
            ),
            command=_FORWARD_TARGETS,
            group=Group(),
        ),
    )
}


def task_name(task_id: str) -> str:
    """'Bumps' for 'bbbench/Bumps-v0': the task without namespace or version."""
    return parse_task_id(task_id)[1]


def entry_point(task_id: str) -> str:
    """The class that plays a task: one per single-bot task name (`bbbench/tasks/envs.py`),
    one for every multi-bot task (`bbbench/tasks/multi.py`)."""
    if SUITE[task_id].multi_agent:
        return "bbbench.tasks.multi:MultiBalanceEnv"
    return f"bbbench.tasks.envs:{task_name(task_id)}Env"


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
    raise ValueError(_multi_bot_hint(task))


def _multi_bot_hint(task_id: str) -> str:
    return (
        f"{task_id} is a multi-bot (PettingZoo) task: make it with "
        f"bbbench.make_parallel({task_id!r}), or bbbench.make_vec for stable-baselines3"
    )


def list_tasks(multi_agent: bool | None = None) -> list[str]:
    """The IDs of the suite's tasks, sorted: all, or only multi-bot (True) or single-bot (False)."""
    return sorted(
        task_id
        for task_id, task in SUITE.items()
        if multi_agent is None or task.multi_agent == multi_agent
    )


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


def agent_spaces(task_id: str, action_mode: str) -> tuple[spaces.Box, spaces.Space]:
    """The observation and action space of one bot of a task (every bot's, on a multi-bot
    task), without building the task."""
    task = spec(task_id)
    if task.group is None:
        return observation_space(), action_space(action_mode)
    from bbbench.tasks.multi import agent_observation_space

    return agent_observation_space(task.group), action_space(action_mode)


def make(task_id: str, **kwargs: Any) -> gymnasium.Env:
    """`gymnasium.make` for a single-bot task, with a clear error for an unknown ID."""
    if spec(task_id).multi_agent:
        raise ValueError(_multi_bot_hint(task_id))
    return gymnasium.make(task_id, **kwargs)


def make_parallel(task_id: str, **kwargs: Any) -> ParallelEnv:
    """A multi-bot task as a PettingZoo `ParallelEnv` (see `MultiBalanceEnv` for keywords)."""
    if not spec(task_id).multi_agent:
        raise ValueError(
            f"{task_id} is a single-bot task: make it with bbbench.make({task_id!r}) or "
            f"gymnasium.make; the multi-bot tasks are "
            f"{', '.join(list_tasks(multi_agent=True))}"
        )
    from bbbench.tasks.multi import MultiBalanceEnv

    return MultiBalanceEnv(task_id, **kwargs)
