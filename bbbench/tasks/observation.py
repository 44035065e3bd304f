"""The observation layout shared by every single-bot task.

One policy can be evaluated on every task of the suite because every task
returns the same vector, in the same order, with the same bounds. Readings a
real robot's sensors would saturate are clipped to the sensor's range, so the
bounds are honest: no observation ever leaves them.

With `height_scan=True` the vector goes on with `SCAN_POINTS` ground heights
ahead of the bot (`HEIGHT_SCAN_LAYOUT`): an option, off by default, so that the
blind layout stays the one every policy can play.
"""

from __future__ import annotations

import math
from itertools import chain
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from bbbench.robots import MODEL
from bbbench.tasks.group import NEIGHBOUR_SPEED_RANGE, Group, nearest_others

OBSERVATION_DTYPE = np.float32

GYRO_RANGE = math.radians(2000.0)  # rad/s: a common MEMS gyro's full scale
ENCODER_SPEED_RANGE = 50.0  # rad/s: about twice the motors' top speed


class ObservationField(NamedTuple):
    name: str
    unit: str
    low: float
    high: float
    meaning: str


OBSERVATION_LAYOUT = (
    ObservationField("pitch", "rad", -math.pi, math.pi, "torso lean from vertical, + forward"),
    ObservationField(
        "pitch_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "gyro rate about the axle, + forward"
    ),
    ObservationField(
        "wheel_speed",
        "rad/s",
        -ENCODER_SPEED_RANGE,
        ENCODER_SPEED_RANGE,
        "measured wheel speed relative to the torso (encoders), + forward",
    ),
    ObservationField(
        "wheel_command",
        "rad/s",
        -MODEL.wheel_speed_limit,
        MODEL.wheel_speed_limit,
        "wheel speed the servos are commanded to hold",
    ),
    ObservationField(
        "target_velocity",
        "m/s",
        -MODEL.top_speed,
        MODEL.top_speed,
        "forward velocity the task asks for",
    ),
)
INDEX = {field.name: i for i, field in enumerate(OBSERVATION_LAYOUT)}
_OBSERVATION_SIZE = len(OBSERVATION_LAYOUT)
_PI = math.pi

# The height scan: ground heights at SCAN_POINTS points along the bot's heading,
# SCAN_SPACING m apart from below the axle (0 m) to 1 m ahead, relative to the axle's
# height (flat ground reads minus the wheel radius). 1 m is half a second at the
# fastest target, 2 m/s; 0.1 m is two cells of the finest terrain.
SCAN_POINTS = 11
SCAN_SPACING = 0.1  # m
SCAN_OFFSETS = tuple(SCAN_SPACING * k for k in range(SCAN_POINTS))  # m ahead of the axle
SCAN_RANGE = 3.0  # m: readings are clipped to +-SCAN_RANGE (terrain spans at most 2 m)

HEIGHT_SCAN_LAYOUT = tuple(
    ObservationField(
        f"height_scan_{k}",
        "m",
        -SCAN_RANGE,
        SCAN_RANGE,
        f"ground height {offset:.1f} m ahead, relative to the axle",
    )
    for k, offset in enumerate(SCAN_OFFSETS)
)


def layout(height_scan: bool = False) -> tuple[ObservationField, ...]:
    """The fields of the observation, in order: the shared layout, then the scan if asked."""
    return OBSERVATION_LAYOUT + HEIGHT_SCAN_LAYOUT if height_scan else OBSERVATION_LAYOUT


def observation_space(height_scan: bool = False) -> spaces.Box:
    """The Box every single-bot task observes in (with the height scan: a longer one)."""
    fields = layout(height_scan)
    return spaces.Box(
        low=np.array([field.low for field in fields], dtype=OBSERVATION_DTYPE),
        high=np.array([field.high for field in fields], dtype=OBSERVATION_DTYPE),
        dtype=OBSERVATION_DTYPE,
    )


