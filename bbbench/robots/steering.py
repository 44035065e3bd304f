"""The two-wheel bot that steers: the tutorial's body and motors, its wheels commanded apart.

The published two-wheel robot (`bbbench.robots.twowheel`) gives both wheels one command,
so it can change speed but never heading. This robot commands them apart, as a
differential drive does (VMAS's `DiffDrive`, a real balancing robot): a forward command
u and a turning command d (rad/s), the left wheel held at u - d and the right at u + d,
each clamped to the wheels' speed limit. Its pitch loop is the two-wheel bot's; turning
left (counter-clockwise seen from above) is positive, as in ROS's REP 103.

An action changes both commands at once:

- `discrete`: `Discrete(27)`, the tutorial's nine changes of the forward command times
  three of the turning command (`TURN_CHANGES`): index = 3 x forward index + turn index;
- `continuous`: `Box(-1, 1, (2,))`, the change of the forward command (scaled to at most
  1 rad/s, as the two-wheel bot's) and of the turning command (to at most
  `MAX_TURN_CHANGE` rad/s).

The observation begins with the five values every robot shares (its forward command
is `wheel_command`), then the gyro's yaw rate, the wheels' speed difference (right -
left, from the encoders) and the turning command: `Box(8,)`. A task appends its own
fields after them (the yaw rate it asks for, where its goal is).

With a track of 0.24 m and wheels of 0.1 m, a turning command d turns the bot at about
0.1 x 2d / 0.24 = 0.83 d rad/s when the wheels roll without slipping.
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.balancebot import MODEL
from bbbench.robots.layout import (
    ENCODER_SPEED_RANGE,
    GYRO_RANGE,
    OBSERVATION_DTYPE,
    ObservationField,
    fields_markdown,
    observation_with,
    sensed,
    shared_layout,
)
from bbbench.robots.robot import Robot
from bbbench.robots.steering_body import TURN_LIMIT, SteeringBot, SteerState
from bbbench.robots.twowheel import MAX_WHEEL_SPEED_CHANGE, WHEEL_SPEED_CHANGES

# Changes of the turning command (rad/s) a discrete action makes, times the nine forward
# ones: 0.3 rad/s a step reaches a 1 rad/s turn (d = 1.2 rad/s) in four steps.
TURN_CHANGES = (-0.3, 0.0, 0.3)
MAX_TURN_CHANGE = max(abs(change) for change in TURN_CHANGES)
ACTION_MODES = ("discrete", "continuous")
DISCRETE_ACTIONS = tuple(
    (forward, turn) for forward in WHEEL_SPEED_CHANGES for turn in TURN_CHANGES
)


def discrete_change(action) -> tuple[float, float]:
    """The (forward, turning) change of a discrete action index, or a clear ValueError."""
    try:
        index = operator.index(action)
    except TypeError:
        index = -1
    if 0 <= index < len(DISCRETE_ACTIONS):
        return DISCRETE_ACTIONS[index]
    raise ValueError(
        f"discrete action {action!r} is not in the action space: expected an integer index "
        f"0..{len(DISCRETE_ACTIONS) - 1}, 3 x (forward change index into "
        f"{WHEEL_SPEED_CHANGES}) + (turning change index into {TURN_CHANGES}) rad/s"
    )


def continuous_change(action) -> tuple[float, float]:
    """The (forward, turning) change of a continuous action in [-1, 1]^2, or a clear
    ValueError."""
    values = None
    if type(action) is np.ndarray and action.shape == (2,):
        values = action.tolist()
    else:
        try:
            array = np.asarray(action, dtype=np.float64)
            values = array.tolist() if array.shape == (2,) else None
        except (TypeError, ValueError):
            pass
    if values is not None:
        forward, turn = values
        if -1.0 <= forward <= 1.0 and -1.0 <= turn <= 1.0:  # NaN fails: refused
            return forward * MAX_WHEEL_SPEED_CHANGE, turn * MAX_TURN_CHANGE
    raise ValueError(
        f"continuous action {action!r} is not in the action space: expected two finite "
        f"numbers in [-1, 1], shape (2,): the change of the forward command (scaled to at "
        f"most {MAX_WHEEL_SPEED_CHANGE} rad/s) and of the turning command (to at most "
        f"{MAX_TURN_CHANGE} rad/s)"
    )


def action_space(action_mode: str) -> spaces.Space:
    if action_mode == "discrete":
        return spaces.Discrete(len(DISCRETE_ACTIONS))
    return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)


_OWN_FIELDS = (
    ObservationField(
        "yaw_rate", "rad/s", -GYRO_RANGE, GYRO_RANGE, "gyro about the up axis, + left"
    ),
    ObservationField(
        "wheel_speed_difference",
        "rad/s",
        -2 * ENCODER_SPEED_RANGE,
        2 * ENCODER_SPEED_RANGE,
        "right wheel's speed minus the left's, relative to the torso (encoders)",
    ),
    ObservationField(
        "turn_command",
        "rad/s",
        -TURN_LIMIT,
        TURN_LIMIT,
        "turning command: the right wheel's command above the forward one, the left's below",
    ),
)
OBSERVATION_LAYOUT = (*shared_layout(MODEL.wheel_speed_limit, MODEL.top_speed), *_OWN_FIELDS)
_SIZE = len(OBSERVATION_LAYOUT)
_DIFFERENCE_RANGE = 2 * ENCODER_SPEED_RANGE


def own_values(state: SteerState) -> tuple[float, float, float]:
    """The robot's own values after the shared five, clipped to their sensors' ranges."""
    rate, difference = state.yaw_rate, state.wheel_speed_difference
    return (
        min(max(rate, -GYRO_RANGE), GYRO_RANGE),
        min(max(difference, -_DIFFERENCE_RANGE), _DIFFERENCE_RANGE),
        state.turn_command,
    )


def steer_observation(
    reading: tuple[float, float, float], command: float, target: float, state: SteerState,
    extra: float,
) -> np.ndarray:  # fmt: skip
    """The robot's observation (`observation_with` of `own_values`), then one more value
    `extra`, in one array (SteerTracking's every step; benchmarks/bench_steering.py)."""
    return np.fromiter(
        (*sensed(*reading), command, target, *own_values(state), extra),
        OBSERVATION_DTYPE,
        _SIZE + 1,
    )


def actions_markdown() -> str:
    """The robot's action spaces, in Markdown: both modes, and the discrete actions as a
    grid, the index of each pair of changes (a row per forward change, a column per
    turning change)."""
    index = {change: i for i, change in enumerate(DISCRETE_ACTIONS)}
    discrete = [
        "| Forward change (rad/s) | " + " | ".join(f"turning {t:g}" for t in TURN_CHANGES) + " |",
        "|---|" + "---|" * len(TURN_CHANGES),
        *(
            f"| {f:g} | " + " | ".join(str(index[f, t]) for t in TURN_CHANGES) + " |"
            for f in WHEEL_SPEED_CHANGES
        ),
    ]
    return f"""\
`discrete` (the default): `Discrete({len(DISCRETE_ACTIONS)})`, a change of the forward
command and of the turning command at once. `continuous`: `Box(-1, 1, (2,), float32)`, the
forward change scaled to at most {MAX_WHEEL_SPEED_CHANGE:g} rad/s and the turning change to
at most {MAX_TURN_CHANGE:g} rad/s. The forward command is clamped to
+-{MODEL.wheel_speed_limit:g} rad/s, the turning command to +-{TURN_LIMIT:g} rad/s, and
each wheel (forward - turning on the left, forward + turning on the right) to
+-{MODEL.wheel_speed_limit:g} rad/s. A discrete action's index, by its forward change (rows)
and its turning change (columns):

{chr(10).join(discrete)}"""


def interface_markdown() -> str:
    """The robot's action and observation spaces as Markdown tables."""
    return f"""\
## Action Space

{actions_markdown()}

## Observation Space

`Box({_SIZE},)` of `float32` (a task appends its own fields): the five values every
robot's tasks share, then the robot's own.

{fields_markdown(OBSERVATION_LAYOUT)}"""


class TwoWheelSteer(Robot):
    """The two-wheel bot with its wheels commanded apart (`SteeringBot`)."""

    name = "two-wheel-steer"
    controller = "steer"  # bbbench.policies.controllers.steer
    summary = "the two-wheel bot commanding its wheels apart: it turns (1.0 kg, 0.5 m tall)"
    model = MODEL
    action_modes = ACTION_MODES

    def body(self, client: BulletClient) -> SteeringBot:
        return SteeringBot(client)

    def action_space(self, action_mode: str) -> spaces.Space:
        self.check_action_mode(action_mode)
        return action_space(action_mode)

    def action_decoder(self, action_mode: str) -> Callable[[Any], tuple[float, float]]:
        self.check_action_mode(action_mode)
        return discrete_change if action_mode == "discrete" else continuous_change

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
        state: SteerState,
        scan: list[float] | None = None,
    ) -> np.ndarray:
        return observation_with(reading, command, target, own_values(state), scan)

    def values(
        self, reading: tuple[float, float, float], command: float, target: float, state: SteerState
    ) -> tuple[float, ...]:
        return (*sensed(*reading), command, target, *own_values(state))


TWO_WHEEL_STEER = TwoWheelSteer()
