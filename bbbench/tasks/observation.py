"""The observation layout shared by every single-bot task.

One policy can be evaluated on every task of the suite because every task
returns the same vector, in the same order, with the same bounds. Readings a
real robot's sensors would saturate are clipped to the sensor's range, so the
bounds are honest: no observation ever leaves them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from bbbench.robots import MODEL

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


def observation_space() -> spaces.Box:
    """The Box every single-bot task observes in."""
    return spaces.Box(
        low=np.array([field.low for field in OBSERVATION_LAYOUT], dtype=OBSERVATION_DTYPE),
        high=np.array([field.high for field in OBSERVATION_LAYOUT], dtype=OBSERVATION_DTYPE),
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
