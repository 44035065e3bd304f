"""The suite: a table of task IDs to specs, registered with gymnasium from that table."""

from __future__ import annotations

import dataclasses
import difflib
from typing import Any

import gymnasium
from gymnasium import spaces

from bbbench.tasks.actions import action_space
from bbbench.tasks.commands import PiecewiseConstantVelocity
from bbbench.tasks.group import Group
from bbbench.tasks.observation import agent_observation_space, observation_space
from bbbench.tasks.reward import StayUpReward
from bbbench.tasks.sensors import NoisySensors
from bbbench.tasks.spec import TaskSpec
from bbbench.terrain import Bumps, HeightfieldTerrain, ObstacleCourse, Obstacles, Slopes

_VELOCITY_TARGETS = PiecewiseConstantVelocity(low=-1.0, high=1.0, hold=(2.0, 5.0))
# On terrain the bot must make progress across it: forward targets only.
_FORWARD_TARGETS = PiecewiseConstantVelocity(low=0.2, high=0.8, hold=(2.0, 5.0))
# The -v1 terrain is crossed at speed, 40-80% of the bot's 2.46 m/s top speed: at walking
# pace the PD baseline stalls against a bump or a step and rocks back, never falling
# (measured: no fall on hills of 45 degrees at 0.2-0.8 m/s); at speed the bot's momentum
# carries the torso over an obstacle that stops the wheels. On flat ground PD holds these
# speeds on every seed tested.
_SPEED_TARGETS = PiecewiseConstantVelocity(low=1.0, high=2.0, hold=(2.0, 5.0))
# m: the strip starts 1 m behind the bot and reaches 23 m ahead: the PD baseline got at
# most 16.5 m along it in 60 episodes (terrain holds it back from the 22 m its targets
# ask for on average); past the end lies flat ground. Each node costs about 0.7 us when a
# new terrain replaces the old after an episode, so the strip is no longer than that and
# narrow (a reset <= 20 ms). The bot cannot steer: kicked by a bump it turns, and drifted
# 2 m sideways in half the PD episodes (14 m in one in ten). So the terrain repeats
# across with a 1.2 m period and the field follows the bot by whole periods: narrow and
# cheap, yet without a side edge to leave by.
_V1_STRIP = dict(size=(2.4, 24.0), start_margin=1.0, lateral_period=1.2)
# m: a heightfield joins nodes by ramps one cell long: at 0.2 m cells a 6 cm step is a
# 17 degree ramp that no wheel hits. At 0.05 m it is a face of 50 degrees.
_V1_FINE_CELLS = 0.05

