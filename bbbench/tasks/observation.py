"""The observations of several bots in one world: each bot's own single-bot layout,
then what it sees of its nearest neighbours (`bbbench.envs.multi.MultiBalanceEnv`
documents the layout)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from bbbench.robots import Robot
from bbbench.robots.layout import OBSERVATION_DTYPE
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE, Group, nearest_others


def agent_observation_space(robot: Robot, group: Group) -> spaces.Box:
    """One bot's observation space in a multi-bot task: the robot's single-bot layout,
    then its neighbours' (`Group.bounds`)."""
    single = robot.observation_space()
    low, high = group.bounds()
    return spaces.Box(
        low=np.concatenate([single.low, low]).astype(OBSERVATION_DTYPE),
        high=np.concatenate([single.high, high]).astype(OBSERVATION_DTYPE),
        dtype=OBSERVATION_DTYPE,
    )


def group_observations(
    robot: Robot,
    states,
    commands: list[float],
    targets: list[float],
    group: Group,
    size: int,
    extras: list[tuple[float, ...]] | None = None,
) -> np.ndarray:
    """The observations of a group's live bots, one row of `size` values each: the robot's
    single-bot layout (`Robot.values`, from each bot's state, wheel command and target),
    then the bot's `extras` if given (a scenario's own fields, a tuple per bot), then its
    `group.neighbours` nearest others within `group.neighbour_range`, in its own frame
    (`bbbench.envs.multi.MultiBalanceEnv` documents the layout).

    Plain Python floats and one numpy sort: at 2-16 bots, numpy's per-call cost would
    outweigh its arithmetic (benchmarks/bench_multi.py).
    """
    k, reach, top = group.neighbours, group.neighbour_range, NEIGHBOUR_SPEED_RANGE
    fill = [0.0] * size
    positions = [complex(state.position[0], state.position[1]) for state in states]
    velocities = [complex(*state.velocity) for state in states]
    nearest = nearest_others(positions, k)
    rows = []
    values = robot.values
    for i, state in enumerate(states):
        reading = (state.pitch, state.pitch_rate, state.wheel_speed)
        row = [*values(reading, commands[i], targets[i], state)]
        if extras is not None:
            row += extras[i]
        here, velocity, (forward_x, forward_y) = positions[i], velocities[i], state.heading
        turn = complex(forward_y, forward_x)  # i * conj(heading): world -> right + i ahead
        for j in nearest[i]:
            offset = (positions[j] - here) * turn
            if abs(offset) > reach:
                break  # the rest are farther
            moving = (velocities[j] - velocity) * turn
            right, ahead = moving.real, moving.imag  # saturated at the sensor's range:
            right = top if right > top else -top if right < -top else right
            ahead = top if ahead > top else -top if ahead < -top else ahead
            row += (offset.real, offset.imag, right, ahead)
        row += fill[len(row) :]
        rows.append(row)
    return np.array(rows, dtype=OBSERVATION_DTYPE).reshape(len(states), -1)
