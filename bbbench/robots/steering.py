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

import collections
import functools
import math
import operator
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import pybullet
from gymnasium import spaces
from pybullet_utils.bullet_client import BulletClient

from bbbench.robots.balancebot import MODEL, BalanceBot, RobotModel
from bbbench.robots.layout import (
    ENCODER_SPEED_RANGE,
    GYRO_RANGE,
    OBSERVATION_DTYPE,
    ObservationField,
    fields_markdown,
    observation_with,
    shared_layout,
)
from bbbench.robots.robot import Robot
from bbbench.robots.twowheel import MAX_WHEEL_SPEED_CHANGE, WHEEL_SPEED_CHANGES

# Changes of the turning command (rad/s) a discrete action makes, times the nine forward
# ones: 0.3 rad/s a step reaches a 1 rad/s turn (d = 1.2 rad/s) in four steps.
TURN_CHANGES = (-0.3, 0.0, 0.3)
MAX_TURN_CHANGE = max(abs(change) for change in TURN_CHANGES)
# The largest turning command (rad/s): about 5 rad/s of yaw rate; each wheel's speed is
# still clamped to the wheels' limit.
TURN_LIMIT = 6.0
ACTION_MODES = ("discrete", "continuous")
DISCRETE_ACTIONS = tuple(
    (forward, turn) for forward in WHEEL_SPEED_CHANGES for turn in TURN_CHANGES
)


class SteerState(NamedTuple):
    """One reading of the steering bot: `BotState`'s fields, then its own. Angles in rad,
    rates in rad/s, velocities in m/s."""

    position: tuple[float, float, float]  # the torso's centre of mass as built, world frame
    orientation: tuple[float, float, float, float]  # torso quaternion (x, y, z, w)
    pitch: float
    pitch_rate: float
    tilt: float
    wheel_speed: float  # the mean of the two wheels, relative to the torso
    forward_velocity: float
    velocity: tuple[float, float]  # the axle's horizontal velocity, world frame
    heading: tuple[float, float]  # the bot's forward direction, horizontal unit vector
    axle: tuple[float, float, float]  # the axle's midpoint, world frame (m)
    yaw_rate: float  # the gyro about the torso's up axis, + turning left
    wheel_speed_difference: float  # right - left, relative to the torso (encoders)
    turn_command: float  # rad/s: the right wheel's command above the forward one


_new_state = functools.partial(tuple.__new__, SteerState)