def observe(
    pitch: float, pitch_rate: float, wheel_speed: float, wheel_command: float, target: float
) -> np.ndarray:
    """The observation vector of one bot, in `OBSERVATION_LAYOUT` order.

    Sensed readings (true or noisy) are clipped to their sensors' ranges;
    `wheel_command` and `target` are within bounds by construction (the bot
    clamps its command; specs bound their targets).
    """
    # fromiter with a known count skips numpy's type and shape discovery (bench/).
    return np.fromiter(
        (
            _PI if pitch > _PI else max(pitch, -_PI),
            GYRO_RANGE if pitch_rate > GYRO_RANGE else max(pitch_rate, -GYRO_RANGE),
            ENCODER_SPEED_RANGE
            if wheel_speed > ENCODER_SPEED_RANGE
            else max(wheel_speed, -ENCODER_SPEED_RANGE),
            wheel_command,
            target,
        ),
        OBSERVATION_DTYPE,
        _OBSERVATION_SIZE,
    )


def sensed(pitch: float, pitch_rate: float, wheel_speed: float) -> tuple[float, float, float]:
    """The three sensed readings clipped as `observe` clips them, as Python floats.

    For callers that build many observations at once (the multi-bot env);
    tests/test_multi.py checks that the two agree.
    """
    return (
        _PI if pitch > _PI else max(pitch, -_PI),
        GYRO_RANGE if pitch_rate > GYRO_RANGE else max(pitch_rate, -GYRO_RANGE),
        ENCODER_SPEED_RANGE
        if wheel_speed > ENCODER_SPEED_RANGE
        else max(wheel_speed, -ENCODER_SPEED_RANGE),
    )


def observe_scanned(
    pitch: float,
    pitch_rate: float,
    wheel_speed: float,
    wheel_command: float,
    target: float,
    scan: list[float],
) -> np.ndarray:
    """`observe`'s vector followed by the height scan (m), clipped to +-SCAN_RANGE: one array,
    built in one call (it runs every step of a height-scan task; bench/bench_suite.py)."""
    if not -SCAN_RANGE <= min(scan) <= max(scan) <= SCAN_RANGE:  # rare: a deep drop ahead
        scan = [SCAN_RANGE if h > SCAN_RANGE else max(h, -SCAN_RANGE) for h in scan]
    return np.fromiter(
        chain(sensed(pitch, pitch_rate, wheel_speed), (wheel_command, target), scan),
        OBSERVATION_DTYPE,
        _OBSERVATION_SIZE + len(scan),
    )


def agent_observation_space(group: Group) -> spaces.Box:
    """One bot's observation space in a multi-bot task: the single-bot layout, then its
    neighbours' (`Group.bounds`)."""
    single = observation_space()
    low, high = group.bounds()
    return spaces.Box(
        low=np.concatenate([single.low, low]).astype(OBSERVATION_DTYPE),
        high=np.concatenate([single.high, high]).astype(OBSERVATION_DTYPE),
        dtype=OBSERVATION_DTYPE,
    )


def group_observations(
    states, commands: list[float], targets: list[float], group: Group, size: int
) -> np.ndarray:
    """The observations of a group's live bots, one row of `size` values each: the
    single-bot layout (from each bot's state, wheel command and target), then its
    `group.neighbours` nearest others within `group.neighbour_range`, in its own frame
    (`bbbench.envs.multi.MultiBalanceEnv` documents the layout).

    Plain Python floats and one numpy sort: at 2-16 bots, numpy's per-call cost would
    outweigh its arithmetic (bench/bench_multi.py).
    """
    k, reach, top = group.neighbours, group.neighbour_range, NEIGHBOUR_SPEED_RANGE
    fill = [0.0] * size
    positions = [complex(state.position[0], state.position[1]) for state in states]
    velocities = [complex(*state.velocity) for state in states]
    nearest = nearest_others(positions, k)
    rows = []
    for i, state in enumerate(states):
        row = [*sensed(state.pitch, state.pitch_rate, state.wheel_speed), commands[i], targets[i]]
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