_PUBLISHED = (
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
        id="bbbench/Bumps-v1",
        summary="cross short, steep random hills (up to ~21 deg) at 1-2 m/s",
        random_return=-5.935016249898391,
        terrain=HeightfieldTerrain(
            generator=Bumps(min_height=0.01, extra_height=0.10, feature_size=0.1),
            difficulty=0.9,
            **_V1_STRIP,
            cell_size=_V1_FINE_CELLS,
        ),
        command=_SPEED_TARGETS,
        version_history=(
            "v0: initial release.",
            "v1: terrain with headroom (on v0's hills, up to 0.08 m at 0.2-0.8 m/s, "
            "PD never fell): short hills (0.1 m features) up to 0.11 m and ~23 deg "
            "at difficulty 1, on 0.05 m cells, crossed at 1-2 m/s on a strip that "
            "repeats across (no side edge); default difficulty 0.9, where PD "
            "finishes 37% of the evaluation episodes.",
        ),
    ),
    TaskSpec(
        id="bbbench/Obstacles-v1",
        summary="cross boxes and steps (up to 6 cm) with shrinking gaps at 1-2 m/s",
        random_return=-5.9759097239538495,
        terrain=HeightfieldTerrain(
            generator=ObstacleCourse(),
            difficulty=0.5,
            **_V1_STRIP,
            cell_size=_V1_FINE_CELLS,
        ),
        command=_SPEED_TARGETS,
        version_history=(
            "v0: initial release.",
            "v1: terrain with headroom (v0's boxes and steps, up to 0.05 m on 0.2 m "
            "cells, were one-cell ramps at 0.2-0.8 m/s, and PD never fell): an "
            "obstacle course of boxes and full-width steps up to 0.06 m (0.6x the "
            "wheel radius) on 0.05 m cells, gaps shrinking to 0.3 m at difficulty 1, "
            "crossed at 1-2 m/s on a strip that repeats across (no side edge); "
            "default difficulty 0.5, where PD finishes 36% of the evaluation episodes.",
        ),
    ),
    TaskSpec(
        id="bbbench/Slopes-v1",
        summary="climb and descend ramps (up to ~26 deg) at 1-2 m/s",
        random_return=-5.9305729273501235,
        terrain=HeightfieldTerrain(
            generator=Slopes(
                min_incline=0.0, extra_incline=0.5, max_height=2.0, ramp_length=(0.3, 1.5)
            ),
            difficulty=0.9,
            size=(3.2, 32.0),
            start_margin=1.0,
            lateral_period=1.6,
            cell_size=0.1,
        ),
        command=_SPEED_TARGETS,
        version_history=(
            "v1: initial release, with the -v1 terrain tasks (there is no v0): ramps "
            "0.3-1.5 m long up to 0.5 rad (29 deg) at difficulty 1, within 0-2 m of "
            "height, on 0.1 m cells, climbed and descended at 1-2 m/s; default "
            "difficulty 0.9 (26 deg), where PD finishes 55% of the evaluation episodes.",
        ),
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


def _staying_up_never_costs(task: TaskSpec, version: int, random_return: float) -> TaskSpec:
    """`task` as version `version`: the same robot, dynamics, terrain, commands, sensors and
    evaluation seeds, scored by the shared reward in which staying up never costs."""
    name = task.id.rsplit("-v", 1)[0]
    change = (
        f"v{version}: the shared reward in which staying up never costs (StayUpReward: each "
        f"step earns 0-0.1, 0.01 for being upright and up to 0.09 more for tracking the "
        f"target velocity; docs/tasks.md says why); robot, dynamics, terrain, commands, "
        f"sensors and evaluation seeds as v{task.version}."
    )
    return dataclasses.replace(
        task,
        id=f"{name}-v{version}",
        reward=StayUpReward(),
        version_history=(*task.version_history, change),
        random_return=random_return,
    )


# Every task's latest version: the published ones re-scored by the new shared reward
# (`bbbench.tasks.reward`). The earlier versions stay registered, unchanged.
_STAY_UP = (
    ("bbbench/FlatBalance-v0", 1, 4.932770048552165),
    ("bbbench/VelocityTracking-v0", 1, 2.1504693078292174),
    ("bbbench/NoisySensors-v0", 1, 2.1504693078292174),
    ("bbbench/Bumps-v1", 2, 0.773599543444995),
    ("bbbench/Obstacles-v1", 2, 0.774324478721841),
    ("bbbench/Slopes-v1", 2, 0.7804649229704179),
    ("bbbench/MultiBalance-v0", 1, 1.72400817656264),
    ("bbbench/MultiBumps-v0", 1, 1.7237354574632304),
)

SUITE: dict[str, TaskSpec] = {spec.id: spec for spec in _PUBLISHED}
SUITE.update(
    (new.id, new)
    for new in (
        _staying_up_never_costs(SUITE[task_id], version, random_return)
        for task_id, version, random_return in _STAY_UP
    )
)


def entry_point(task_id: str) -> str:
    """The class that plays a task: one per single-bot task name (`bbbench/envs/tasks.py`),
    one for every multi-bot task (`bbbench/envs/multi.py`)."""
    if SUITE[task_id].multi_agent:
        return "bbbench.envs.multi:MultiBalanceEnv"
    return f"bbbench.envs.tasks:{SUITE[task_id].name}Env"


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


def _version(task: TaskSpec) -> int:
    return task.version


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


def agent_spaces(
    task_id: str, action_mode: str, height_scan: bool = False
) -> tuple[spaces.Box, spaces.Space]:
    """The observation and action space of one bot of a task (every bot's, on a multi-bot
    task, which has no height scan), without building the task."""
    task = spec(task_id)
    if task.group is None:
        return observation_space(height_scan), action_space(action_mode)
    return agent_observation_space(task.group), action_space(action_mode)
