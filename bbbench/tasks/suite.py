"""The suite: a table of task IDs to specs, registered with gymnasium from that table."""

from __future__ import annotations

import difflib
from typing import Any

import gymnasium

from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TaskSpec
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
        ),
        TaskSpec(
            id="bbbench/VelocityTracking-v0",
            summary="follow a target velocity in [-1, 1] m/s that changes every 2-5 s",
            command=_VELOCITY_TARGETS,
        ),
        TaskSpec(
            id="bbbench/NoisySensors-v0",
            summary="velocity tracking with a biased, noisy IMU and encoders",
            command=_VELOCITY_TARGETS,
            sensors=NoisySensors(),
        ),
        TaskSpec(
            id="bbbench/Bumps-v0",
            summary="drive forward at 0.2-0.8 m/s across smooth random hills",
            terrain=HeightfieldTerrain(generator=Bumps(), difficulty=0.3),
            command=_FORWARD_TARGETS,
        ),
        TaskSpec(
            id="bbbench/Obstacles-v0",
            summary="drive forward at 0.2-0.8 m/s over scattered boxes and steps",
            terrain=HeightfieldTerrain(generator=Obstacles(), difficulty=0.3),
            command=_FORWARD_TARGETS,
        ),
    )
}


def task_name(task_id: str) -> str:
    """'Bumps' for 'bbbench/Bumps-v0': the task without namespace or version."""
    return task_id.split("/", 1)[-1].rsplit("-v", 1)[0]


def entry_point(task_id: str) -> str:
    """The class that plays a task, one per task name (`bbbench/tasks/envs.py`)."""
    return f"bbbench.tasks.envs:{task_name(task_id)}Env"


def register_suite() -> None:
    """Register every task of the suite with gymnasium (idempotent)."""
    for task in SUITE.values():
        if task.id in gymnasium.registry:
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
