"""The wheel-legged balancer: a torso on two legs, each with a hip, a knee and a wheel.

The tutorial's third idea (a robot like Boston Dynamics' Handle), in the two-wheel
bot's family: the same 0.1 m wheels and wheel motors, the same shared observation
first, the same tasks and ground. The legs set the torso's height and can level it
over uneven ground; the wheels balance it. Upkie and Ascento are the real robots of
this kind.

Facts, read from `wheel_legged.urdf` (`read_legged_model`; tests/test_wheel_legged.py
checks this table against the file):

| part | value |
|---|---|
| torso | box 0.2 x 0.08 x 0.16 m, 0.8 kg |
| thigh, shin | 0.15 m and 0.15 m |
| wheels | radius 0.1 m, 0.13 m either side of the centre |
| total mass | 1.2 kg |
| hip range | -0.4 to 1.6 rad (+: thigh forward) |
| knee range | -2.4 to 0 rad (-: shin backward) |
| leg servos | 1.5 N m, 8 rad/s |
| wheel motors | 0.6 N m, 24.6 rad/s (2.46 m/s) |
| standing pose | hip 0.6 rad, knee -1.2 rad |
| axle below the hips | 0.109 to 0.300 m with knee = -2 hip; 0.248 m standing |

Conventions are the two-wheel bot's (`bbbench.robots.balancebot`): forward is +y, pitch
leans forward, wheel speed is the mean of the two wheels relative to their shins
(encoders), forward velocity is the axle midpoint's true horizontal velocity along the
heading. Roll is the torso's lean towards its right side (+x), in rad.

Leg servos are soft position loops: each control step the servo is asked for the joint
speed `LEG_POSITION_GAIN * (target - angle)`, clipped to the joint's speed limit, and
holds it with at most the joint's torque limit. Targets are clipped to the joint's
range, so no target outside it reaches a servo.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.layout import (
    ENCODER_SPEED_RANGE,
    GYRO_RANGE,
    ObservationField,
    fields_markdown,
    observation_with,
    sensed,
    shared_layout,
)
from bbbench.robots.legged_body import (
    LEG_JOINT_NAMES,
    LEG_POSITION_GAIN,
    LEGGED_MODEL,
    MAX_WHEEL_SPEED_CHANGE,
    URDF_PATH,
    WHEEL_JOINT_NAMES,
    LeggedModel,
    LeggedState,
    WheelLeggedBot,
    facts_markdown,
    legged_spawn_pose,
    read_legged_model,
)
from bbbench.robots.robot import Robot

__all__ = [  # the body's names, re-exported: the robot is read from here
    "LEGGED_MODEL",
    "LEG_JOINT_NAMES",
    "LEG_POSITION_GAIN",
    "MAX_WHEEL_SPEED_CHANGE",
    "URDF_PATH",
    "WHEEL_JOINT_NAMES",
    "WHEEL_LEGGED",
    "LeggedModel",
    "LeggedState",
    "WheelLegged",
    "WheelLeggedBot",
    "decode",
    "facts_markdown",
    "interface_markdown",
    "legged_spawn_pose",
    "read_legged_model",
]


# -- the robot's face to its tasks ---------------------------------------------------


def _leg_fields(model: LeggedModel) -> tuple[ObservationField, ...]:
    angles = tuple(
        ObservationField(
            f"{leg.name}_angle",
            "rad",
            leg.lower,
            leg.upper,
            f"{leg.name.replace('_', ' ')} angle, "
            + ("0 thigh straight down, + forward" if "hip" in leg.name else "0 straight, - bent"),
        )
        for leg in model.legs
    )
    rates = tuple(
        ObservationField(
            f"{leg.name}_rate",
            "rad/s",
            -ENCODER_SPEED_RANGE,
            ENCODER_SPEED_RANGE,
            f"{leg.name.replace('_', ' ')} angular rate (encoder)",
        )
        for leg in model.legs
    )
    limit = model.wheel_speed_limit
    return (
        *angles,
        *rates,
        ObservationField("roll", "rad", -math.pi, math.pi, "torso lean towards its right side"),
        ObservationField(
            "roll_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "gyro rate about the heading"
        ),
        ObservationField(
            "wheel_speed_difference",
            "rad/s",
            -2 * ENCODER_SPEED_RANGE,
            2 * ENCODER_SPEED_RANGE,
            "right wheel's speed minus the left's (encoders): + turns left",
        ),
        ObservationField(
            "wheel_command_difference",
            "rad/s",
            -2 * limit,
            2 * limit,
            "right wheel's command minus the left's",
        ),
    )


OBSERVATION_LAYOUT = shared_layout(LEGGED_MODEL.wheel_speed_limit, LEGGED_MODEL.top_speed) + (
    _leg_fields(LEGGED_MODEL)
)
_SIZE = len(OBSERVATION_LAYOUT)
_LOW = tuple(field.low for field in OBSERVATION_LAYOUT[5:])
_HIGH = tuple(field.high for field in OBSERVATION_LAYOUT[5:])

ACTION_LAYOUT = (
    *(f"{name}_target" for name in LEG_JOINT_NAMES),
    "left_wheel_change",
    "right_wheel_change",
)


_LEG_SCALES = tuple((leg.centre, leg.half_range) for leg in LEGGED_MODEL.legs)


def decode(action: Any) -> tuple[float, ...]:
    """The leg targets (rad) and wheel changes (rad/s) of an action of `Box(-1, 1, (6,))`.

    A leg value v aims the joint at centre + v * half range: -1 and 1 are the ends of the
    joint's range, and a value beyond them asks for a target outside it, which the body
    clips to the range. A wheel value is a change of that wheel's commanded speed of v
    rad/s and must lie in [-1, 1], as on the two-wheel bot. NaN, a wrong shape or a
    wheel value outside [-1, 1] raise a ValueError that says what was expected.
    """
    values = None
    if type(action) is np.ndarray and action.shape == (6,):
        values = action.tolist()
    else:
        try:
            array = np.asarray(action, dtype=np.float64)
            if array.shape == (6,):
                values = array.tolist()
        except (TypeError, ValueError):
            pass
    if values is not None:
        v0, v1, v2, v3, left, right = values
        # NaN fails every comparison: refused, never clipped.
        finite = v0 == v0 and v1 == v1 and v2 == v2 and v3 == v3
        if finite and -1.0 <= left <= 1.0 and -1.0 <= right <= 1.0:
            (c0, h0), (c1, h1), (c2, h2), (c3, h3) = _LEG_SCALES
            change = MAX_WHEEL_SPEED_CHANGE
            return (c0 + h0 * v0, c1 + h1 * v1, c2 + h2 * v2, c3 + h3 * v3, left * change,
                    right * change)  # fmt: skip
    raise ValueError(
        f"wheel-legged action {action!r} is not in the action space: expected 6 finite "
        f"numbers {ACTION_LAYOUT}, the leg targets in [-1, 1] (the ends of each joint's "
        f"range; beyond them, clipped) and the wheel-speed changes in [-1, 1] (scaled to "
        f"at most {MAX_WHEEL_SPEED_CHANGE} rad/s)"
    )


def _legs_observed(state: LeggedState) -> list[float]:
    """The robot's own observations (after the shared five), clipped to their bounds."""
    (speed_left, speed_right), (command_left, command_right) = (
        state.wheel_speeds,
        state.wheel_commands,
    )
    values = (
        *state.leg_angles,
        *state.leg_rates,
        state.roll,
        state.roll_rate,
        speed_right - speed_left,
        command_right - command_left,
    )
    return [h if v > h else lo if v < lo else v for v, lo, h in zip(values, _LOW, _HIGH)]  # noqa: B905


