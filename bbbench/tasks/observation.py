"""The observations of several bots in one world: each bot's own single-bot layout,
then what it sees of its nearest neighbours (`bbbench.envs.multi.MultiBalanceEnv`
documents the layout)."""

from __future__ import annotations

import numpy as np

from bbbench.robots import Robot
from bbbench.robots.layout import OBSERVATION_DTYPE, ObservationField
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE, Group, nearest_others


def neighbour_layout(group: Group) -> tuple[ObservationField, ...]:
    """The fields of a bot's neighbour block: its `group.neighbours` nearest others within
    `group.neighbour_range`, nearest first, 4 values each in the bot's own frame; a slot
    without a neighbour reads 0."""
    reach, top = group.neighbour_range, NEIGHBOUR_SPEED_RANGE
    return tuple(
        field
        for k in range(1, group.neighbours + 1)
        for field in (
            ObservationField(f"neighbour{k}_right", "m", -reach, reach,
                             f"the {_ordinal(k)} nearest other bot: how far to the right"),
            ObservationField(f"neighbour{k}_forward", "m", -reach, reach, "how far ahead"),
            ObservationField(f"neighbour{k}_right_velocity", "m/s", -top, top,
                             "its velocity minus this bot's, to the right"),
            ObservationField(f"neighbour{k}_forward_velocity", "m/s", -top, top,
                             "the same, ahead"),
        )
    )  # fmt: skip


def _ordinal(k: int) -> str:
    return {1: "1st", 2: "2nd", 3: "3rd"}.get(k, f"{k}th")


def group_observations(
    robot: Robot,
    states,
    commands: list[float],
    targets: list[float],
    group: Group,
    size: int,
    extras: list[tuple[float, ...]] | None = None,
    after: list[list[float]] | None = None,
    nearest: list[list[int]] | None = None,
    readings: list[tuple[float, float, float]] | None = None,
    positions: list[complex] | None = None,
) -> np.ndarray:
    """The observations of a group's live bots, one row of `size` values each: the robot's
    single-bot layout (`Robot.values`, from each bot's state, wheel command and target),
    then the bot's `extras` if given (a scenario's own fields, a tuple per bot), then its
    `group.neighbours` nearest others within `group.neighbour_range`, in its own frame
    (`bbbench.tasks.observation.neighbour_layout` names the slots; the task pages show them),
    then the bot's values `after` them if given (a channel's message block, a list per bot).
    `nearest`: each bot's others, nearest first (`nearest_others`), where the caller has
    them already (at least `group.neighbours` each where there are as many).
    `readings`: each bot's (pitch, pitch rate, wheel speed) as its sensors read them
    (`Scene.live_readings`); None, the true state's. `positions`: each bot's x + iy,
    where the caller has them.

    Plain Python floats and one numpy sort: at 2-16 bots, numpy's per-call cost would
    outweigh its arithmetic (benchmarks/bench_multi.py).
    """
    k, reach, top = group.neighbours, group.neighbour_range, NEIGHBOUR_SPEED_RANGE
    fill = [0.0] * size
    end = size - (len(after[0]) if after else 0)  # where the neighbour block ends
    if positions is None:
        positions = [complex(state.position[0], state.position[1]) for state in states]
    velocities = [complex(*state.velocity) for state in states]
    if nearest is None:
        nearest = nearest_others(positions, k)
    rows = []
    values = robot.values
    for i, state in enumerate(states):
        reading = (
            (state.pitch, state.pitch_rate, state.wheel_speed) if readings is None else readings[i]
        )
        row = [*values(reading, commands[i], targets[i], state)]
        if extras is not None:
            row += extras[i]
        here, velocity, (forward_x, forward_y) = positions[i], velocities[i], state.heading
        turn = complex(forward_y, forward_x)  # i * conj(heading): world -> right + i ahead
        for j in nearest[i][:k]:
            offset = (positions[j] - here) * turn
            if abs(offset) > reach:
                break  # the rest are farther
            moving = (velocities[j] - velocity) * turn
            right, ahead = moving.real, moving.imag  # saturated at the sensor's range:
            right = top if right > top else -top if right < -top else right
            ahead = top if ahead > top else -top if ahead < -top else ahead
            row += (offset.real, offset.imag, right, ahead)
        row += fill[len(row) : end]
        if after:
            row += after[i]
        rows.append(row)
    return np.array(rows, dtype=OBSERVATION_DTYPE).reshape(len(states), -1)