class SteeringBot(BalanceBot):
    """The balancing bot with its wheels commanded apart (`command_wheels`).

    `wheel_command` is the forward command u and `turn_command` the turning command d
    (rad/s); the servos hold u - d on the left wheel and u + d on the right, each clamped
    to the wheel-speed limit. `read` returns a `SteerState`.
    """

    def __init__(self, client: BulletClient, model: RobotModel = MODEL) -> None:
        self.turn_command = 0.0
        super().__init__(client, model)

    def act(self, change: tuple[float, float]) -> float:
        """Change the forward and turning commands by `change` (rad/s each); return the
        forward command now held."""
        forward, turn = change
        return self.command_wheels(self.wheel_command + forward, self.turn_command + turn)

    def command_wheel_speed(self, speed: float) -> float:
        """Both wheels at `speed` rad/s apart from the turning command held."""
        return self.command_wheels(speed, self.turn_command)

    def command_wheels(self, forward: float, turn: float) -> float:
        """Drive the wheels at `forward` - `turn` (left) and `forward` + `turn` (right)
        rad/s. `forward` is clamped to the wheel-speed limit and `turn` to `TURN_LIMIT`;
        each wheel's speed to the limit. Returns the forward command, kept in
        `wheel_command` (and the turning one in `turn_command`). NaN raises ValueError."""
        if forward != forward or turn != turn:
            raise ValueError("wheel speed command is NaN; expected numbers of rad/s")
        limit = self.model.wheel_speed_limit
        # Clamps as conditionals, not min(max()): this runs every step (the same values).
        forward = limit if forward > limit else -limit if forward < -limit else forward
        turn = TURN_LIMIT if turn > TURN_LIMIT else -TURN_LIMIT if turn < -TURN_LIMIT else turn
        held_forward, held_turn = forward, turn
        if self._delayed is not None:  # `set_action_delay`: the servos get an older pair
            self._delayed.append((forward, turn))
            held_forward, held_turn = self._delayed.popleft()
        left, right = held_forward - held_turn, held_forward + held_turn
        left = limit if left > limit else -limit if left < -limit else left
        right = limit if right > limit else -limit if right < -limit else right
        pybullet.setJointMotorControlArray(
            self.body,
            self.wheel_joints,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=(left, -right),  # the right wheel's axis is reversed
            forces=self._motor_forces,
            physicsClientId=self._client_id,
        )
        self.wheel_command, self.turn_command = forward, turn
        return forward

    def set_action_delay(self, steps: int) -> None:
        """As the two-wheel bot's: the servos hold the pair of commands asked `steps`
        commands before (both 0 for the first `steps` after a reset)."""
        self._delayed = collections.deque([(0.0, 0.0)] * steps) if steps else None

    def _hold_still(self) -> None:
        if self._delayed is not None:
            self._delayed = collections.deque([(0.0, 0.0)] * len(self._delayed))
        self.command_wheels(0.0, 0.0)

    def _stop(self) -> None:
        self.command_wheels(0.0, 0.0)

    def read(self) -> SteerState:
        """Query the world once and return the bot's state in its own frame: the two-wheel
        bot's reading (`BalanceBot.read`, whose arithmetic this repeats so that the world
        is queried once), then the yaw rate, the wheels' speed difference and the turning
        command."""
        body, client_id = self.body, self._client_id
        position, orientation = pybullet.getBasePositionAndOrientation(body, client_id)
        (vx, vy, _), (wx, wy, wz) = pybullet.getBaseVelocity(body, client_id)
        left, right = pybullet.getJointStates(body, self.wheel_joints, client_id)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = pybullet.getMatrixFromQuaternion(orientation)
        d = self._com_above_axle
        vx -= d * (wy * r22 - wz * r12)
        vy -= d * (wz * r02 - wx * r22)
        e = self._com_forward
        if e:  # `set_com_offset`, as BalanceBot.read
            vx -= e * (wy * r21 - wz * r11)
            vy -= e * (wz * r01 - wx * r21)
            px, py, pz = position
            position = (px - e * r01, py - e * r11, pz - e * r21)
        length = math.hypot(r01, r11)
        heading = (r01 / length, r11 / length) if length > 1e-9 else (0.0, 1.0)
        px, py, pz = position
        qx, qy = orientation[0], orientation[1]
        up = 1.0 - 2.0 * (qx * qx + qy * qy)
        up = up if up < 1.0 else 1.0
        return _new_state(
            (
                position,
                orientation,
                math.atan2(-r21, r22),  # pitch
                0.0 - (r00 * wx + r10 * wy + r20 * wz),  # pitch rate
                math.acos(up if up > -1.0 else -1.0),  # tilt
                0.5 * (left[1] - right[1]),  # wheel speed
                vx * heading[0] + vy * heading[1],  # forward velocity
                (vx, vy),
                heading,
                (px - d * r02, py - d * r12, pz - d * r22),  # axle
                r02 * wx + r12 * wy + r22 * wz,  # yaw rate: about the torso's up axis
                0.0 - right[1] - left[1],  # right - left, forward-positive each
                self.turn_command,
            )
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
_PI = math.pi  # the pitch sensor's range, as layout's


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
    `extra`: in one call, with the clips written out (SteerTracking's every step;
    benchmarks/bench_steering.py). The same values as `observation_with`."""
    pitch, pitch_rate, wheel_speed = reading
    rate, difference = state.yaw_rate, state.wheel_speed_difference
    return np.fromiter(
        (
            _PI if pitch > _PI else max(pitch, -_PI),
            GYRO_RANGE if pitch_rate > GYRO_RANGE else max(pitch_rate, -GYRO_RANGE),
            ENCODER_SPEED_RANGE
            if wheel_speed > ENCODER_SPEED_RANGE
            else max(wheel_speed, -ENCODER_SPEED_RANGE),
            command,
            target,
            min(max(rate, -GYRO_RANGE), GYRO_RANGE),
            min(max(difference, -_DIFFERENCE_RANGE), _DIFFERENCE_RANGE),
            state.turn_command,
            extra,
        ),
        OBSERVATION_DTYPE,
        _SIZE + 1,
    )


def actions_markdown() -> str:
    """The robot's action spaces, in Markdown: both modes, and the discrete table."""
    discrete = [
        "| Index | Forward change (rad/s) | Turning change (rad/s) |",
        "|-------|------------------------|------------------------|",
        *(f"| {i} | {f:g} | {t:g} |" for i, (f, t) in enumerate(DISCRETE_ACTIONS)),
    ]
    return f"""\
`discrete` (the default): `Discrete({len(DISCRETE_ACTIONS)})`, a change of the forward
command and of the turning command at once. `continuous`: `Box(-1, 1, (2,), float32)`, the
forward change scaled to at most {MAX_WHEEL_SPEED_CHANGE:g} rad/s and the turning change to
at most {MAX_TURN_CHANGE:g} rad/s. The forward command is clamped to
+-{MODEL.wheel_speed_limit:g} rad/s, the turning command to +-{TURN_LIMIT:g} rad/s, and
each wheel (forward - turning on the left, forward + turning on the right) to
+-{MODEL.wheel_speed_limit:g} rad/s.

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
        # `sensed` and `own_values`, written out: the multi-bot observations call this per
        # bot per step (benchmarks/bench_steering.py). The same values.
        pitch, pitch_rate, wheel_speed = reading
        rate, difference = state.yaw_rate, state.wheel_speed_difference
        return (
            _PI if pitch > _PI else max(pitch, -_PI),
            GYRO_RANGE if pitch_rate > GYRO_RANGE else max(pitch_rate, -GYRO_RANGE),
            ENCODER_SPEED_RANGE
            if wheel_speed > ENCODER_SPEED_RANGE
            else max(wheel_speed, -ENCODER_SPEED_RANGE),
            command,
            target,
            min(max(rate, -GYRO_RANGE), GYRO_RANGE),
            min(max(difference, -_DIFFERENCE_RANGE), _DIFFERENCE_RANGE),
            state.turn_command,
        )


TWO_WHEEL_STEER = TwoWheelSteer()
