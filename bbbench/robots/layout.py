"""The observation layout every robot's single-bot tasks begin with, and its pieces.

One policy can be evaluated on every task of a robot because every task returns
the same vector, in the same order, with the same bounds; and every robot's vector
begins with the same five values (`shared_layout`), so that a controller of the
shared values reads any robot's observation. A robot with more to say (joint
angles, roll) appends its fields after them (`bbbench.robots.robot.Robot.layout`).
Readings a real robot's sensors would saturate are clipped to the sensor's range,
so the bounds are honest: no observation ever leaves them.

With `height_scan=True` the vector goes on with `SCAN_POINTS` ground heights
ahead of the bot (`HEIGHT_SCAN_LAYOUT`): an option, off by default, so that the
blind layout stays the one every policy can play.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import chain
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

OBSERVATION_DTYPE = np.float32

GYRO_RANGE = math.radians(2000.0)  # rad/s: a common MEMS gyro's full scale
ENCODER_SPEED_RANGE = 50.0  # rad/s: about twice the motors' top speed


class ObservationField(NamedTuple):
    name: str
    unit: str
    low: float
    high: float
    meaning: str


def shared_layout(wheel_speed_limit: float, top_speed: float) -> tuple[ObservationField, ...]:
    """The five values every robot's observation begins with, bounded by its wheels'
    speed limit (rad/s) and its top speed (m/s)."""
    return (
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
            -wheel_speed_limit,
            wheel_speed_limit,
            "wheel speed the servos are commanded to hold",
        ),
        ObservationField(
            "target_velocity", "m/s", -top_speed, top_speed, "forward velocity the task asks for"
        ),
    )


SHARED_FIELDS = ("pitch", "pitch_rate", "wheel_speed", "wheel_command", "target_velocity")
INDEX = {name: i for i, name in enumerate(SHARED_FIELDS)}  # the same place for every robot
_OBSERVATION_SIZE = len(SHARED_FIELDS)
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


def fields_markdown(fields: Sequence[ObservationField]) -> str:
    """`fields` as a Markdown table (Num, Observation, Min, Max, Unit, Meaning): the
    robots' docstrings and the site's task pages print their layouts with it."""
    rows = (
        f"| {i} | {field.name} | {field.low:.5g} | {field.high:.5g} | {field.unit} | "
        f"{field.meaning} |"
        for i, field in enumerate(fields)
    )
    return "\n".join(
        (
            "| Num | Observation | Min | Max | Unit | Meaning |",
            "|-----|-------------|-----|-----|------|---------|",
            *rows,
        )
    )


def box(fields: tuple[ObservationField, ...]) -> spaces.Box:
    """The Box of an observation made of `fields`, in order."""
    return spaces.Box(
        low=np.array([field.low for field in fields], dtype=OBSERVATION_DTYPE),
        high=np.array([field.high for field in fields], dtype=OBSERVATION_DTYPE),
        dtype=OBSERVATION_DTYPE,
    )


def observe(
    pitch: float, pitch_rate: float, wheel_speed: float, wheel_command: float, target: float
) -> np.ndarray:
    """The observation vector of one bot, in `SHARED_FIELDS` order.

    Sensed readings (true or noisy) are clipped to their sensors' ranges;
    `wheel_command` and `target` are within bounds by construction (the bot
    clamps its command; specs bound their targets).
    """
    # fromiter with a known count skips numpy's type and shape discovery (benchmarks/).
    return np.fromiter(
        (*sensed(pitch, pitch_rate, wheel_speed), wheel_command, target),
        OBSERVATION_DTYPE,
        _OBSERVATION_SIZE,
    )


def sensed(pitch: float, pitch_rate: float, wheel_speed: float) -> tuple[float, float, float]:
    """The three sensed readings clipped to their sensors' ranges, as Python floats: the
    one place the shared readings are clipped (every robot's observation calls it)."""
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
    built in one call (it runs every step of a height-scan task; benchmarks/bench_suite.py)."""
    return np.fromiter(
        chain(sensed(pitch, pitch_rate, wheel_speed), (wheel_command, target), clipped_scan(scan)),
        OBSERVATION_DTYPE,
        _OBSERVATION_SIZE + len(scan),
    )


def clipped_scan(scan):
    """The height scan's readings (m) clipped to +-SCAN_RANGE."""
    if scan and not -SCAN_RANGE <= min(scan) <= max(scan) <= SCAN_RANGE:  # rare: a deep drop
        return [SCAN_RANGE if h > SCAN_RANGE else max(h, -SCAN_RANGE) for h in scan]
    return scan


def observation_with(
    reading: tuple[float, float, float],
    command: float,
    target: float,
    own: Sequence[float],
    scan: list[float] | None = None,
) -> np.ndarray:
    """A robot's observation: the shared five (`reading` clipped as `sensed` clips it, the
    command, the target), then the robot's `own` values, then the height `scan` (clipped)
    if given. For the robots that add fields (`observe` is the two-wheel bot's own)."""
    values = chain(sensed(*reading), (command, target), own)
    if scan is not None:
        scan = clipped_scan(scan)
        values = chain(values, scan)
    size = _OBSERVATION_SIZE + len(own) + (len(scan) if scan is not None else 0)
    return np.fromiter(values, OBSERVATION_DTYPE, size)