def actions_markdown() -> str:
    """The robot's action space, in Markdown, from the layouts in this module."""
    legs = LEGGED_MODEL.legs
    actions = [
        "| Num | Action | -1 | +1 | Unit |",
        "|-----|--------|----|----|------|",
        *(
            f"| {i} | {name} | {leg.lower:g} | {leg.upper:g} | rad (joint target) |"
            for i, (name, leg) in enumerate(zip(ACTION_LAYOUT, legs, strict=False))
        ),
        *(
            f"| {i} | {name} | -{MAX_WHEEL_SPEED_CHANGE:g} | {MAX_WHEEL_SPEED_CHANGE:g} | "
            "rad/s (change of command) |"
            for i, name in list(enumerate(ACTION_LAYOUT))[4:]
        ),
    ]
    return f"""\
`Box(-1, 1, (6,), float32)`, continuous only. A leg value v aims its joint at the
centre of its range plus v times half the range (-1 and +1 are the range's ends; the
standing pose is 0); a target beyond the range is clipped to it, never refused. A wheel
value changes that wheel's commanded speed by v rad/s, as on the two-wheel bot: it must
lie in [-1, 1] (outside, or NaN anywhere, raises `ValueError`), and the command is
clamped to +-{LEGGED_MODEL.wheel_speed_limit:g} rad/s.

{chr(10).join(actions)}"""


def interface_markdown() -> str:
    """The robot's action and observation spaces as Markdown tables, from the layouts in
    this module: its tasks' docstrings and docs/robots.md carry them (tests check both)."""
    return f"""\
## Action Space

{actions_markdown()}

## Observation Space

`Box({len(OBSERVATION_LAYOUT)},)` of `float32`: the five values every robot's tasks share
(as the two-wheel bot's: its policies' controllers read them), then the legs. Angles
are in the robot's own frame against gravity; readings a sensor would saturate are
clipped to its range. `height_scan=True` appends the 11 ground heights ahead, as on
the two-wheel bot.

{fields_markdown(OBSERVATION_LAYOUT)}"""


class WheelLegged(Robot):
    """The wheel-legged balancer (`WheelLeggedBot`): continuous actions only."""

    name = "wheel-legged"
    controller = "legged"  # bbbench.policies.controllers.legged
    summary = "a wheel-legged balancer: hip, knee and wheel per leg (1.2 kg)"
    model = LEGGED_MODEL
    action_modes = ("continuous",)

    def body(self, client: BulletClient) -> WheelLeggedBot:
        return WheelLeggedBot(client)

    def action_space(self, action_mode: str) -> spaces.Space:
        self.check_action_mode(action_mode)
        return spaces.Box(-1.0, 1.0, shape=(len(ACTION_LAYOUT),), dtype=np.float32)

    def action_decoder(self, action_mode: str) -> Callable[[Any], tuple[float, ...]]:
        self.check_action_mode(action_mode)
        return decode

    def own_layout(self) -> tuple[ObservationField, ...]:
        return OBSERVATION_LAYOUT

    def interface_markdown(self) -> str:
        return interface_markdown()

    def actions_markdown(self) -> str:
        return actions_markdown()

    def observe(
        self,
        reading: tuple[float, float, float],
        command: float,
        target: float,
        state: LeggedState,
        scan: list[float] | None = None,
    ) -> np.ndarray:
        own = _legs_observed(state)
        return observation_with(reading, command, target, own, scan)

    def values(
        self, reading: tuple[float, float, float], command: float, target: float, state: LeggedState
    ) -> tuple[float, ...]:
        return (*sensed(*reading), command, target, *_legs_observed(state))


WHEEL_LEGGED = WheelLegged()
